//! The surface reflectance being optimised, held in the unconstrained θ space of `nlos_brdf::param`
//! (softplus albedos, logistic α and F0), and the dispatch of renderer calls to the concrete BRDF type.

use nlos_brdf::{
    Fresnel, Ggx, GgxGrad, GgxTheta, Lambertian, LambertianTheta, Masking, Model, Retroreflective, param::sigmoid,
};
use nlos_render::AnyBrdf;
use serde::{Deserialize, Serialize};

use crate::error::Result;

/// A reflectance model with its parameters θ (f64, exact in checkpoints).
///
/// With the global intensity scale solved in closed form (`DataTerm::solve_scale`) the overall albedo level
/// is absorbed by the scale: the Lambertian albedo then has zero gradient, and for GGX only the ratio of
/// the lobes, α and F0 are really determined by the data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Reflectance {
    /// Lambertian, `albedo = softplus(theta)`.
    Lambertian {
        /// θ of the albedo.
        theta: f64,
    },
    /// GGX over a Lambertian base (`nlos_brdf::Ggx`), θ = (ρ_d, ρ_s, α, F0) as in [`GgxTheta`].
    Ggx {
        /// θ of (albedo_diffuse, specular, alpha, f0).
        theta: [f64; 4],
        /// Schlick Fresnel (else F = 1; then θ_f0 is not optimised).
        schlick: bool,
        /// Masking-shadowing model.
        masking: Masking,
    },
    /// Retroreflective (`nlos_brdf::Retroreflective`, default 1° lobe), `albedo = softplus(theta)`: the
    /// confocal return falls as `1/r²`.
    Retroreflective {
        /// θ of the return ρ.
        theta: f64,
    },
}

impl Default for Reflectance {
    /// Lambertian with albedo 1.
    fn default() -> Self {
        Reflectance::Lambertian { theta: nlos_brdf::param::softplus_inv(1.0f64) }
    }
}

impl Reflectance {
    /// The start of a fit of `model`: [`AnyBrdf::unit`] (albedo 1; GGX's specular lobe alone, of roughness
    /// `alpha`, without a Fresnel term).
    ///
    /// # Errors
    /// [`crate::OptimError::Render`] for an `alpha` outside GGX's range.
    pub fn start(model: Model, alpha: f32) -> Result<Self> {
        Ok(match AnyBrdf::unit(model, alpha)? {
            AnyBrdf::Lambertian(_) => Reflectance::default(),
            AnyBrdf::Ggx(g) => Reflectance::from_ggx(&g),
            AnyBrdf::Retroreflective(_) => Reflectance::retroreflective(),
        })
    }

    /// From a Lambertian BRDF.
    pub fn from_lambertian(b: &Lambertian<f32>) -> Self {
        Reflectance::Lambertian { theta: f64::from(LambertianTheta::from_lambertian(b).albedo) }
    }

    /// A retroreflector of return 1.
    pub fn retroreflective() -> Self {
        Reflectance::Retroreflective { theta: nlos_brdf::param::softplus_inv(1.0f64) }
    }

    /// Whether the model is one albedo (Lambertian or retroreflective): a pure scale factor of the
    /// rendering, which the closed-form scale absorbs.
    pub fn is_scale_only(&self) -> bool {
        matches!(self, Reflectance::Lambertian { .. } | Reflectance::Retroreflective { .. })
    }

    /// From a GGX BRDF.
    pub fn from_ggx(b: &Ggx<f32>) -> Self {
        let t = GgxTheta::from_ggx(b);
        Reflectance::Ggx {
            theta: [t.albedo_diffuse, t.specular, t.alpha, t.f0].map(f64::from),
            schlick: matches!(b.fresnel(), Fresnel::Schlick { .. }),
            masking: b.masking(),
        }
    }

