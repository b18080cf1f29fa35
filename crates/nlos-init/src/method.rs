//! The start, by name: [`Method`] (which volumetric reconstruction) and [`InitMethod`] (where the optimiser
//! starts: a method chosen for the scan, a method by name, or a mesh file). The one definition read by the
//! settings (`init`), the command line (`nlos init --method`, `nlos reconstruct --init`, `nlos eval --method`),
//! Python (`nlos.volume(method=…)`) and the residual's patches; [`Method::for_scan`] is the one place that
//! decides which method a scan gets.
//!
//! A new method is its algorithm's file, a variant here (its [`Method::name`], [`Method::summary`], its
//! call in [`Method::volume`]) and its `mod` line in `lib.rs`; every list of methods is [`Method::ALL`].

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use nlos_brdf::Model;
use nlos_transient::{Scan, ScanPattern, Transient};
use serde::{Deserialize, Serialize};

use crate::error::{InitError, Result};
use crate::{
    CarveParams, FbpParams, FkParams, Gate, LctParams, PfParams, SurfaceParams, Volume, carve, fbp, fk, lct, pf,
};

/// A volumetric reconstruction of the start.
///
/// Written `"lct"`, `"fk"`, `"fbp"`, `"pf"` and `"carve"` in settings files, on the command line and in
/// Python.
///
/// ```
/// use nlos_init::Method;
/// assert_eq!("pf".parse::<Method>()?, Method::Pf);
/// assert_eq!(Method::Fbp.to_string(), "fbp");
/// assert!("sart".parse::<Method>().is_err());
/// # Ok::<(), nlos_init::InitError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// The light-cone transform with Wiener deconvolution (O'Toole et al. 2018, [`lct()`]).
    Lct,
    /// f-k migration (Lindell et al. 2019, [`fk()`]).
    Fk,
    /// Laplacian-filtered backprojection ([`fbp()`]).
    Fbp,
    /// The phasor field (Liu et al. 2019, [`pf()`]): any scan.
    Pf,
    /// Space carving from first returns (Tsai et al. 2017, [`carve()`]).
    Carve,
}

impl Method {
    /// Every method, in the order of the docs.
    pub const ALL: [Method; 5] = [Method::Lct, Method::Fk, Method::Fbp, Method::Pf, Method::Carve];

