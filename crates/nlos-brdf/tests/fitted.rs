//! `FittedBrdf` for every model, through `AnyBrdf`: the parameter vector and θ round-trip, θ's chain rule
//! matches finite differences of its maps, and the settings' JSON form names the model.

use nlos_brdf::{AnyBrdf, Fresnel, Ggx, Model};

/// One BRDF of each model with parameters away from their bounds (GGX with Schlick Fresnel, so F0 is fitted).
fn every_model() -> Vec<AnyBrdf> {
    let mut all: Vec<AnyBrdf> =
        Model::ALL.into_iter().map(|m| AnyBrdf::new(m, 0.3, 0.8, 0.3).expect("valid")).collect();
    all.push(AnyBrdf::Ggx(Ggx::new(0.3, 0.8, 0.3, Fresnel::Schlick { f0: 0.2 }).expect("valid")));
    all
}

#[test]
fn every_model_round_trips_its_parameters_theta_and_json() {
    for b in every_model() {
        let model = b.model();
        assert_eq!(b.param_names().len(), b.params().len(), "{model}");
        assert_eq!(b.with_params(&b.params()).expect("own parameters"), b, "{model}");
        let back = b.with_theta(&b.theta()).expect("finite θ");
        for (x, y) in back.params().iter().zip(b.params()) {
            assert!((x - y).abs() < 1e-5 * (1.0 + y.abs()), "{model}: {x} vs {y}");
        }
        let json = serde_json::to_value(b).expect("serialise");
        assert!(json.get(model.name()).is_some(), "{model}: {json}");
        assert_eq!(serde_json::from_value::<AnyBrdf>(json).expect("deserialise"), b);
        assert!(!b.describe().is_empty());
        assert!(b.with_theta(&[f64::NAN; 4]).is_err(), "{model}: a NaN θ is refused");
        assert!(b.with_params(&[]).is_err(), "{model}: missing parameters are refused");
    }
    let scale_only: Vec<bool> = every_model().iter().map(AnyBrdf::is_scale_only).collect();
    assert_eq!(scale_only, [true, false, true, false]);
    assert_eq!(AnyBrdf::unit(Model::Retroreflective, 0.3).expect("unit").describe(), "retroreflective, return 1.0000");
}

/// `chain_theta` is `∂(physical)/∂θ` applied to the gradient: checked one physical parameter at a time against
/// central differences of the θ → parameters map.
#[test]
fn the_chain_rule_matches_finite_differences_of_the_maps() {
    for b in every_model() {
        let theta = b.theta();
        let n = b.param_names().len();
        for (k, _) in theta.iter().enumerate() {
            for p in 0..n {
                let mut unit = vec![0.0f32; n];
                unit[p] = 1.0;
                let analytic = b.chain_theta(&theta, &unit)[k];
                let h = 1e-3;
                let value = |d: f64| {
                    let mut t = theta.clone();
                    t[k] += d;
                    f64::from(b.with_theta(&t).expect("finite").params()[p])
                };
                let fd = (value(h) - value(-h)) / (2.0 * h);
                assert!(
                    (fd - analytic).abs() < 2e-3 * (1.0 + analytic.abs()),
                    "{}: θ{k} → {}: fd {fd} vs {analytic}",
                    b.model(),
                    b.param_names()[p]
                );
            }
        }
    }
}
