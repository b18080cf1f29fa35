//! The surface reflectance being optimised, held in the unconstrained θ space of `nlos_brdf::param`
//! (softplus albedos, logistic α and F0), and the dispatch of renderer calls to the concrete BRDF type.

use nlos_brdf::{AnyBrdf, Model};
use serde::{Deserialize, Serialize};

use crate::error::Result;

/// A reflectance model with its parameters θ (f64, exact in checkpoints): [`nlos_brdf::FittedBrdf`]'s θ
/// and maps, whatever the model.
///
/// With the global intensity scale solved in closed form (`DataTerm::solve_scale`) the overall albedo level
/// is absorbed by the scale: a one-albedo model ([`Reflectance::is_scale_only`]) then has zero gradient, and
/// for GGX only the ratio of the lobes, α and F0 are really determined by the data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reflectance {
    /// The model, and what θ leaves fixed (GGX's Fresnel kind and masking, the retroreflector's lobe width);
    /// its fitted values are the start's, [`Reflectance::brdf`] the current ones.
    template: AnyBrdf,
    /// θ of the fitted parameters ([`AnyBrdf::theta`]).
    theta: Vec<f64>,
}

impl Default for Reflectance {
    /// Lambertian with albedo 1.
    fn default() -> Self {
        Reflectance::from_brdf(AnyBrdf::Lambertian(
            nlos_brdf::Lambertian::new(1.0).unwrap_or_else(|_| unreachable!("1 is a valid albedo")),
        ))
    }
}

impl Reflectance {
    /// The start of a fit of `model`: [`AnyBrdf::unit`] (albedo 1; GGX's specular lobe alone, of roughness
    /// `alpha`, without a Fresnel term).
    ///
    /// # Errors
    /// [`crate::OptimError::Brdf`] for an `alpha` outside GGX's range.
    pub fn start(model: Model, alpha: f32) -> Result<Self> {
        Ok(Self::from_brdf(AnyBrdf::unit(model, alpha)?))
    }

    /// A fit that starts from `brdf`.
    pub fn from_brdf(brdf: AnyBrdf) -> Self {
        Self { theta: brdf.theta(), template: brdf }
    }

    /// The model.
    pub fn model(&self) -> Model {
        self.template.model()
    }

    /// Whether the model is one albedo (Lambertian or retroreflective): a pure scale factor of the
    /// rendering, which the closed-form scale absorbs.
    pub fn is_scale_only(&self) -> bool {
        self.template.is_scale_only()
    }

    /// The BRDF θ maps to.
    ///
    /// # Errors
    /// [`crate::OptimError::Brdf`] only for a non-finite θ.
    pub fn brdf(&self) -> Result<AnyBrdf> {
        Ok(self.template.with_theta(&self.theta)?)
    }

    /// θ (the optimised components only: GGX's F0 only with Schlick Fresnel).
    pub fn theta(&self) -> Vec<f64> {
        self.theta.clone()
    }

    /// Adds `delta` (as from [`Reflectance::theta`]) to θ.
    pub fn add_theta(&mut self, delta: &[f64]) {
        for (t, d) in self.theta.iter_mut().zip(delta) {
            *t += d;
        }
    }

    /// Chain rule: dE/dθ from the renderer's dE/d(physical parameters) (order of `FittedBrdf::PARAM_NAMES`).
    pub fn chain(&self, physical: &[f32]) -> Vec<f64> {
        self.template.chain_theta(&self.theta, physical)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// θ moves the BRDF, the template's fixed settings stay, and the checkpoint form round-trips exactly.
    #[test]
    fn theta_moves_the_brdf_and_round_trips_through_json() {
        let ggx = nlos_brdf::Ggx::new(0.3f32, 0.8, 0.3, nlos_brdf::Fresnel::Schlick { f0: 0.2 }).expect("valid");
        let mut r = Reflectance::from_brdf(AnyBrdf::Ggx(ggx));
        assert_eq!(r.theta().len(), 4);
        assert!(!r.is_scale_only() && r.model() == Model::Ggx);
        r.add_theta(&[0.0, 0.0, 1.0, 0.0]);
        let AnyBrdf::Ggx(moved) = r.brdf().expect("finite") else { unreachable!("ggx") };
        assert!(moved.alpha() > 0.3 && (moved.albedo_diffuse() - 0.3).abs() < 1e-5);
        assert!(matches!(moved.fresnel(), nlos_brdf::Fresnel::Schlick { .. }));
        let json = serde_json::to_string(&r).expect("serialise");
        assert_eq!(serde_json::from_str::<Reflectance>(&json).expect("deserialise"), r);
        let d = Reflectance::default();
        assert_eq!(d.theta().len(), 1);
        assert!(d.is_scale_only());
        assert_eq!(d, Reflectance::start(Model::Lambert, 0.3).expect("lambert"));
    }
}