    /// The method's name in settings, on the command line and in Python.
    pub const fn name(self) -> &'static str {
        match self {
            Method::Lct => "lct",
            Method::Fk => "fk",
            Method::Fbp => "fbp",
            Method::Pf => "pf",
            Method::Carve => "carve",
        }
    }

    /// One line on what the method is and what it takes (the command line's list of methods).
    pub const fn summary(self) -> &'static str {
        match self {
            Method::Lct => "Light-cone transform with Wiener deconvolution (O'Toole et al. 2018): confocal grid scans",
            Method::Fk => "f-k migration (Lindell et al. 2019): confocal grid scans",
            Method::Fbp => {
                "Laplacian-filtered backprojection: confocal grid scans, or exhaustive scans with a sensor grid"
            }
            Method::Pf => "Phasor-field reconstruction (Liu et al. 2019): any scan, confocal or not, grid or list",
            Method::Carve => "Space carving from first-returning photons (Tsai et al. 2017): confocal or exhaustive",
        }
    }

    /// The method a scan gets when none is named (`auto`), with the reason in words: [`Method::Lct`] on a
    /// confocal scan whose points form a regular grid (the LCT's resampling needs both), [`Method::Pf`] on
    /// everything else.
    pub fn for_scan(scan: &Scan) -> (Method, &'static str) {
        if scan.is_confocal() && scan.sensors().grid_dims().is_some() {
            (Method::Lct, "a confocal scan on a regular grid: the light-cone transform")
        } else if scan.is_confocal() {
            (Method::Pf, "a confocal scan whose points are no regular grid: the phasor field")
        } else if matches!(scan.pattern, ScanPattern::Paired { .. }) {
            (Method::Pf, "a paired scan (laser spot i with sensor spot i): the phasor field")
        } else {
            (Method::Pf, "a non-confocal scan (lasers × sensors): the phasor field")
        }
    }

    /// The method's volume of a capture whose direct light is gated already (as `nlos reconstruct` prepares
    /// it), weighted for `reflectance`: the LCT and the filtered backprojection by the path length to the
    /// model's [`Model::distance_power`], the LCT's Wiener SNR the model's ([`lct_params`]; `snr` replaces
    /// it). The phasor field runs ungated and uncut; the other methods keep their automatic gate, which finds
    /// no direct light left in a gated capture.
    ///
    /// # Errors
    /// Those of the method: [`InitError::NotConfocal`] or [`InitError::NotGrid`] for a scan it cannot take,
    /// [`InitError::Empty`] for an empty volume, …
    pub fn volume(self, gated: &Transient, reflectance: Model, snr: Option<f64>) -> Result<Volume> {
        match self {
            Method::Lct => {
                let p = lct_params(reflectance);
                lct(gated, &LctParams { snr: snr.unwrap_or(p.snr), ..p })
            }
            Method::Fk => fk(gated, &FkParams::default()),
            Method::Fbp => fbp(gated, &FbpParams { reflectance, ..FbpParams::default() }),
            Method::Pf => {
                pf(gated, &PfParams { reflectance, gate: Gate::None, max_depth: None, ..PfParams::default() })
            }
            Method::Carve => carve(gated, &CarveParams::default()),
        }
    }

    /// The method's volume of `gated` without the clamp at zero, where the method is linear in the data: the
    /// LCT (its settings for `reflectance`, [`lct_params`], with [`LctParams::clamp`] off and no gate of its
    /// own: `gated` is gated already). The volume of a difference is then the difference of the volumes, so a
    /// residual back-projected keeps its sign, and its noise averages out instead of being cut in half. `None`
    /// for the other methods: f-k and the phasor field take a magnitude, carving is not a transform, and
    /// FBP's Laplacian is the LCT's.
    pub fn signed_volume(self, gated: &Transient, reflectance: Model) -> Option<Result<Volume>> {
        match self {
            Method::Lct => Some(lct(gated, &LctParams { clamp: false, gate: Gate::None, ..lct_params(reflectance) })),
            Method::Fk | Method::Fbp | Method::Pf | Method::Carve => None,
        }
    }

    /// The surface extraction of the method's start: the settings for compact objects for the LCT and the
    /// phasor field ([`SurfaceParams::object`]: Otsu's threshold alone keeps only the brightest columns,
    /// about half the bunny's silhouette from the LCT, a fifth from the one-laser phasor field), the plain
    /// extraction otherwise.
    pub fn surface_params(self) -> SurfaceParams {
        match self {
            Method::Lct | Method::Pf => SurfaceParams::object(),
            Method::Fk | Method::Fbp | Method::Carve => SurfaceParams::default(),
        }
    }
}

/// The LCT settings of a reflectance model: its weighting and Wiener SNR — 0.1 for diffuse (tuned on the
/// simulated bunny; the captures' reference code uses 0.08 on 16 ps bins for its diffuse S), 0.8 for
/// retroreflective (the reference code's value for its retroreflective scenes). A retroreflective scene
/// (`1/r²` in a confocal scan) gets the light-cone transform's retroreflective weighting, a diffuse one
/// (`1/r⁴`) the diffuse weighting (O'Toole, Lindell & Wetzstein 2018: data weighted by `t²` or `t⁴`).
pub fn lct_params(reflectance: Model) -> LctParams {
    // Keyed on the return's fall-off (`Model::distance_power`): a 1/r² return takes the retroreflective SNR.
    let snr = match reflectance.distance_power() {
        2 => 0.8,
        _ => LctParams::default().snr,
    };
    LctParams { reflectance, snr, ..LctParams::default() }
}

/// The methods' names as a sentence lists them: `"lct", "fk", … or "carve"`.
fn one_of() -> String {
    let names: Vec<String> = Method::ALL.iter().map(|m| format!("{:?}", m.name())).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => names.concat(),
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = InitError;

    /// # Errors
    /// [`InitError::UnknownMethod`] for any other name.
    fn from_str(s: &str) -> Result<Self> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| InitError::UnknownMethod { got: s.into(), known: one_of() })
    }
}

