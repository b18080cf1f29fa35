//! [`RenderBrdf`]: what the renderer needs from an `nlos_brdf` model beyond [`Brdf`] — its parameters as a
//! flat vector, so gradients and finite differences can be written once for every model; [`AnyBrdf`]: one
//! BRDF of a [`Model`] chosen at run time, and [`with_brdf!`](crate::with_brdf) to call the renderer's
//! generic passes with it.

use nlos_brdf::{Brdf, Fresnel, Ggx, GgxGrad, Lambertian, LambertianGrad, Model, Retroreflective, RetroreflectiveGrad};

use crate::error::Result;

/// An `f32` BRDF whose parameters the renderer differentiates.
pub trait RenderBrdf: Brdf<Scalar = f32> {
    /// Parameter names, in the order of [`RenderBrdf::params`] and of `Gradient::brdf`.
    const PARAM_NAMES: &'static [&'static str];
    /// The parameter vector.
    fn params(&self) -> Vec<f32>;
    /// The same model with other parameter values (validated by the model's constructor).
    ///
    /// # Errors
    /// [`crate::RenderError::Brdf`] when a value is out of the model's domain.
    fn with_params(&self, params: &[f32]) -> Result<Self>;
    /// `∂f/∂(parameters)` as an array (first `PARAM_NAMES.len()` entries used).
    fn param_grad_array(g: &Self::ParamGrad) -> [f32; 4];
    /// The model, by name.
    const MODEL: Model;
    /// The power of the path length τ by which the measurement of a small face falls along a confocal path
    /// ([`Model::distance_power`]: 4, or 2 for [`Retroreflective`]). The splat rule's fall-off correction
    /// uses it.
    const DISTANCE_POWER: f32 = Self::MODEL.distance_power() as f32;
    /// The roughness α of a glossy (microfacet) lobe worth importance sampling, None for none (the
    /// default). Used by the lobe sampling of `Renderer::set_lobe_sampling`.
    fn lobe_alpha(&self) -> Option<f32> {
        None
    }
    /// The same BRDF as an [`AnyBrdf`] (what the GPU backend reads the shader's terms from).
    fn to_any(&self) -> AnyBrdf;
}

/// A BRDF as the GPU backend's shader (feature `gpu`, `shader.wgsl`) evaluates it: which of its models
/// (`kind`: the shader's `Params.brdf`) and that model's terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GpuTerms {
    /// The shader's model: 0 Lambertian, 1 retroreflective.
    pub(crate) kind: u32,
    /// ρ.
    pub(crate) albedo: f32,
    /// `1/σ²` of the retroreflective lobe of width σ (0 for the Lambertian).
    pub(crate) inv_w2: f32,
}

impl RenderBrdf for Lambertian<f32> {
    const PARAM_NAMES: &'static [&'static str] = &["albedo"];
    const MODEL: Model = Model::Lambert;
    fn params(&self) -> Vec<f32> {
        vec![self.albedo()]
    }
    fn with_params(&self, params: &[f32]) -> Result<Self> {
        Ok(Lambertian::new(params.first().copied().unwrap_or(f32::NAN))?)
    }
    #[inline(always)]
    fn param_grad_array(g: &LambertianGrad<f32>) -> [f32; 4] {
        [g.albedo, 0.0, 0.0, 0.0]
    }
    fn to_any(&self) -> AnyBrdf {
        AnyBrdf::Lambertian(*self)
    }
}

impl RenderBrdf for Ggx<f32> {
    const PARAM_NAMES: &'static [&'static str] = &["albedo_diffuse", "specular", "alpha", "f0"];
    const MODEL: Model = Model::Ggx;
    fn params(&self) -> Vec<f32> {
        let f0 = match self.fresnel() {
            Fresnel::One => 1.0,
            Fresnel::Schlick { f0 } => f0,
        };
        vec![self.albedo_diffuse(), self.specular(), self.alpha(), f0]
    }
    fn with_params(&self, p: &[f32]) -> Result<Self> {
        let get = |i: usize| p.get(i).copied().unwrap_or(f32::NAN);
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
    fn to_any(&self) -> AnyBrdf {
        AnyBrdf::Ggx(*self)
    }
}

impl RenderBrdf for Retroreflective<f32> {
    const PARAM_NAMES: &'static [&'static str] = &["albedo"];
    const MODEL: Model = Model::Retroreflective;
    fn params(&self) -> Vec<f32> {
        vec![self.albedo()]
    }
    fn with_params(&self, params: &[f32]) -> Result<Self> {
        Ok(Retroreflective::with_lobe_width(params.first().copied().unwrap_or(f32::NAN), self.lobe_width())?)
    }
    #[inline(always)]
    fn param_grad_array(g: &RetroreflectiveGrad<f32>) -> [f32; 4] {
        [g.albedo, 0.0, 0.0, 0.0]
    }
    fn to_any(&self) -> AnyBrdf {
        AnyBrdf::Retroreflective(*self)
    }
}

/// One BRDF of any [`Model`], for code that picks the model at run time (settings, the command line,
/// Python); [`with_brdf!`](crate::with_brdf) calls the renderer's generic passes with the concrete type, so
/// the inner loops stay monomorphised (`nlos_brdf`'s design).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnyBrdf {
    /// [`Model::Lambert`].
    Lambertian(Lambertian<f32>),
    /// [`Model::Ggx`].
    Ggx(Ggx<f32>),
    /// [`Model::Retroreflective`].
    Retroreflective(Retroreflective<f32>),
}

