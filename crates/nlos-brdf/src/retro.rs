//! A retroreflector: a surface that sends the light it receives back toward the spot that lit it.
//!
//! ## The model
//! A diffuse surface element spreads what it returns over the hemisphere, so the light reaching the sensor
//! spot falls as `1/|x − s|²` on the way back, and a confocal measurement (`l = s`, distance r) falls as
//! `1/r⁴`. A retroreflector (corner cubes, glass beads, retroreflective tape or paint) sends its return
//! into a narrow cone around the incoming direction, aimed at the spot it came from; the spot collects all
//! of it whatever the distance, and the confocal measurement falls as `1/r²`. That is the retroreflective
//! image formation model of the light-cone transform (O'Toole, Lindell & Wetzstein, "Confocal
//! non-line-of-sight imaging based on the light-cone transform", Nature 2018, eq. 1 with the `1/r²` falloff
//! of their retroreflective case; the volumetric starts weight the data by `t²` for it, [`crate::Model::distance_power`]).
//!
//! In the renderer's form of the measurement, `f_s · ⟨−ω_l,n_l⟩⟨ω_l,n⟩/|x−l|² · ⟨−ω_s,n_s⟩⟨ω_s,n⟩/|x−s|²`,
//! the retroreflector is the reflectance
//! ```text
//! f_r(ω_l, ω_s, n) = ρ/π · |ω_l| |ω_s| / d₀² · g(ω̂_l · ω̂_s),     g(c) = exp(−(1 − c)/σ²),   d₀ = 1 m
//! ```
//! on the front side (`n·ω_l > 0`, `n·ω_s > 0`), 0 behind, where `ω_l = l − x` and `ω_s = s − x` are the
//! **unnormalised vectors in metres** (this model, unlike [`crate::Lambertian`] and [`crate::Ggx`], reads
//! their lengths; the renderer passes exactly these vectors). Hence:
//! - **Falloff.** Confocal: `f_r /r⁴ = ρ/(π d₀²) / r²`, the `1/r²` of the LCT's retroreflective model. ρ is
//!   the surface's return relative to a Lambertian surface of albedo ρ at `d₀ = 1 m` (a confocal
//!   retroreflector of ρ at 0.5 m returns 4× the Lambertian one of the same ρ). The product `|ω_l||ω_s|`
//!   rather than `|ω_s|²` keeps the model reciprocal (`f_r(ω_l, ω_s) = f_r(ω_s, ω_l)`).
//! - **Angular behaviour.** The cosines of the measurement stay: `⟨ω_l,n⟩` is the element's projected area
//!   toward the light (what it intercepts), `⟨ω_s,n⟩` the falling efficiency of the retroreflector at oblique
//!   entrance (real sheeting loses about as much), and the wall cosines are the wall's. The LCT drops all
//!   cosines (its model is for small fronto-parallel patches); here they follow the measurement equation.
//! - **Non-confocal pairs.** `g` is a Gaussian in the observation angle θ between `ω_l` and `ω_s`
//!   (`1 − cos θ ≈ θ²/2`, so `g ≈ exp(−θ²/(2σ²))`) of width σ ([`Retroreflective::lobe_width`], 1° by
//!   default, the order of retroreflective sheeting's observation angles): a pair of spots 2 cm apart seen
//!   from 0.5 m (θ ≈ 2.3°) gets about 7 % of the confocal return, 5 cm apart about nothing.
//!
//! ## Gradients
//! With `c = ω̂_l·ω̂_s`: `∂f/∂ω_l = f ω_l/|ω_l|² + f/σ² (ω̂_s − c ω̂_l)/|ω_l|` (likewise for `ω_s`),
//! `∂f/∂n = 0` (the front-side test is a step), `∂f/∂ρ = f/ρ`. Confocal (`ω_l = ω_s = ω`, `c = 1`): the lobe
//! terms cancel and the total derivative along ω is `2 ρ/(π d₀²) ω`.

use crate::Lambertian;
use crate::brdf::{Brdf, BrdfSample, ConfocalGrad, Grad};
use crate::error::{BrdfError, Result};
use crate::lambert::check_albedo;
use crate::real::{Real, V3, Vector3, normalize_with_inv_len};

/// The default lobe width σ of [`Retroreflective`]: 1° in radians.
pub const RETRO_LOBE_WIDTH: f64 = 0.017_453_292_519_943_295;

