//! Importance sampling: cosine-weighted hemisphere sampling for the diffuse lobe, visible-normal (VNDF)
//! sampling of GGX (Heitz 2018) for the specular lobe, each with its solid-angle pdf, and the local frame.
//!
//! Local-frame functions take and return directions in a frame whose z axis is the surface normal; the
//! [`Brdf::sample`](crate::Brdf::sample) implementations do the world↔local change with [`Frame`].
//!
//! References: Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4) 2018 ("H18");
//! Walter et al. 2007 ("W07"); Shirley & Chiu, "A Low Distortion Map Between Disk and Square", JGT 1997;
//! Duff et al., "Building an Orthonormal Basis, Revisited", JCGT 6(1) 2017.

use crate::microfacet::{d, g1};
use crate::real::{Real, V3, Vector3};

/// An orthonormal frame `(t, b, n)` around a unit normal `n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame<T: Real> {
    /// First tangent.
    pub t: V3<T>,
    /// Second tangent (`n × t`).
    pub b: V3<T>,
    /// The normal (z axis of the local frame).
    pub n: V3<T>,
}

impl<T: Real> Frame<T> {
    /// Branchless-in-spirit frame from a **unit** normal (Duff et al. 2017, Listing 3); continuous except
    /// across `n.z = 0`, exact for all unit `n` including `±z`.
    #[inline(always)]
    pub fn from_normal(n: V3<T>) -> Self {
        let sign = if n.z() >= T::ZERO { T::ONE } else { -T::ONE };
        let a = -T::ONE / (sign + n.z());
        let b = n.x() * n.y() * a;
        let t = V3::<T>::new(T::ONE + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
        let bt = V3::<T>::new(b, sign + n.y() * n.y() * a, -n.y());
        Self { t, b: bt, n }
    }

    /// World → local (`z` along `n`).
    #[inline(always)]
    pub fn to_local(&self, v: V3<T>) -> V3<T> {
        V3::<T>::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    /// Local → world.
    #[inline(always)]
    pub fn to_world(&self, v: V3<T>) -> V3<T> {
        self.t * v.x() + self.b * v.y() + self.n * v.z()
    }
}

/// Shirley–Chiu concentric map of `[0,1)²` onto the unit disk.
#[inline(always)]
fn concentric_disk<T: Real>(u1: T, u2: T) -> (T, T) {
    let x = T::TWO * u1 - T::ONE;
    let y = T::TWO * u2 - T::ONE;
    if x == T::ZERO && y == T::ZERO {
        return (T::ZERO, T::ZERO);
    }
    let quarter_pi = T::PI * T::from_f64(0.25);
    let (r, phi) =
        if x.abs() > y.abs() { (x, quarter_pi * (y / x)) } else { (y, T::PI * T::HALF - quarter_pi * (x / y)) };
    let (sp, cp) = phi.sin_cos();
    (r * cp, r * sp)
}

/// Cosine-weighted direction on the local upper hemisphere (Malley's method: Shirley–Chiu disk point lifted
/// to the hemisphere). Its density is [`pdf_cosine_hemisphere`].
#[inline]
pub fn sample_cosine_hemisphere<T: Real>(u1: T, u2: T) -> V3<T> {
    let (x, y) = concentric_disk(u1, u2);
    // 1 − x² − y² can round below 0 on the disk's rim.
    let z = (T::ONE - x * x - y * y).max(T::ZERO).sqrt();
    V3::<T>::new(x, y, z)
}

/// Solid-angle density of [`sample_cosine_hemisphere`]: `max(cos θ, 0)/π`.
#[inline(always)]
pub fn pdf_cosine_hemisphere<T: Real>(cos_theta: T) -> T {
    cos_theta.max(T::ZERO) * T::FRAC_1_PI
}

/// Samples a microfacet normal from the GGX distribution of normals visible from the local direction
/// `wi` (`wi.z > 0`, unit), H18 Listing 1 (isotropic α). Its density is [`pdf_vndf`].
#[inline]
pub fn sample_vndf<T: Real>(wi: V3<T>, alpha: T, u1: T, u2: T) -> V3<T> {
    // H18 §3.2: stretch the view direction to the hemisphere configuration.
    let vh = normalize::<T>(V3::<T>::new(alpha * wi.x(), alpha * wi.y(), wi.z()));
    // H18 §4.1: orthonormal basis, special case when vh is the pole.
    let lensq = vh.x() * vh.x() + vh.y() * vh.y();
    let t1 = if lensq > T::ZERO {
        V3::<T>::new(-vh.y(), vh.x(), T::ZERO) * (T::ONE / lensq.sqrt())
    } else {
        V3::<T>::new(T::ONE, T::ZERO, T::ZERO)
    };
    let t2 = vh.cross(t1);
    // H18 §4.2: parameterisation of the projected area.
    let r = u1.sqrt();
    let (sp, cp) = (T::TWO * T::PI * u2).sin_cos();
    let p1 = r * cp;
    let p2 = r * sp;
    let s = T::HALF * (T::ONE + vh.z());
    // 1 − p1² ≥ 0 up to rounding.
    let p2 = (T::ONE - s) * (T::ONE - p1 * p1).max(T::ZERO).sqrt() + s * p2;
    // H18 §4.3: reprojection onto the hemisphere.
    let nh = t1 * p1 + t2 * p2 + vh * (T::ONE - p1 * p1 - p2 * p2).max(T::ZERO).sqrt();
    // H18 §3.4: back to the ellipsoid configuration; z clamped so the normal never points below.
    normalize::<T>(V3::<T>::new(alpha * nh.x(), alpha * nh.y(), nh.z().max(T::ZERO)))
}

/// Density of [`sample_vndf`] over microfacet normals `m` (solid angle), H18 eq. 3:
/// `D_wi(m) = G1(wi) max(0, wi·m) D(m) / wi.z`; 0 when `wi.z ≤ 0` or `m.z ≤ 0`.
#[inline]
pub fn pdf_vndf<T: Real>(wi: V3<T>, m: V3<T>, alpha: T) -> T {
    if !(wi.z() > T::ZERO && m.z() > T::ZERO) {
        return T::ZERO;
    }
    let sin2 = m.x() * m.x() + m.y() * m.y();
    g1(wi.z(), alpha) * wi.dot(m).max(T::ZERO) * d(m.z(), sin2, alpha) / wi.z()
}

/// Mirror reflection of `wi` about the microfacet normal `m` (W07 eq. 39): `2 (wi·m) m − wi`.
#[inline(always)]
pub fn reflect<T: Real>(wi: V3<T>, m: V3<T>) -> V3<T> {
    m * (T::TWO * wi.dot(m)) - wi
}

/// Samples an outgoing local direction by reflecting `wi` about a VNDF-sampled normal (H18 §2). The result
/// can lie below the surface (`z ≤ 0`); its density over the whole sphere is [`pdf_vndf_reflection`].
#[inline]
pub fn sample_vndf_reflection<T: Real>(wi: V3<T>, alpha: T, u1: T, u2: T) -> V3<T> {
    reflect::<T>(wi, sample_vndf(wi, alpha, u1, u2))
}

/// Solid-angle density of [`sample_vndf_reflection`] at `wo` (both local, unit): `D_wi(h) / (4 wi·h)`
/// with `h = (wi + wo)/|wi + wo|` (H18 eq. 17, the reflection Jacobian of W07 eq. 14). Integrates to 1 over
/// the sphere; 0 when `wi.z ≤ 0`, `h.z ≤ 0` or `wi = −wo`.
#[inline]
pub fn pdf_vndf_reflection<T: Real>(wi: V3<T>, wo: V3<T>, alpha: T) -> T {
    let hs = wi + wo;
    let len2 = hs.length_squared();
    // wi = −wo has no half vector (and zero density).
    if !(len2 > T::ZERO) {
        return T::ZERO;
    }
    let h = hs * (T::ONE / len2.sqrt());
    let wi_h = wi.dot(h);
    if !(wi_h > T::ZERO) {
        return T::ZERO;
    }
    pdf_vndf(wi, h, alpha) / (T::from_f64(4.0) * wi_h)
}

#[inline(always)]
fn normalize<T: Real>(v: V3<T>) -> V3<T> {
    v * (T::ONE / v.length_squared().sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn frame_is_orthonormal() {
        for n in [DVec3::Z, -DVec3::Z, DVec3::X, DVec3::new(0.3, -0.5, 0.2).normalize()] {
            let f = Frame::<f64>::from_normal(n);
            assert!((f.t.length() - 1.0).abs() < 1e-12 && (f.b.length() - 1.0).abs() < 1e-12);
            assert!(f.t.dot(f.b).abs() < 1e-12 && f.t.dot(n).abs() < 1e-12 && f.b.dot(n).abs() < 1e-12);
            assert!((f.t.cross(f.b) - n).length() < 1e-12);
            let v = DVec3::new(0.1, 0.7, -0.2);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-12);
        }
    }

    #[test]
    fn vndf_normals_are_visible_and_unit() {
        let wi = DVec3::new(0.6, 0.0, 0.8);
        for i in 0..64 {
            for j in 0..64 {
                let m = sample_vndf(wi, 0.3, (i as f64 + 0.5) / 64.0, (j as f64 + 0.5) / 64.0);
                assert!((m.length() - 1.0).abs() < 1e-12);
                assert!(m.z >= 0.0 && wi.dot(m) >= -1e-12);
            }
        }
    }
}
