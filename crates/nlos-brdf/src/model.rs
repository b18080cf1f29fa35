//! [`Model`]: which reflectance model, by name — the one choice read by the settings (`reflectance.model`),
//! the command line (`--brdf`), Python (`brdf=`), the volumetric starts' weighting and the renderer; and
//! [`AnyBrdf`], one BRDF of a model chosen at run time, with [`with_brdf!`](crate::with_brdf) to reach its
//! concrete type.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::BrdfError;
use crate::fitted::FittedBrdf;
use crate::{Fresnel, Ggx, Lambertian, Retroreflective};

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

/// One BRDF of any [`Model`], for code that picks the model at run time (settings, the command line,
/// Python, the optimiser's reflectance); [`with_brdf!`](crate::with_brdf) calls generic code with the concrete
/// type, so the renderer's inner loops stay monomorphised. Written in settings and checkpoints as the model's
/// name holding the BRDF's parameters, e.g. `{"lambert": {"albedo": 0.5}}`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum AnyBrdf {
    /// [`Model::Lambert`].
    #[serde(rename = "lambert")]
    Lambertian(Lambertian<f32>),
    /// [`Model::Ggx`].
    #[serde(rename = "ggx")]
    Ggx(Ggx<f32>),
    /// [`Model::Retroreflective`].
    #[serde(rename = "retroreflective")]
    Retroreflective(Retroreflective<f32>),
}

/// Calls `$body` with `$b` bound to the concrete BRDF (a [`crate::FittedBrdf`]) of an [`AnyBrdf`]:
/// `with_brdf!(brdf, b => renderer.forward(&b))`.
#[macro_export]
macro_rules! with_brdf {
    ($brdf:expr, $b:ident => $body:expr) => {
        match $brdf {
            $crate::AnyBrdf::Lambertian($b) => $body,
            $crate::AnyBrdf::Ggx($b) => $body,
            $crate::AnyBrdf::Retroreflective($b) => $body,
        }
    };
}

impl AnyBrdf {
    /// `model` with these parameters: the Lambertian's albedo, the retroreflector's return `albedo` (1° lobe),
    /// GGX's diffuse albedo `albedo`, lobe weight `specular` and roughness `alpha`, without a Fresnel term
    /// (Tsai et al. 2019's model); the parameters a model does not have are ignored.
    ///
    /// # Errors
    /// A [`BrdfError`] for a value outside the model's domain.
    pub fn new(model: Model, albedo: f32, specular: f32, alpha: f32) -> Result<Self, BrdfError> {
        Ok(match model {
            Model::Lambert => AnyBrdf::Lambertian(Lambertian::new(albedo)?),
            Model::Ggx => AnyBrdf::Ggx(Ggx::new(albedo, specular, alpha, Fresnel::One)?),
            Model::Retroreflective => AnyBrdf::Retroreflective(Retroreflective::new(albedo)?),
        })
    }

    /// The surface `nlos render` simulates and a reconstruction starts from: albedo 1; for GGX the
    /// specular lobe alone (no diffuse part, weight 1) of roughness `alpha`.
    ///
    /// # Errors
    /// A [`BrdfError`] for an `alpha` outside GGX's range.
    pub fn unit(model: Model, alpha: f32) -> Result<Self, BrdfError> {
        let albedo = if model == Model::Ggx { 0.0 } else { 1.0 };
        Self::new(model, albedo, 1.0, alpha)
    }

    /// The model ([`FittedBrdf::MODEL`]).
    pub fn model(&self) -> Model {
        with_brdf!(self, b => model_of(b))
    }

    /// The BRDF in words, with its parameters ([`FittedBrdf::describe`]).
    pub fn describe(&self) -> String {
        with_brdf!(self, b => b.describe())
    }

    /// Parameter names, in the order of [`AnyBrdf::params`] ([`FittedBrdf::PARAM_NAMES`]).
    pub fn param_names(&self) -> &'static [&'static str] {
        with_brdf!(self, b => param_names_of(b))
    }

    /// The parameter vector ([`FittedBrdf::params`]).
    pub fn params(&self) -> Vec<f32> {
        with_brdf!(self, b => b.params())
    }

    /// The same model with parameters `p` (in [`AnyBrdf::param_names`] order).
    ///
    /// # Errors
    /// A [`BrdfError`] when a value is out of the model's domain.
    pub fn with_params(&self, p: &[f32]) -> Result<Self, BrdfError> {
        with_brdf!(self, b => b.with_params(p).map(|b| b.to_any()))
    }

    /// Whether the BRDF is a pure scale of the rendering ([`FittedBrdf::SCALE_ONLY`]).
    pub fn is_scale_only(&self) -> bool {
        with_brdf!(self, b => scale_only_of(b))
    }

    /// θ of the fitted parameters ([`FittedBrdf::theta`]).
    pub fn theta(&self) -> Vec<f64> {
        with_brdf!(self, b => b.theta())
    }

    /// The BRDF θ maps to, with what θ leaves fixed taken from `self` ([`FittedBrdf::with_theta`]).
    ///
    /// # Errors
    /// A [`BrdfError`] only for a non-finite θ.
    pub fn with_theta(&self, theta: &[f64]) -> Result<Self, BrdfError> {
        with_brdf!(self, b => b.with_theta(theta).map(|b| b.to_any()))
    }

    /// `∂E/∂θ` from `∂E/∂(physical parameters)` ([`FittedBrdf::chain_theta`]).
    pub fn chain_theta(&self, theta: &[f64], d_params: &[f32]) -> Vec<f64> {
        with_brdf!(self, b => b.chain_theta(theta, d_params))
    }
}

fn model_of<B: FittedBrdf>(_: &B) -> Model {
    B::MODEL
}

fn param_names_of<B: FittedBrdf>(_: &B) -> &'static [&'static str] {
    B::PARAM_NAMES
}

fn scale_only_of<B: FittedBrdf>(_: &B) -> bool {
    B::SCALE_ONLY
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