/// Where the optimisation starts: `"auto"`, a [`Method`] by name, or the path of a mesh file.
///
/// ```
/// use nlos_init::{InitMethod, Method};
/// use nlos_transient::{PointSet, Scan};
/// assert_eq!("fbp".parse::<InitMethod>(), Ok(InitMethod::Volume(Method::Fbp)));
/// assert_eq!("start.obj".parse::<InitMethod>(), Ok(InitMethod::Mesh("start.obj".into())));
/// let one_laser = Scan::exhaustive(PointSet::list(vec![glam::Vec3::ZERO]), PointSet::wall_grid(4, 4, 0.1, 0.1)?);
/// assert_eq!(InitMethod::Auto.resolve(&one_laser).0, InitMethod::Volume(Method::Pf));
/// # Ok::<(), nlos_transient::TransientError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(from = "String", into = "String")]
pub enum InitMethod {
    /// The method of [`Method::for_scan`].
    #[default]
    Auto,
    /// This volumetric method's volume turned into a mesh.
    Volume(Method),
    /// A mesh file (OBJ, PLY, GLB) whose faces face the wall.
    Mesh(PathBuf),
}

impl InitMethod {
    /// What `auto` chooses for `scan` ([`Method::for_scan`]), with the reason in words; a method or mesh
    /// given is returned as it is, "as set".
    pub fn resolve(&self, scan: &Scan) -> (Self, &'static str) {
        match self {
            Self::Auto => {
                let (method, why) = Method::for_scan(scan);
                (Self::Volume(method), why)
            }
            other => (other.clone(), "as set"),
        }
    }
}

impl FromStr for InitMethod {
    type Err = std::convert::Infallible;
    /// `"auto"`, a method's name, else a mesh file's path.
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        Ok(match s {
            "auto" => Self::Auto,
            _ => s.parse::<Method>().map_or_else(|_| Self::Mesh(s.into()), Self::Volume),
        })
    }
}

impl From<String> for InitMethod {
    fn from(s: String) -> Self {
        match s.parse() {
            Ok(m) => m,
            Err(e) => match e {},
        }
    }
}

impl From<InitMethod> for String {
    fn from(m: InitMethod) -> Self {
        m.to_string()
    }
}

impl fmt::Display for InitMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Auto => f.write_str("auto"),
            Self::Volume(m) => f.write_str(m.name()),
            Self::Mesh(p) => write!(f, "{}", p.display()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nlos_transient::PointSet;

    #[test]
    fn names_round_trip() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>().expect("own name"), m);
            let start = InitMethod::Volume(m);
            assert_eq!(start.to_string().parse::<InitMethod>(), Ok(start.clone()));
            let json = serde_json::to_string(&start).expect("serialise");
            assert_eq!(json, format!("\"{m}\""));
        }
        assert_eq!("auto".parse::<InitMethod>(), Ok(InitMethod::Auto));
        let e = "LCT".parse::<Method>().expect_err("names are lower case");
        assert!(e.to_string().contains("\"lct\", \"fk\", \"fbp\", \"pf\" or \"carve\""), "{e}");
    }

    /// `auto`: the LCT only where its resampling works (confocal and a grid); the phasor field elsewhere.
    #[test]
    fn every_scan_gets_a_method_it_takes() {
        let grid = PointSet::wall_grid(4, 4, 0.1, 0.1).expect("grid");
        let list = PointSet::list(grid.points.clone());
        let one = PointSet::list(vec![glam::Vec3::ZERO]);
        for (scan, want) in [
            (Scan::confocal(grid.clone()), Method::Lct),
            (Scan::confocal(list), Method::Pf),
            (Scan::exhaustive(one, grid.clone()), Method::Pf),
            (Scan::exhaustive(grid.clone(), grid.clone()), Method::Pf),
            (Scan::paired(grid.clone(), grid.clone()), Method::Pf),
        ] {
            assert_eq!(Method::for_scan(&scan).0, want, "{scan:?}");
            assert_eq!(InitMethod::Auto.resolve(&scan).0, InitMethod::Volume(want));
            assert_eq!(InitMethod::Volume(Method::Fk).resolve(&scan).0, InitMethod::Volume(Method::Fk));
        }
    }
}
