//! [`Model`]: which reflectance model, by name — the one choice read by the settings (`reflectance.model`),
//! the command line (`--brdf`), Python (`brdf=`), the volumetric starts' weighting and the renderer; and
//! [`AnyBrdf`], one BRDF of a model chosen at run time, with [`with_brdf!`](crate::with_brdf) to reach its
//! concrete type; and [`FittedBrdf`], what rendering and fitting need of each model beyond [`Brdf`]: its
//! parameters as a flat vector (so the renderer's gradients and every finite-difference test are written once
//! for all models) and its unconstrained parameters θ (`crate::param`) with their chain rule (so the optimiser's
//! reflectance steps are written once too). Everything a model is known by at run time stands here, so that
//! adding one touches its own file, this one and `lib.rs`.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::BrdfError;
use crate::error::Result as BrdfResult;
use crate::ggx::{Ggx, GgxGrad};
use crate::lambert::{Lambertian, LambertianGrad};
use crate::param;
use crate::retro::{Retroreflective, RetroreflectiveGrad};
use crate::{Brdf, Fresnel};

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

/// An `f32` BRDF whose parameters are rendered, differentiated and fitted.
///
/// Two parametrisations: the physical parameters ([`FittedBrdf::params`], in [`FittedBrdf::PARAM_NAMES`]
/// order, the renderer's `Gradient::brdf`), and θ ([`FittedBrdf::theta`]), the unconstrained reals an
/// optimiser moves (the maps of `crate::param`: every finite θ is a valid BRDF). θ lists only the fitted
/// components; what θ leaves fixed (GGX's Fresnel kind and masking, the retroreflector's lobe width) is read
/// from `self`, the template [`FittedBrdf::with_theta`] is called on.
pub trait FittedBrdf: Brdf<Scalar = f32> + Copy {
    /// The model, by name.
    const MODEL: Model;
    /// Parameter names, in the order of [`FittedBrdf::params`] and of the renderer's `Gradient::brdf`.
    const PARAM_NAMES: &'static [&'static str];
    /// The power of the path length τ by which the measurement of a small face falls along a confocal path
    /// ([`Model::distance_power`]: 4, or 2 for a retroreflector). The renderer's splat rule corrects its
    /// fall-off by it.
    const DISTANCE_POWER: f32 = Self::MODEL.distance_power() as f32;
    /// Whether the BRDF is one albedo times a fixed function of the directions: a pure scale of every
    /// rendering, which a closed-form intensity scale absorbs (then θ has nothing left to fit).
    const SCALE_ONLY: bool;

    /// The parameter vector.
    fn params(&self) -> Vec<f32>;
    /// The same model with other parameter values (validated by the model's constructor).
    ///
    /// # Errors
    /// A [`crate::BrdfError`] when a value is out of the model's domain.
    fn with_params(&self, params: &[f32]) -> BrdfResult<Self>;
    /// `∂f/∂(parameters)` as an array (first `PARAM_NAMES.len()` entries used).
    fn param_grad_array(g: &Self::ParamGrad) -> [f32; 4];
    /// The roughness α of a glossy (microfacet) lobe worth importance sampling, None for none (the
    /// default). Used by the renderer's lobe sampling.
    fn lobe_alpha(&self) -> Option<f32> {
        None
    }
    /// The BRDF in words, with its parameters (a run report's line).
    fn describe(&self) -> String;
    /// The same BRDF as an [`AnyBrdf`].
    fn to_any(&self) -> AnyBrdf;

    /// θ of the fitted parameters (f64: an optimiser accumulates steps in it, and checkpoints keep it exact).
    fn theta(&self) -> Vec<f64>;
    /// The BRDF θ maps to, with what θ leaves fixed taken from `self`.
    ///
    /// # Errors
    /// A [`crate::BrdfError`] only for a non-finite θ.
    fn with_theta(&self, theta: &[f64]) -> BrdfResult<Self>;
    /// Chain rule: `∂E/∂θ` at θ from `∂E/∂(physical parameters)` (in [`FittedBrdf::PARAM_NAMES`] order), one
    /// entry per component of θ.
    fn chain_theta(&self, theta: &[f64], d_params: &[f32]) -> Vec<f64>;
}

/// Entry `i` of `v`, or `fallback` past its end (a short vector reads as missing values, which the models'
/// constructors reject when the fallback is NaN).
pub(crate) fn entry<T: Copy>(v: &[T], i: usize, fallback: T) -> T {
    v.get(i).copied().unwrap_or(fallback)
}

/// θ of a one-albedo model: `softplus⁻¹ ρ`, in f64 ([`crate::LambertianTheta`]'s map).
fn albedo_theta(albedo: f32) -> Vec<f64> {
    vec![param::softplus_inv(f64::from(albedo))]
}

/// The albedo `softplus θ₀` (NaN, which the constructors refuse, for a missing θ₀).
fn albedo_of_theta(theta: &[f64]) -> f32 {
    param::softplus(entry(theta, 0, f64::NAN) as f32)
}

/// `∂E/∂θ₀ = ∂E/∂ρ · σ(θ₀)`.
fn albedo_chain(theta: &[f64], d_params: &[f32]) -> Vec<f64> {
    vec![f64::from(entry(d_params, 0, 0.0)) * param::sigmoid(entry(theta, 0, 0.0))]
}

