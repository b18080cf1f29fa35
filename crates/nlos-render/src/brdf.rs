//! [`RenderBrdf`]: what the renderer needs from an `nlos_brdf` model beyond [`Brdf`] — its parameters as a
//! flat vector, so gradients and finite differences can be written once for every model.

use nlos_brdf::{Brdf, Fresnel, Ggx, GgxGrad, Lambertian, LambertianGrad, Retroreflective, RetroreflectiveGrad};

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
    /// The power of the path length τ by which the measurement of a small face falls along a confocal path:
    /// 4 for models whose value does not depend on distance (the `1/(|a|²|b|²)` of eq. 2), 2 for
    /// [`Retroreflective`] (its value grows as `|a||b|`). The splat rule's fall-off correction uses it.
    const DISTANCE_POWER: f32 = 4.0;
    /// The roughness α of a glossy (microfacet) lobe worth importance sampling, None for none (the
    /// default). Used by the lobe sampling of `Renderer::set_lobe_sampling`.
    fn lobe_alpha(&self) -> Option<f32> {
        None
    }
    /// The model as the GPU backend evaluates it, None where it has no GPU version (the default).
    fn gpu_model(&self) -> Option<GpuModel> {
        None
    }
}

/// A BRDF the GPU backend (feature `gpu`) evaluates: its kind and parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GpuModel {
    /// [`Lambertian`] of this albedo.
    Lambertian {
        /// ρ.
        albedo: f32,
    },
    /// [`Retroreflective`] of this return and lobe width (radians).
    Retroreflective {
        /// ρ.
        albedo: f32,
        /// σ.
        lobe_width: f32,
    },
}

impl RenderBrdf for Lambertian<f32> {
    const PARAM_NAMES: &'static [&'static str] = &["albedo"];
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
    fn gpu_model(&self) -> Option<GpuModel> {
        Some(GpuModel::Lambertian { albedo: self.albedo() })
    }
}

impl RenderBrdf for Ggx<f32> {
    const PARAM_NAMES: &'static [&'static str] = &["albedo_diffuse", "specular", "alpha", "f0"];
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
}

impl RenderBrdf for Retroreflective<f32> {
    const PARAM_NAMES: &'static [&'static str] = &["albedo"];
    const DISTANCE_POWER: f32 = 2.0;
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
    fn gpu_model(&self) -> Option<GpuModel> {
        Some(GpuModel::Retroreflective { albedo: self.albedo(), lobe_width: self.lobe_width() })
    }
}