/// A retroreflective surface: `f_r = ρ/π · |ω_l||ω_s|/d₀² · exp(−(1 − ω̂_l·ω̂_s)/σ²)` with `d₀ = 1 m` (see the
/// [module docs](self) for the derivation: a confocal measurement falls as `1/r²`, not `1/r⁴`).
///
/// # Example
/// ```
/// use glam::Vec3;
/// use nlos_brdf::{Brdf, Lambertian, Retroreflective};
/// let retro = Retroreflective::new(1.0f32)?;
/// let lambert = Lambertian::new(1.0f32)?;
/// let n = Vec3::Z;
/// // Confocal at 0.5 m: the retroreflector returns (0.5 m)² of the Lambertian value, so the measurement
/// // (with its 1/r⁴) falls as 1/r² instead.
/// let w = Vec3::new(0.0, 0.0, 0.5);
/// assert!((retro.eval_confocal(w, n) - 0.25 * lambert.eval_confocal(w, n)).abs() < 1e-7);
/// // Spots 10 cm apart seen from 0.5 m lie far outside the 1° lobe.
/// assert!(retro.eval(Vec3::new(0.05, 0.0, 0.5), Vec3::new(-0.05, 0.0, 0.5), n) < 1e-20);
/// # Ok::<(), nlos_brdf::BrdfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "RetroRaw<T>", into = "RetroRaw<T>", bound = "")]
pub struct Retroreflective<T: Real = f32> {
    albedo: T,
    lobe_width: T,
    /// `1/σ²`.
    inv_w2: T,
}

/// ∂f/∂(parameters) of [`Retroreflective`] (the lobe width is a fixed property, not fitted).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RetroreflectiveGrad<T> {
    /// ∂f/∂ρ.
    pub albedo: T,
}

impl<T: Real> Retroreflective<T> {
    /// A retroreflector of return ρ with the default 1° lobe ([`RETRO_LOBE_WIDTH`]).
    ///
    /// # Errors
    /// [`BrdfError::InvalidAlbedo`] if `albedo` is negative or not finite.
    pub fn new(albedo: T) -> Result<Self> {
        Self::with_lobe_width(albedo, T::from_f64(RETRO_LOBE_WIDTH))
    }

    /// A retroreflector of return ρ whose lobe has width σ (radians) in the observation angle.
    ///
    /// # Errors
    /// [`BrdfError::InvalidAlbedo`] for a negative or non-finite ρ; [`BrdfError::InvalidLobeWidth`] for σ
    /// outside `[1e-4, 1]` rad.
    pub fn with_lobe_width(albedo: T, lobe_width: T) -> Result<Self> {
        check_albedo("albedo", albedo)?;
        let w = lobe_width.to_f64();
        if !(1e-4..=1.0).contains(&w) {
            return Err(BrdfError::InvalidLobeWidth { value: w });
        }
        Ok(Self { albedo, lobe_width, inv_w2: T::ONE / (lobe_width * lobe_width) })
    }

    /// The return ρ (relative to a Lambertian surface of albedo ρ at 1 m).
    #[inline(always)]
    pub fn albedo(&self) -> T {
        self.albedo
    }

    /// The lobe width σ in radians.
    #[inline(always)]
    pub fn lobe_width(&self) -> T {
        self.lobe_width
    }

    #[inline(always)]
    fn front(omega_l: V3<T>, omega_s: V3<T>, n: V3<T>) -> bool {
        n.dot(omega_l) > T::ZERO && n.dot(omega_s) > T::ZERO
    }

    /// `g = exp(−(1 − ω̂_l·ω̂_s)/σ²)` of unit vectors, with `1 − c = |ω̂_l − ω̂_s|²/2`: the dot product would
    /// lose `1 − c` to round-off (in f32 about 1e-7 of 1, against σ² ≈ 3e-4 for the 1° lobe).
    #[inline(always)]
    fn lobe(&self, ul: V3<T>, us: V3<T>) -> T {
        (-(ul - us).length_squared() * T::HALF * self.inv_w2).exp()
    }