/// Calls `$body` with `$b` bound to the concrete BRDF of an [`AnyBrdf`]:
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
    /// [`crate::RenderError::Brdf`] for a value outside the model's domain.
    pub fn new(model: Model, albedo: f32, specular: f32, alpha: f32) -> Result<Self> {
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
    /// [`crate::RenderError::Brdf`] for an `alpha` outside GGX's range.
    pub fn unit(model: Model, alpha: f32) -> Result<Self> {
        let albedo = if model == Model::Ggx { 0.0 } else { 1.0 };
        Self::new(model, albedo, 1.0, alpha)
    }

    /// The BRDF as the GPU backend's shader evaluates it, None for a model it has no version of (GGX). The one
    /// place that maps a BRDF to the shader: [`gpu_support`] asks it which models run on the GPU.
    pub(crate) fn gpu_terms(&self) -> Option<GpuTerms> {
        match self {
            AnyBrdf::Lambertian(b) => Some(GpuTerms { kind: 0, albedo: b.albedo(), inv_w2: 0.0 }),
            AnyBrdf::Retroreflective(b) => {
                Some(GpuTerms { kind: 1, albedo: b.albedo(), inv_w2: 1.0 / (b.lobe_width() * b.lobe_width()) })
            }
            AnyBrdf::Ggx(_) => None,
        }
    }

    /// The model ([`RenderBrdf::MODEL`]).
    pub fn model(&self) -> Model {
        with_brdf!(self, b => model_of(b))
    }

    /// The BRDF in words, with its fitted parameters (the run report's line).
    pub fn describe(&self) -> String {
        match self {
            AnyBrdf::Lambertian(b) => format!("Lambertian, albedo {:.4}", b.albedo()),
            AnyBrdf::Ggx(b) => format!(
                "GGX, alpha {:.4}, specular {:.4}, diffuse albedo {:.4}",
                b.alpha(),
                b.specular(),
                b.albedo_diffuse()
            ),
            AnyBrdf::Retroreflective(b) => format!("retroreflective, return {:.4}", b.albedo()),
        }
    }

    /// Parameter names, in the order of [`AnyBrdf::params`] and of [`crate::Gradient::brdf`].
    pub fn param_names(&self) -> &'static [&'static str] {
        with_brdf!(self, b => param_names_of(b))
    }

    /// The parameter vector ([`RenderBrdf::params`]).
    pub fn params(&self) -> Vec<f32> {
        with_brdf!(self, b => b.params())
    }

    /// The same model with parameters `p` (in [`AnyBrdf::param_names`] order).
    ///
    /// # Errors
    /// [`crate::RenderError::Brdf`] when a value is out of the model's domain.
    pub fn with_params(&self, p: &[f32]) -> Result<Self> {
        Ok(match self {
            AnyBrdf::Lambertian(b) => AnyBrdf::Lambertian(b.with_params(p)?),
            AnyBrdf::Ggx(b) => AnyBrdf::Ggx(b.with_params(p)?),
            AnyBrdf::Retroreflective(b) => AnyBrdf::Retroreflective(b.with_params(p)?),
        })
    }
}

/// The renderer's passes with the concrete BRDF ([`crate::Renderer`]'s generic methods of the same names).
impl AnyBrdf {
    /// [`crate::Renderer::forward`].
    pub fn forward(&self, r: &crate::Renderer) -> Vec<f32> {
        with_brdf!(self, b => r.forward(b))
    }

    /// [`crate::Renderer::forward_triangle`].
    ///
    /// # Errors
    /// As `Renderer::forward_triangle`: a triangle index out of range.
    pub fn forward_triangle(&self, r: &crate::Renderer, triangle: usize) -> Result<Vec<crate::RowSpan>> {
        with_brdf!(self, b => r.forward_triangle(b, triangle))
    }

    /// [`crate::Renderer::adjoint`].
    ///
    /// # Errors
    /// As `Renderer::adjoint`.
    pub fn adjoint(&self, r: &crate::Renderer, d_loss: &[f32]) -> Result<crate::Gradient> {
        with_brdf!(self, b => r.adjoint(b, d_loss))
    }
}

fn param_names_of<B: RenderBrdf>(_: &B) -> &'static [&'static str] {
    B::PARAM_NAMES
}

fn model_of<B: RenderBrdf>(_: &B) -> Model {
    B::MODEL
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every model's BRDF names its model and describes itself (the report's line), and the GPU's terms
    /// exist exactly for the models `gpu_support` accepts.
    #[test]
    fn every_model_names_and_describes_itself() {
        let splat = crate::RenderParams {
            kernel: crate::Kernel::Tent,
            visibility: crate::Visibility::Off,
            sampling: crate::Sampling::Splat(crate::SplatRule::default()),
            ..crate::RenderParams::default()
        };
        for model in Model::ALL {
            let b = AnyBrdf::unit(model, 0.3).expect("unit");
            assert_eq!(b.model(), model);
            assert!(!b.describe().is_empty());
            assert_eq!(b.gpu_terms().is_some(), crate::gpu_support(model, &splat).is_ok(), "{model}");
        }
        assert_eq!(
            AnyBrdf::unit(Model::Retroreflective, 0.3).expect("unit").describe(),
            "retroreflective, return 1.0000"
        );
    }
}
