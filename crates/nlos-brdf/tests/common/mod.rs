//! Shared test helpers: the workspace's seeded PCG32, random configurations, Gauss–Legendre quadrature, and an f64
//! textbook reference of the BRDF written independently of the crate (W07 eqs. 20, 33, 34; H14 eq. 99).
#![allow(dead_code)]

use glam::DVec3;
use std::f64::consts::PI;

/// The workspace's PCG32 (`nlos_transient::rng`), with the draws these tests use.
#[derive(Debug, Clone)]
pub struct Pcg32(nlos_transient::rng::Pcg32);

impl Pcg32 {
    pub fn new(seed: u64, stream: u64) -> Self {
        Self(nlos_transient::rng::Pcg32::new(seed, stream))
    }
    pub fn next_u32(&mut self) -> u32 {
        self.0.next_u32()
    }
    /// Uniform in [0, 1) with 53 random bits.
    pub fn f64(&mut self) -> f64 {
        let hi = u64::from(self.next_u32()) << 21;
        let lo = u64::from(self.next_u32()) >> 11;
        ((hi | lo) as f64) * (1.0 / (1u64 << 53) as f64)
    }
    /// Uniform in [0, 1) with 24 random bits.
    pub fn f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }
    /// Uniform direction on the sphere.
    pub fn unit(&mut self) -> DVec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, 2.0 * PI);
        let r = (1.0 - z * z).sqrt();
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// Orthonormal tangents of a unit vector (independent of the crate's `Frame`).
pub fn tangents(n: DVec3) -> (DVec3, DVec3) {
    let a = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = n.cross(a).normalize();
    (t, n.cross(t))
}

/// Unit direction with cosine `mu` to the unit `n` and azimuth `phi`.
pub fn dir_with_cos(n: DVec3, mu: f64, phi: f64) -> DVec3 {
    let (t, b) = tangents(n);
    let s = (1.0 - mu * mu).max(0.0).sqrt();
    (t * phi.cos() + b * phi.sin()) * s + n * mu
}

/// A random front-facing cosine: 25% grazing (log-uniform in [1e-3, 2e-2]), else uniform in [2e-2, 1].
pub fn random_mu(rng: &mut Pcg32) -> f64 {
    if rng.f64() < 0.25 { (rng.range(1e-3f64.ln(), 2e-2f64.ln())).exp() } else { rng.range(2e-2, 1.0) }
}

/// Roughness log-uniform in [1e-3, 1].
pub fn random_alpha(rng: &mut Pcg32) -> f64 {
    rng.range(1e-3f64.ln(), 0.0).exp()
}

/// A random front-facing configuration `(l, s, n)` with **non-unit** lengths in [0.3, 3]. A third of them are
/// near-specular (half vector within a few α of the normal), where D is largest.
pub fn random_config(rng: &mut Pcg32, alpha: f64) -> (DVec3, DVec3, DVec3) {
    let n = rng.unit();
    let l = dir_with_cos(n, random_mu(rng), rng.range(0.0, 2.0 * PI));
    let s = if rng.f64() < 1.0 / 3.0 {
        // Reflect l about a normal tilted by ~α from n, keep it if front-facing.
        let (t, b) = tangents(n);
        let tilt = alpha * rng.range(0.0, 3.0);
        let phi = rng.range(0.0, 2.0 * PI);
        let m = (n + (t * phi.cos() + b * phi.sin()) * tilt).normalize();
        let r = m * (2.0 * l.dot(m)) - l;
        if r.dot(n) > 1e-3 { r } else { dir_with_cos(n, random_mu(rng), rng.range(0.0, 2.0 * PI)) }
    } else {
        dir_with_cos(n, random_mu(rng), rng.range(0.0, 2.0 * PI))
    };
    (l * rng.range(0.3, 3.0), s * rng.range(0.3, 3.0), n * rng.range(0.3, 3.0))
}

/// Textbook f64 reference of the GGX BRDF, written from the papers and independent of the crate:
/// W07 eq. 20 with D from eq. 33 (tan form), G1 from eq. 34, G2 from H14 eq. 99 if `height_correlated`,
/// Schlick F if `f0` is `Some`. Inputs are normalised first.
#[allow(clippy::too_many_arguments)]
pub fn reference_ggx(
    l: DVec3,
    s: DVec3,
    n: DVec3,
    rho_d: f64,
    rho_s: f64,
    alpha: f64,
    f0: Option<f64>,
    height_correlated: bool,
) -> f64 {
    let (l, s, n) = (l.normalize(), s.normalize(), n.normalize());
    let (mu_l, mu_s) = (n.dot(l), n.dot(s));
    if mu_l <= 0.0 || mu_s <= 0.0 {
        return 0.0;
    }
    let h = (l + s).normalize();
    let ch = n.dot(h);
    let tan2_h = n.cross(h).length_squared() / (ch * ch);
    let a2 = alpha * alpha;
    let d = a2 / (PI * ch.powi(4) * (a2 + tan2_h).powi(2));
    let tan2 = |mu: f64| (1.0 - mu * mu) / (mu * mu);
    let lambda = |mu: f64| (-1.0 + (1.0 + a2 * tan2(mu)).sqrt()) / 2.0;
    let g1 = |mu: f64| 2.0 / (1.0 + (1.0 + a2 * tan2(mu)).sqrt());
    let g = if height_correlated { 1.0 / (1.0 + lambda(mu_l) + lambda(mu_s)) } else { g1(mu_l) * g1(mu_s) };
    let f = f0.map_or(1.0, |f0| f0 + (1.0 - f0) * (1.0 - l.dot(h)).powi(5));
    rho_d / PI + rho_s * d * g * f / (4.0 * mu_l * mu_s)
}

/// Gauss–Legendre nodes and weights on [-1, 1] (Newton on P_n).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out
}

/// Composite Gauss–Legendre nodes/weights on [a, b]: `panels` panels of `order` points.
pub fn composite_gl(a: f64, b: f64, panels: usize, order: usize) -> Vec<(f64, f64)> {
    let gl = gauss_legendre(order);
    let w = (b - a) / panels as f64;
    let mut out = Vec::with_capacity(panels * order);
    for p in 0..panels {
        let lo = a + w * p as f64;
        for &(x, wt) in &gl {
            out.push((lo + 0.5 * w * (x + 1.0), 0.5 * w * wt));
        }
    }
    out
}