    /// `(f/ρ, ∂(f/ρ)/∂ω_l, ∂(f/ρ)/∂ω_s)` on the front side.
    #[inline(always)]
    fn unit(&self, omega_l: V3<T>, omega_s: V3<T>) -> (T, V3<T>, V3<T>) {
        let (ul, inv_l) = normalize_with_inv_len::<T>(omega_l);
        let (us, inv_s) = normalize_with_inv_len::<T>(omega_s);
        let c = ul.dot(us);
        let g = self.lobe(ul, us);
        let v = T::FRAC_1_PI * g / (inv_l * inv_s);
        // ∂/∂ω_l of |ω_l| is ω̂_l; of g through c: g/σ² (ω̂_s − c ω̂_l)/|ω_l|.
        let dl = (ul + (us - ul * c) * self.inv_w2) * (v * inv_l);
        let ds = (us + (ul - us * c) * self.inv_w2) * (v * inv_s);
        (v, dl, ds)
    }
}

impl<T: Real> Brdf for Retroreflective<T> {
    type Scalar = T;
    type ParamGrad = RetroreflectiveGrad<T>;

    #[inline]
    fn eval(&self, omega_l: V3<T>, omega_s: V3<T>, n: V3<T>) -> T {
        if !Self::front(omega_l, omega_s, n) {
            return T::ZERO;
        }
        let (ul, inv_l) = normalize_with_inv_len::<T>(omega_l);
        let (us, inv_s) = normalize_with_inv_len::<T>(omega_s);
        let g = self.lobe(ul, us);
        self.albedo * T::FRAC_1_PI * g / (inv_l * inv_s)
    }

    #[inline]
    fn eval_grad(&self, omega_l: V3<T>, omega_s: V3<T>, n: V3<T>) -> Grad<T, RetroreflectiveGrad<T>> {
        if !Self::front(omega_l, omega_s, n) {
            return Grad::zero();
        }
        let (v, dl, ds) = self.unit(omega_l, omega_s);
        Grad {
            value: self.albedo * v,
            d_params: RetroreflectiveGrad { albedo: v },
            d_omega_l: dl * self.albedo,
            d_omega_s: ds * self.albedo,
            d_n: V3::<T>::ZERO,
        }
    }

    #[inline]
    fn eval_confocal(&self, omega: V3<T>, n: V3<T>) -> T {
        if !(n.dot(omega) > T::ZERO) {
            return T::ZERO;
        }
        self.albedo * T::FRAC_1_PI * omega.length_squared()
    }

    #[inline]
    fn eval_grad_confocal(&self, omega: V3<T>, n: V3<T>) -> ConfocalGrad<T, RetroreflectiveGrad<T>> {
        if !(n.dot(omega) > T::ZERO) {
            return ConfocalGrad::zero();
        }
        let v = T::FRAC_1_PI * omega.length_squared();
        ConfocalGrad {
            value: self.albedo * v,
            d_params: RetroreflectiveGrad { albedo: v },
            d_omega: omega * (T::TWO * T::FRAC_1_PI * self.albedo),
            d_n: V3::<T>::ZERO,
        }
    }

    /// Cosine-weighted hemisphere sampling (as [`Lambertian`]): the lobe points back at the spot that lit
    /// the surface, which a renderer reaches by sampling the surface's area, not directions.
    #[inline]
    fn sample(&self, omega_i: V3<T>, n: V3<T>, u: [T; 3]) -> Option<BrdfSample<T>> {
        Lambertian::<T>::new(T::ONE).ok()?.sample(omega_i, n, u)
    }

    #[inline]
    fn pdf(&self, omega_i: V3<T>, omega_o: V3<T>, n: V3<T>) -> T {
        Lambertian::<T>::new(T::ONE).map_or(T::ZERO, |l| l.pdf(omega_i, omega_o, n))
    }
}

/// Serialised form of [`Retroreflective`], validated on deserialisation.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(bound = "")]
struct RetroRaw<T: Real> {
    albedo: T,
    lobe_width: T,
}

impl<T: Real> TryFrom<RetroRaw<T>> for Retroreflective<T> {
    type Error = BrdfError;
    fn try_from(raw: RetroRaw<T>) -> Result<Self> {
        Self::with_lobe_width(raw.albedo, raw.lobe_width)
    }
}

impl<T: Real> From<Retroreflective<T>> for RetroRaw<T> {
    fn from(r: Retroreflective<T>) -> Self {
        Self { albedo: r.albedo, lobe_width: r.lobe_width }
    }
}