    /// The BRDF θ maps to.
    ///
    /// # Errors
    /// [`crate::OptimError::Brdf`] only for a non-finite θ.
    pub fn brdf(&self) -> Result<AnyBrdf> {
        Ok(match self {
            Reflectance::Lambertian { theta } => {
                AnyBrdf::Lambertian(LambertianTheta { albedo: *theta as f32 }.to_lambertian()?)
            }
            Reflectance::Ggx { theta, schlick, masking } => {
                let t = GgxTheta {
                    albedo_diffuse: theta[0] as f32,
                    specular: theta[1] as f32,
                    alpha: theta[2] as f32,
                    f0: theta[3] as f32,
                };
                AnyBrdf::Ggx(t.to_ggx(*schlick, *masking)?)
            }
            Reflectance::Retroreflective { theta } => {
                let rho = LambertianTheta { albedo: *theta as f32 }.to_lambertian()?.albedo();
                AnyBrdf::Retroreflective(Retroreflective::new(rho)?)
            }
        })
    }

    /// θ as a vector (the optimised components only: F0 only with Schlick Fresnel).
    pub fn theta(&self) -> Vec<f64> {
        match self {
            Reflectance::Lambertian { theta } | Reflectance::Retroreflective { theta } => vec![*theta],
            Reflectance::Ggx { theta, schlick, .. } => theta[..if *schlick { 4 } else { 3 }].to_vec(),
        }
    }

    /// Adds `delta` (as from [`Reflectance::theta`]) to θ.
    pub fn add_theta(&mut self, delta: &[f64]) {
        match self {
            Reflectance::Lambertian { theta } | Reflectance::Retroreflective { theta } => {
                *theta += delta.first().copied().unwrap_or(0.0);
            }
            Reflectance::Ggx { theta, .. } => {
                for (t, d) in theta.iter_mut().zip(delta) {
                    *t += d;
                }
            }
        }
    }

    /// Chain rule: dE/dθ from the renderer's dE/d(physical parameters) (order of `RenderBrdf::PARAM_NAMES`).
    pub fn chain(&self, physical: &[f32]) -> Vec<f64> {
        let get = |i: usize| physical.get(i).copied().unwrap_or(0.0);
        match self {
            Reflectance::Lambertian { theta } | Reflectance::Retroreflective { theta } => {
                vec![f64::from(get(0)) * sigmoid(*theta)]
            }
            Reflectance::Ggx { theta, schlick, .. } => {
                let t = GgxTheta { albedo_diffuse: theta[0], specular: theta[1], alpha: theta[2], f0: theta[3] };
                let g = GgxGrad {
                    albedo_diffuse: f64::from(get(0)),
                    specular: f64::from(get(1)),
                    alpha: f64::from(get(2)),
                    f0: f64::from(get(3)),
                };
                let c = t.chain(&g);
                let all = [c.albedo_diffuse, c.specular, c.alpha, c.f0];
                all[..if *schlick { 4 } else { 3 }].to_vec()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn theta_round_trips_and_chain_matches_finite_differences() {
        let g = Ggx::new(0.3f32, 0.8, 0.3, Fresnel::Schlick { f0: 0.2 }).expect("valid");
        let r = Reflectance::from_ggx(&g);
        let AnyBrdf::Ggx(back) = r.brdf().expect("finite") else { unreachable!("ggx") };
        assert!((back.alpha() - 0.3).abs() < 1e-5 && (back.albedo_diffuse() - 0.3).abs() < 1e-5);
        // d(physical)/dθ against finite differences of the maps, component by component.
        for k in 0..4 {
            let mut phys = [0.0f32; 4];
            phys[k] = 1.0;
            let an = r.chain(&phys)[k];
            let h = 1e-3;
            let val = |d: f64| {
                let mut rr = r.clone();
                let mut delta = [0.0; 4];
                delta[k] = d;
                rr.add_theta(&delta);
                let AnyBrdf::Ggx(b) = rr.brdf().expect("finite") else { unreachable!("ggx") };
                let f0 = b.fresnel().f0().unwrap_or(0.0);
                f64::from([b.albedo_diffuse(), b.specular(), b.alpha(), f0][k])
            };
            let fd = (val(h) - val(-h)) / (2.0 * h);
            assert!((fd - an).abs() < 1e-3 * (1.0 + an.abs()), "param {k}: fd {fd} vs {an}");
        }
        assert_eq!(Reflectance::default().theta().len(), 1);
    }
}
