//! The scalar and 3-vector abstraction that lets every formula of this crate run in `f32` (the renderer) and in
//! `f64` (the tests' finite-difference reference) from one source.
//!
//! [`Real`] is sealed and implemented for `f32` (vectors: [`glam::Vec3`]) and `f64` (vectors: [`glam::DVec3`]).
//! Everything is `#[inline]` and monomorphised, so the `f32` instantiation compiles to the same code as
//! hand-written `f32` arithmetic.

use std::fmt::{Debug, Display};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// A floating-point scalar: `f32` or `f64`.
///
/// The associated [`Real::V3`] is the matching glam vector, so `Ggx<f32>` takes [`glam::Vec3`] and
/// `Ggx<f64>` takes [`glam::DVec3`].
pub trait Real:
    sealed::Sealed
    + Copy
    + Default
    + Debug
    + Display
    + PartialEq
    + PartialOrd
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + serde::Serialize
    + for<'de> serde::Deserialize<'de>
{
    /// The 3-vector of this precision.
    type V3: Vector3<Self>;
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// 2.
    const TWO: Self;
    /// 1/2.
    const HALF: Self;
    /// π.
    const PI: Self;
    /// 1/π.
    const FRAC_1_PI: Self;
    /// Converts an `f64` constant (rounding to nearest for `f32`).
    fn from_f64(x: f64) -> Self;
    /// Widens to `f64` (exact).
    fn to_f64(self) -> f64;
    /// Square root.
    fn sqrt(self) -> Self;
    /// e^x.
    fn exp(self) -> Self;
    /// Natural logarithm.
    fn ln(self) -> Self;
    /// ln(1 + x), accurate for small x.
    fn ln_1p(self) -> Self;
    /// e^x − 1, accurate for small x.
    fn exp_m1(self) -> Self;
    /// |x|.
    fn abs(self) -> Self;
    /// The larger of two (NaN-ignoring, as `f32::max`).
    fn max(self, other: Self) -> Self;
    /// The smaller of two (NaN-ignoring, as `f32::min`).
    fn min(self, other: Self) -> Self;
    /// (sin x, cos x).
    fn sin_cos(self) -> (Self, Self);
    /// Whether the value is neither infinite nor NaN.
    fn is_finite(self) -> bool;
}

/// A 3-vector over [`Real`] `T` (implemented for [`glam::Vec3`] and [`glam::DVec3`]).
pub trait Vector3<T>:
    Copy
    + Debug
    + Default
    + PartialEq
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<T, Output = Self>
    + Neg<Output = Self>
{
    /// The zero vector.
    const ZERO: Self;
    /// Builds a vector from its components.
    fn new(x: T, y: T, z: T) -> Self;
    /// x component.
    fn x(self) -> T;
    /// y component.
    fn y(self) -> T;
    /// z component.
    fn z(self) -> T;
    /// Dot product.
    fn dot(self, rhs: Self) -> T;
    /// Cross product.
    fn cross(self, rhs: Self) -> Self;
    /// Squared Euclidean length.
    fn length_squared(self) -> T;
}

macro_rules! impl_real {
    ($t:ident, $v:ty) => {
        impl Real for $t {
            type V3 = $v;
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const TWO: Self = 2.0;
            const HALF: Self = 0.5;
            const PI: Self = std::$t::consts::PI;
            const FRAC_1_PI: Self = std::$t::consts::FRAC_1_PI;
            #[inline(always)]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                $t::sqrt(self)
            }
            #[inline(always)]
            fn exp(self) -> Self {
                $t::exp(self)
            }
            #[inline(always)]
            fn ln(self) -> Self {
                $t::ln(self)
            }
            #[inline(always)]
            fn ln_1p(self) -> Self {
                $t::ln_1p(self)
            }
            #[inline(always)]
            fn exp_m1(self) -> Self {
                $t::exp_m1(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                $t::abs(self)
            }
            #[inline(always)]
            fn max(self, other: Self) -> Self {
                $t::max(self, other)
            }
            #[inline(always)]
            fn min(self, other: Self) -> Self {
                $t::min(self, other)
            }
            #[inline(always)]
            fn sin_cos(self) -> (Self, Self) {
                $t::sin_cos(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                $t::is_finite(self)
            }
        }

        impl Vector3<$t> for $v {
            const ZERO: Self = <$v>::ZERO;
            #[inline(always)]
            fn new(x: $t, y: $t, z: $t) -> Self {
                <$v>::new(x, y, z)
            }
            #[inline(always)]
            fn x(self) -> $t {
                self.x
            }
            #[inline(always)]
            fn y(self) -> $t {
                self.y
            }
            #[inline(always)]
            fn z(self) -> $t {
                self.z
            }
            #[inline(always)]
            fn dot(self, rhs: Self) -> $t {
                <$v>::dot(self, rhs)
            }
            #[inline(always)]
            fn cross(self, rhs: Self) -> Self {
                <$v>::cross(self, rhs)
            }
            #[inline(always)]
            fn length_squared(self) -> $t {
                <$v>::length_squared(self)
            }
        }
    };
}

impl_real!(f32, glam::Vec3);
impl_real!(f64, glam::DVec3);

/// Shorthand for the vector type of scalar `T`.
pub type V3<T> = <T as Real>::V3;

/// `v / |v|` and `1 / |v|`. A zero vector gives non-finite components, which every caller's
/// front-facing test (`x > 0`, false for NaN) turns into "back-facing → 0".
#[inline(always)]
pub(crate) fn normalize_with_inv_len<T: Real>(v: V3<T>) -> (V3<T>, T) {
    let inv = T::ONE / v.length_squared().sqrt();
    (v * inv, inv)
}

/// Gradient of `g(v/|v|)` with respect to `v`, given `u = v/|v|`, `inv_len = 1/|v|` and `grad_u = ∇g(u)`:
/// `(I − u uᵀ) grad_u / |v|` (the Jacobian of normalisation, transposed).
#[inline(always)]
pub(crate) fn project_through_normalize<T: Real>(u: V3<T>, inv_len: T, grad_u: V3<T>) -> V3<T> {
    (grad_u - u * u.dot(grad_u)) * inv_len
}
