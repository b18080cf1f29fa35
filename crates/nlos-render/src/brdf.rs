//! The BRDF as the GPU backend's shader (feature `gpu`, `shader.wgsl`) evaluates it: [`gpu_terms`], the one
//! place that maps an [`AnyBrdf`] to the shader. The models themselves, their parameter vectors and
//! [`AnyBrdf`] live in `nlos_brdf` ([`nlos_brdf::FittedBrdf`]).

use nlos_brdf::AnyBrdf;

/// A BRDF as the shader evaluates it: which of its models (`kind`: the shader's `Params.brdf`) and that
/// model's terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GpuTerms {
    /// The shader's model: 0 Lambertian, 1 retroreflective.
    pub(crate) kind: u32,
    /// ρ.
    pub(crate) albedo: f32,
    /// `1/σ²` of the retroreflective lobe of width σ (0 for the Lambertian).
    pub(crate) inv_w2: f32,
}

/// The BRDF as the shader evaluates it, None for a model it has no version of. [`crate::gpu_support`] asks
/// it which models run on the GPU; a model added to `nlos_brdf` runs on the CPU until it has an arm here and
/// in the shader.
pub(crate) fn gpu_terms(brdf: &AnyBrdf) -> Option<GpuTerms> {
    match brdf {
        AnyBrdf::Lambertian(b) => Some(GpuTerms { kind: 0, albedo: b.albedo(), inv_w2: 0.0 }),
        AnyBrdf::Retroreflective(b) => {
            Some(GpuTerms { kind: 1, albedo: b.albedo(), inv_w2: 1.0 / (b.lobe_width() * b.lobe_width()) })
        }
        // No shader version (GGX, and any model added since): the CPU renders it.
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nlos_brdf::Model;

    /// The GPU's terms exist exactly for the models `gpu_support` accepts.
    #[test]
    fn gpu_terms_exist_where_gpu_support_accepts() {
        let splat = crate::RenderParams {
            kernel: crate::Kernel::Tent,
            visibility: crate::Visibility::Off,
            sampling: crate::Sampling::Splat(crate::SplatRule::default()),
            ..crate::RenderParams::default()
        };
        for model in Model::ALL {
            let b = AnyBrdf::unit(model, 0.3).expect("unit");
            assert_eq!(gpu_terms(&b).is_some(), crate::gpu_support(model, &splat).is_ok(), "{model}");
        }
    }
}