/// θ = (softplus⁻¹ ρ) ([`crate::LambertianTheta`], in f64).
impl FittedBrdf for Lambertian<f32> {
    const MODEL: Model = Model::Lambert;
    const PARAM_NAMES: &'static [&'static str] = &["albedo"];
    const SCALE_ONLY: bool = true;
    fn params(&self) -> Vec<f32> {
        vec![self.albedo()]
    }
    fn with_params(&self, params: &[f32]) -> BrdfResult<Self> {
        Lambertian::new(entry(params, 0, f32::NAN))
    }
    #[inline(always)]
    fn param_grad_array(g: &LambertianGrad<f32>) -> [f32; 4] {
        [g.albedo, 0.0, 0.0, 0.0]
    }
    fn describe(&self) -> String {
        format!("Lambertian, albedo {:.4}", self.albedo())
    }
    fn to_any(&self) -> AnyBrdf {
        AnyBrdf::Lambertian(*self)
    }
    fn theta(&self) -> Vec<f64> {
        albedo_theta(self.albedo())
    }
    fn with_theta(&self, theta: &[f64]) -> BrdfResult<Self> {
        Lambertian::new(albedo_of_theta(theta))
    }
    fn chain_theta(&self, theta: &[f64], d_params: &[f32]) -> Vec<f64> {
        albedo_chain(theta, d_params)
    }
}

/// θ = (softplus⁻¹ ρ) of the return, in f64; the lobe width is kept.
impl FittedBrdf for Retroreflective<f32> {
    const MODEL: Model = Model::Retroreflective;
    const PARAM_NAMES: &'static [&'static str] = &["albedo"];
    const SCALE_ONLY: bool = true;
    fn params(&self) -> Vec<f32> {
        vec![self.albedo()]
    }
    fn with_params(&self, params: &[f32]) -> BrdfResult<Self> {
        Retroreflective::with_lobe_width(entry(params, 0, f32::NAN), self.lobe_width())
    }
    #[inline(always)]
    fn param_grad_array(g: &RetroreflectiveGrad<f32>) -> [f32; 4] {
        [g.albedo, 0.0, 0.0, 0.0]
    }
    fn describe(&self) -> String {
        format!("retroreflective, return {:.4}", self.albedo())
    }
    fn to_any(&self) -> AnyBrdf {
        AnyBrdf::Retroreflective(*self)
    }
    fn theta(&self) -> Vec<f64> {
        albedo_theta(self.albedo())
    }
    fn with_theta(&self, theta: &[f64]) -> BrdfResult<Self> {
        Retroreflective::with_lobe_width(albedo_of_theta(theta), self.lobe_width())
    }
    fn chain_theta(&self, theta: &[f64], d_params: &[f32]) -> Vec<f64> {
        albedo_chain(theta, d_params)
    }
}

/// θ = [`param::GgxTheta`] (ρ_d, ρ_s, α, and F0 only with Schlick Fresnel); the Fresnel kind and the masking
/// are kept.
impl FittedBrdf for Ggx<f32> {
    const MODEL: Model = Model::Ggx;
    const PARAM_NAMES: &'static [&'static str] = &["albedo_diffuse", "specular", "alpha", "f0"];
    const SCALE_ONLY: bool = false;
    fn params(&self) -> Vec<f32> {
        let f0 = self.fresnel().f0().unwrap_or(1.0);
        vec![self.albedo_diffuse(), self.specular(), self.alpha(), f0]
    }
    fn with_params(&self, p: &[f32]) -> BrdfResult<Self> {
        let get = |i: usize| entry(p, i, f32::NAN);
        let fresnel = match self.fresnel() {
            Fresnel::One => Fresnel::One,
            Fresnel::Schlick { .. } => Fresnel::Schlick { f0: get(3) },
        };
        Ok(Ggx::new(get(0), get(1), get(2), fresnel)?.with_masking(self.masking()))
    }
    #[inline(always)]
    fn param_grad_array(g: &GgxGrad<f32>) -> [f32; 4] {
        [g.albedo_diffuse, g.specular, g.alpha, g.f0]
    }
    fn lobe_alpha(&self) -> Option<f32> {
        (self.specular() > 0.0).then_some(self.alpha())
    }
    fn describe(&self) -> String {
        format!(
            "GGX, alpha {:.4}, specular {:.4}, diffuse albedo {:.4}",
            self.alpha(),
            self.specular(),
            self.albedo_diffuse()
        )
    }
    fn to_any(&self) -> AnyBrdf {
        AnyBrdf::Ggx(*self)
    }
    fn theta(&self) -> Vec<f64> {
        let t = param::GgxTheta::from_ggx(self);
        let all = [t.albedo_diffuse, t.specular, t.alpha, t.f0].map(f64::from);
        all[..self.fitted_len()].to_vec()
    }
    fn with_theta(&self, theta: &[f64]) -> BrdfResult<Self> {
        let get = |i: usize| entry(theta, i, if i == 3 { 0.0 } else { f64::NAN }) as f32;
        let t = param::GgxTheta { albedo_diffuse: get(0), specular: get(1), alpha: get(2), f0: get(3) };
        t.to_ggx(self.fitted_len() == 4, self.masking())
    }
    fn chain_theta(&self, theta: &[f64], d_params: &[f32]) -> Vec<f64> {
        let t = |i: usize| entry(theta, i, 0.0);
        let d = |i: usize| f64::from(entry(d_params, i, 0.0));
        let t = param::GgxTheta { albedo_diffuse: t(0), specular: t(1), alpha: t(2), f0: t(3) };
        let g = GgxGrad { albedo_diffuse: d(0), specular: d(1), alpha: d(2), f0: d(3) };
        let c = t.chain(&g);
        [c.albedo_diffuse, c.specular, c.alpha, c.f0][..self.fitted_len()].to_vec()
    }
}

impl Ggx<f32> {
    /// The number of fitted θ components: F0 only with Schlick Fresnel.
    fn fitted_len(&self) -> usize {
        if matches!(self.fresnel(), Fresnel::Schlick { .. }) { 4 } else { 3 }
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
