//! Multiple importance sampling of a GGX lobe for the stratified rule ([`Renderer::set_lobe_sampling`]).

use glam::Vec3;

/// The GGX lobe sampler of [`Renderer::set_lobe_sampling`] for one (triangle, confocal spot): microfacet
/// normals `m ~ D(m)(m·n)` about the oriented unit normal `n`, mapped to the plane through the ray from `l`
/// along `−m`.
#[derive(Debug, Clone, Copy)]
pub(in crate::render) struct Lobe {
    pub(in crate::render) alpha2: f32,
    pub(in crate::render) n: Vec3,
    /// Tangent frame of n.
    pub(in crate::render) t1: Vec3,
    pub(in crate::render) t2: Vec3,
    pub(in crate::render) l: Vec3,
}

impl Lobe {
    pub(in crate::render) fn new(alpha: f32, n_raw: Vec3, l: Vec3) -> Self {
        let a = alpha.max(1e-3);
        let n = n_raw.normalize_or_zero();
        let (t1, t2) = n.any_orthonormal_pair();
        Self { alpha2: a * a, n, t1, t2, l }
    }

    /// GGX `D(m)` at `cos θ_m = c`: `α²/(π (c²(α² − 1) + 1)²)`.
    #[inline(always)]
    pub(in crate::render) fn d(&self, c: f32) -> f32 {
        let k = c * c * (self.alpha2 - 1.0) + 1.0;
        self.alpha2 / (std::f32::consts::PI * k * k)
    }

    /// The lobe's density at x per unit area of the plane: `D(m)(n·m)²/|x − l|²`, `m = (l − x)/|l − x|`
    /// (0 behind the plane).
    #[inline(always)]
    pub(in crate::render) fn pdf(&self, x: Vec3) -> f32 {
        let d = self.l - x;
        let r2 = d.length_squared();
        let c = self.n.dot(d) / r2.sqrt();
        if !(c > 0.0 && r2 > 0.0) {
            return 0.0;
        }
        self.d(c) * c * c / r2
    }

    /// The barycentric coordinates (u along e1, v along e2) of the lobe sample for uniforms `(r1, r2)`, or
    /// None when the ray misses the plane or the point is outside the triangle.
    #[inline(always)]
    pub(in crate::render) fn sample(&self, r1: f32, r2: f32, v0: Vec3, e1: Vec3, e2: Vec3) -> Option<(f32, f32)> {
        // tan²θ = α² r1/(1 − r1) samples D(m) cos θ_m.
        let tan2 = self.alpha2 * r1 / (1.0 - r1);
        let cos = 1.0 / (1.0 + tan2).sqrt();
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * r2;
        let m = sin * phi.cos() * self.t1 + sin * phi.sin() * self.t2 + cos * self.n;
        // x = l − s m on the plane n·(x − v0) = 0: s = n·(l − v0)/(n·m) > 0 for a front-facing pair.
        let s = self.n.dot(self.l - v0) / self.n.dot(m);
        if !(s > 0.0 && s.is_finite()) {
            return None;
        }
        let x = self.l - s * m - v0;
        let nn = e1.cross(e2);
        let inv = 1.0 / nn.length_squared();
        let u = x.cross(e2).dot(nn) * inv;
        let v = e1.cross(x).dot(nn) * inv;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then_some((u, v))
    }
}
