//! [`Model`]: which reflectance model, by name — the one choice read by the settings (`reflectance.model`),
//! the command line (`--brdf`), Python (`brdf=`), the volumetric starts' weighting and the renderer.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::BrdfError;

/// A reflectance model, by name: [`crate::Lambertian`], [`crate::Ggx`] or [`crate::Retroreflective`].
///
/// Written `"lambert"`, `"ggx"` and `"retroreflective"` in settings files, on the command line and in
/// Python; `"lambertian"` is accepted as another name of `"lambert"` (the Python module's first spelling).
///
/// ```
/// use nlos_brdf::Model;
/// assert_eq!("retroreflective".parse::<Model>()?, Model::Retroreflective);
/// assert_eq!("lambertian".parse::<Model>()?, Model::Lambert);
/// assert_eq!(Model::Lambert.to_string(), "lambert");
/// assert!("phong".parse::<Model>().is_err());
/// # Ok::<(), nlos_brdf::BrdfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Model {
    /// One albedo ([`crate::Lambertian`]).
    #[default]
    #[serde(alias = "lambertian")]
    Lambert,
    /// A GGX microfacet lobe over a Lambertian base ([`crate::Ggx`]).
    Ggx,
    /// A retroreflector ([`crate::Retroreflective`]): the confocal return falls as `1/r²`.
    Retroreflective,
}

impl Model {
    /// Every model, in the order of the docs.
    pub const ALL: [Model; 3] = [Model::Lambert, Model::Ggx, Model::Retroreflective];

    /// Other names accepted for a model (and never written): `"lambertian"`, the Python module's first
    /// spelling of `"lambert"`.
    pub const ALIASES: [(&'static str, Model); 1] = [("lambertian", Model::Lambert)];

    /// The model's name in settings, on the command line and in Python.
    pub const fn name(self) -> &'static str {
        match self {
            Model::Lambert => "lambert",
            Model::Ggx => "ggx",
            Model::Retroreflective => "retroreflective",
        }
    }

    /// The power of the path length by which a small face's confocal return falls: 4 where the BRDF's value
    /// does not depend on distance (the `1/(|x−l|²|x−s|²)` of the measurement equation), 2 for a
    /// retroreflector, whose value grows as `|x−l||x−s|` ([`crate::retro`]). The volumetric starts weight the
    /// data by `t` to this power (O'Toole, Lindell & Wetzstein 2018: `t⁴` diffuse, `t²` retroreflective), and
    /// the renderer's splat rule corrects its fall-off by it.
    pub const fn distance_power(self) -> u32 {
        match self {
            Model::Lambert | Model::Ggx => 4,
            Model::Retroreflective => 2,
        }
    }
}

impl fmt::Display for Model {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Model {
    type Err = BrdfError;

    /// # Errors
    /// [`BrdfError::UnknownModel`] for any other name.
    fn from_str(s: &str) -> Result<Self, BrdfError> {
        let named = Model::ALL.into_iter().map(|m| (m.name(), m));
        named
            .chain(Model::ALIASES)
            .find_map(|(name, m)| (name == s).then_some(m))
            .ok_or_else(|| BrdfError::UnknownModel { got: s.into() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_through_every_form() {
        for m in Model::ALL {
            assert_eq!(m.name().parse::<Model>().expect("own name"), m);
            let json = serde_json::to_string(&m).expect("serialise");
            assert_eq!(json, format!("\"{m}\""));
            assert_eq!(serde_json::from_str::<Model>(&json).expect("deserialise"), m);
        }
        assert_eq!(serde_json::from_str::<Model>("\"lambertian\"").expect("alias"), Model::Lambert);
        let e = "Lambert".parse::<Model>().expect_err("names are lower case");
        assert!(e.to_string().contains("\"lambert\", \"ggx\" or \"retroreflective\""), "{e}");
        assert!(serde_json::from_str::<Model>("\"phong\"").is_err());
    }
}
