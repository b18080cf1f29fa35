// The splat rule (crate docs, "The optimiser's rule"; `splat.rs`) on the GPU: the forward pass and the adjoint
// pass of the CPU renderer's (`render/cpu`) `forward_pair_splat` / `adjoint_tile_splat`, term for term, for a confocal or general scan
// and the Lambertian or retroreflective BRDF, with cached (or no) visibility.
//
// Determinism without float atomics:
// - forward: one workgroup per (measurement, range of bins); its histogram lives in workgroup memory as 64-bit
//   fixed-point integers (two u32 words, carried by hand), so the order in which threads add does not change a
//   bit. The scale is a power of two from the largest value of any (face, sub-triangle) of the measurement
//   (a first sweep, max by integer atomics on the float bits, also order-free), so no bin can overflow.
// - adjoint: one thread per (triangle, range of measurements) sums its own terms in a fixed order; a second
//   kernel adds the ranges in order.
//
// `HB` (the histogram capacity of a workgroup, in bins) is a pipeline-overridable constant the host sets from
// the device's workgroup memory and the capture's bins.

override HB: u32 = 1024u;
const WG: u32 = 256u;
const PI_INV: f32 = 0.31830988618379067;

struct Params {
    nt: u32,          // triangles (storage slots)
    nm: u32,          // measurements
    bins: u32,        // bins per measurement
    confocal: u32,    // 1 when l = s for every measurement
    two_sided: u32,
    brdf: u32,        // 0 Lambertian, 1 retroreflective
    has_vis: u32,     // 1 when `vis` holds the cached visibility
    chunk: u32,       // adjoint: measurements per thread
    albedo: f32,
    inv_w2: f32,      // retroreflective: 1/σ²
    t0: f32,          // the tent axis: node u = (τ − t0)·inv_dt − ½
    inv_dt: f32,
    power: f32,       // RenderBrdf::DISTANCE_POWER
    max_contrib: f32, // an upper bound on the (face, sub-triangle) pairs of one measurement
    pad0: f32,
    pad1: f32,
}

@group(0) @binding(0) var<uniform> P: Params;
// Per slot: [v0, level], [e1, inv_2n], [e2, inv_n2], [N, weight] (weight = face weight, 0 for a degenerate face).
@group(0) @binding(1) var<storage, read> tris: array<vec4<f32>>;
// Per measurement: l, n_l, s, n_s.
@group(0) @binding(2) var<storage, read> wall: array<vec4<f32>>;
// Cached visibility, one byte per (measurement, slot), four to a word.
@group(0) @binding(3) var<storage, read> vis: array<u32>;
// Forward: the transient (out). Adjoint: dE/dI (in).
@group(0) @binding(4) var<storage, read_write> rows: array<f32>;
// Adjoint: 16 partial sums per (range, slot): Σ(1−u−v)dE/dx, Σu dE/dx, Σv dE/dx, sign·ΣdE/dN, dE/d(params).
@group(0) @binding(5) var<storage, read_write> partial: array<f32>;
// Adjoint: the partial sums added over the ranges, 16 per slot.
@group(0) @binding(6) var<storage, read_write> reduced: array<f32>;

struct Frame { l: vec3<f32>, n_l: vec3<f32>, s: vec3<f32>, n_s: vec3<f32> }

fn frame(m: u32) -> Frame {
    return Frame(wall[4u * m].xyz, wall[4u * m + 1u].xyz, wall[4u * m + 2u].xyz, wall[4u * m + 3u].xyz);
}

// Orientation sign × cached visibility × face weight of (slot t, measurement m); 0 when the pair is skipped.
fn pair_factor(t: u32, m: u32, fr: Frame) -> vec2<f32> {
    let n = tris[4u * t + 3u];
    if (n.w == 0.0) { return vec2<f32>(0.0); }
    let v0 = tris[4u * t].xyz;
    let dl = dot(n.xyz, fr.l - v0);
    let ds = dot(n.xyz, fr.s - v0);
    var sign = 0.0;
    if (dl > 0.0 && ds > 0.0) { sign = 1.0; } else if (P.two_sided != 0u && dl < 0.0 && ds < 0.0) { sign = -1.0; }
    if (sign == 0.0) { return vec2<f32>(0.0); }
    var v = n.w;
    if (P.has_vis != 0u) {
        let i = m * P.nt + t;
        let byte = (vis[i >> 2u] >> (8u * (i & 3u))) & 255u;
        v = v * f32(byte) * (1.0 / 255.0);
    }
    return vec2<f32>(sign, v);
}

// Sub-triangle `j` of level n (the order of `subtriangles`): corners and centroid in barycentric (u, v).
struct Sub { c0: vec2<f32>, c1: vec2<f32>, c2: vec2<f32>, cen: vec2<f32> }

fn sub_triangle(n: u32, idx: u32) -> Sub {
    // Row i holds 2(n − i) − 1 sub-triangles (upright ones at even k, flipped ones between them), so i(2n − i)
    // come before row i: i = ⌊n − √(n² − idx)⌋, corrected by one where the square root rounds.
    let inv = 1.0 / f32(n);
    var i = u32(max(f32(n) - sqrt(f32(n * n - idx)), 0.0));
    if (i > 0u && i * (2u * n - i) > idx) { i = i - 1u; }
    if ((i + 1u) * (2u * n - i - 1u) <= idx) { i = i + 1u; }
    let k = idx - i * (2u * n - i);
    let j = k / 2u;
    let fi = f32(i);
    let fj = f32(j);
    if ((k & 1u) == 0u) {
        return Sub(vec2<f32>(fi, fj) * inv, vec2<f32>(fi + 1.0, fj) * inv, vec2<f32>(fi, fj + 1.0) * inv,
                   vec2<f32>((fi + 1.0 / 3.0) * inv, (fj + 1.0 / 3.0) * inv));
    }
    return Sub(vec2<f32>(fi + 1.0, fj) * inv, vec2<f32>(fi + 1.0, fj + 1.0) * inv, vec2<f32>(fi, fj + 1.0) * inv,
               vec2<f32>((fi + 2.0 / 3.0) * inv, (fj + 2.0 / 3.0) * inv));
}

// The BRDF's value and gradients: value, ∂f/∂ω_l, ∂f/∂ω_s (confocal: the total along ω in dl, ds = 0), ∂f/∂ρ.
struct BrdfGrad { value: f32, dl: vec3<f32>, ds: vec3<f32>, dp: f32 }

fn brdf_grad(a: vec3<f32>, b: vec3<f32>, n: vec3<f32>) -> BrdfGrad {
    if (!(dot(n, a) > 0.0 && dot(n, b) > 0.0)) { return BrdfGrad(0.0, vec3<f32>(0.0), vec3<f32>(0.0), 0.0); }
    if (P.brdf == 0u) {
        return BrdfGrad(P.albedo * PI_INV, vec3<f32>(0.0), vec3<f32>(0.0), PI_INV);
    }
    if (P.confocal != 0u) {
        let v = PI_INV * dot(a, a);
        return BrdfGrad(P.albedo * v, a * (2.0 * PI_INV * P.albedo), vec3<f32>(0.0), v);
    }
    let inv_l = 1.0 / sqrt(dot(a, a));
    let inv_s = 1.0 / sqrt(dot(b, b));
    let ul = a * inv_l;
    let us = b * inv_s;
    let c = dot(ul, us);
    let d = ul - us;
    let g = exp(-dot(d, d) * 0.5 * P.inv_w2);
    let v = PI_INV * g / (inv_l * inv_s);
    let dl = (ul + (us - ul * c) * P.inv_w2) * (v * inv_l);
    let ds = (us + (ul - us * c) * P.inv_w2) * (v * inv_s);
    return BrdfGrad(P.albedo * v, dl * P.albedo, ds * P.albedo, v);
}

// The path length of barycentric point c of the triangle in node units, and ∂τ/∂x there (`corner` of soa/splat.rs).
struct Corner { u: f32, d: vec3<f32> }

fn corner(p0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, fr: Frame, c: vec2<f32>) -> Corner {
    let x = p0 + c.x * e1 + c.y * e2;
    let a = fr.l - x;
    let ra = sqrt(dot(a, a));
    var tau: f32;
    var d: vec3<f32>;
    if (P.confocal != 0u) {
        tau = ra + ra;
        d = a * (-2.0 / ra);
    } else {
        let b = fr.s - x;
        let rb = sqrt(dot(b, b));
        tau = ra + rb;
        d = -(a / ra + b / rb);
    }
    return Corner((tau - P.t0) * P.inv_dt - 0.5, d);
}

// `splat::centred`: the corner values shifted for τ's curvature and the distance fall-off.
fn centred(u: vec3<f32>, uc: f32, tc: f32) -> vec3<f32> {
    let var_ = ((u.x - u.y) * (u.x - u.y) + (u.y - u.z) * (u.y - u.z) + (u.x - u.z) * (u.x - u.z)) * (1.0 / 36.0);
    let s = 0.75 * (uc - (u.x + u.y + u.z) * (1.0 / 3.0)) - P.power * var_ / tc;
    return u + vec3<f32>(s);
}

// The knots of a (sub-)triangle (`splat::Knots`): sorted, shifted by k0 = ⌊a⌋.
struct Knots { k0: i32, a: f32, b: f32, c: f32, l1: f32, inv_d: f32, mean: f32, c2: f32, inv_l2: f32, ok: bool }

fn knots(u: vec3<f32>) -> Knots {
    let lo = min(min(u.x, u.y), u.z);
    let hi = max(max(u.x, u.y), u.z);
    let mid = max(min(u.x, u.y), min(max(u.x, u.y), u.z));
    // Finite and within ±2²² nodes (the CPU kernels' fast path; beyond that no real path length).
    let ok = lo > -4194304.0 && hi < 4194304.0;
    var k0f = 0.0;
    if (ok) { k0f = floor(lo); }
    let a = lo - k0f;
    let b = mid - k0f;
    let c = hi - k0f;
    let l1 = b - a;
    let l2 = c - b;
    let d = c - a;
    var inv_d = 0.0;
    if (d > 0.0) { inv_d = 1.0 / d; }
    var c2 = 0.0;
    if (l1 > 0.0) { c2 = inv_d / (3.0 * l1); }
    var inv_l2 = 0.0;
    if (l2 > 0.0) { inv_l2 = 1.0 / l2; }
    return Knots(i32(k0f), a, b, c, l1, inv_d, (a + b + c) * (1.0 / 3.0), c2, inv_l2, ok);
}

// G at the shifted node u (an integer): 0 at or below a (u ≤ 0), then the cubic pieces, then u − mean.
fn g_at(k: Knots, u: f32) -> f32 {
    if (u <= 0.0) { return 0.0; }
    if (u <= k.b) {
        let d = u - k.a;
        return d * d * d * k.c2;
    }
    if (u <= k.c) {
        let t = u - k.b;
        return (k.l1 * k.l1 * (1.0 / 3.0) + k.l1 * t + t * t * (1.0 - t * k.inv_l2 * (1.0 / 3.0))) * k.inv_d;
    }
    return u - k.mean;
}

// (G, ∂G/∂a, ∂G/∂b, ∂G/∂c) at the shifted node u (`Knots::g_grad2`, `g_grad3`, the linear tail).
fn g_grad(k: Knots, u: f32) -> vec4<f32> {
    if (u <= 0.0) { return vec4<f32>(0.0); }
    if (u <= k.b) {
        let d = u - k.a;
        let f = d * d * (3.0 * k.c2);
        let g = f * d * (1.0 / 3.0);
        let gb = -g * (3.0 * k.c2 * (k.c - k.a));
        let gc = -g * k.inv_d;
        return vec4<f32>(g, -f - gb - gc, gb, gc);
    }
    if (u <= k.c) {
        let t = u - k.b;
        let rho = t * k.inv_l2;
        let nn = k.l1 * k.l1 * (1.0 / 3.0) + k.l1 * t + t * t - t * t * rho * (1.0 / 3.0);
        let g = nn * k.inv_d;
        let f = (k.l1 + 2.0 * t - t * rho) * k.inv_d;
        let gc = (t * rho * rho * (1.0 / 3.0) - g) * k.inv_d;
        let ga = (g - (2.0 / 3.0) * k.l1 - t) * k.inv_d;
        return vec4<f32>(g, ga, -f - ga - gc, gc);
    }
    return vec4<f32>(u - k.mean, -1.0 / 3.0, -1.0 / 3.0, -1.0 / 3.0);
}

// The last bin with a weight: ⌈c⌉ (absolute).
fn span_end(k: Knots) -> i32 {
    return k.k0 + i32(ceil(k.c));
}

// The geometry of a pair at barycentric point c of triangle t: the oriented normal, a = l − x,
// b = s − x, the cosines' numerators c_l, p_l, c_s, p_s (eq. 2), and whether all four are positive.
struct Geom { n: vec3<f32>, a: vec3<f32>, b: vec3<f32>, cl: f32, pl: f32, cs: f32, ps: f32, lit: bool }

fn geometry(t: u32, fr: Frame, sign: f32, c: vec2<f32>) -> Geom {
    let x = tris[4u * t].xyz + c.x * tris[4u * t + 1u].xyz + c.y * tris[4u * t + 2u].xyz;
    let n = sign * tris[4u * t + 3u].xyz;
    let a = fr.l - x;
    var b = a;
    if (P.confocal == 0u) { b = fr.s - x; }
    let cl = -dot(fr.n_l, a);
    let pl = dot(n, a);
    let cs = -dot(fr.n_s, b);
    let ps = dot(n, b);
    return Geom(n, a, b, cl, pl, cs, ps, cl > 0.0 && cs > 0.0 && pl > 0.0 && ps > 0.0);
}

// The centroid's value of one (face, sub-triangle, measurement): w·vis·f_s·Q, 0 where a cosine test fails.
struct Sample { g: f32, ra: f32, rb: f32 }

fn centroid_sample(t: u32, fr: Frame, sign: f32, vis_w: f32, c: vec2<f32>, w: f32) -> Sample {
    let p = geometry(t, fr, sign, c);
    let ra2 = dot(p.a, p.a);
    let rb2 = dot(p.b, p.b);
    var g = 0.0;
    if (p.lit) {
        let fs = brdf_grad(p.a, p.b, p.n).value;
        g = w * vis_w * fs * (p.cl * p.pl * p.cs * p.ps * tris[4u * t + 1u].w / (ra2 * ra2 * rb2 * rb2));
    }
    return Sample(g, sqrt(ra2), sqrt(rb2));
}

// The corner node values after the centring shift, and their gradients ∂τ/∂x.
struct Corners { u: vec3<f32>, d0: vec3<f32>, d1: vec3<f32>, d2: vec3<f32> }

fn sub_corners(t: u32, fr: Frame, sub: Sub, ra: f32, rb: f32) -> Corners {
    let p0 = tris[4u * t].xyz;
    let e1 = tris[4u * t + 1u].xyz;
    let e2 = tris[4u * t + 2u].xyz;
    let k0 = corner(p0, e1, e2, fr, sub.c0);
    let k1 = corner(p0, e1, e2, fr, sub.c1);
    let k2 = corner(p0, e1, e2, fr, sub.c2);
    let tc = ra + rb;
    let u = centred(vec3<f32>(k0.u, k1.u, k2.u), (tc - P.t0) * P.inv_dt - 0.5, tc * P.inv_dt);
    return Corners(u, k0.d, k1.d, k2.d);
}

fn level_of(t: u32) -> u32 {
    return u32(tris[4u * t].w);
}

// ----- forward -----

var<workgroup> h_lo: array<atomic<u32>, HB>;
var<workgroup> h_hi: array<atomic<u32>, HB>;
var<workgroup> g_max: atomic<u32>;
var<workgroup> g_max_read: u32;

// Adds x (fixed point, |x| < 2⁶²) to bin k of the workgroup's histogram: a 64-bit two's complement sum in two
// words; the low word's carry is detected from its old value, so the total is exact whatever the order.
fn add_fixed(k: u32, x: f32) {
    let hi_f = floor(x * 2.3283064365386963e-10);
    let lo = u32(x - hi_f * 4294967296.0);
    var hi = bitcast<u32>(i32(hi_f));
    let old = atomicAdd(&h_lo[k], lo);
    if (old + lo < old) { hi = hi + 1u; }
    if (hi != 0u) { atomicAdd(&h_hi[k], hi); }
}

@compute @workgroup_size(256)
fn forward(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    // Measurements in rows of 32,768 workgroups (the grid's x dimension is limited to 65,535).
    let m = wid.x + wid.z * 32768u;
    if (m >= P.nm) { return; }
    let first = wid.y * HB;
    let count = min(HB, P.bins - first);
    for (var k = lid; k < HB; k = k + WG) {
        atomicStore(&h_lo[k], 0u);
        atomicStore(&h_hi[k], 0u);
    }
    if (lid == 0u) { atomicStore(&g_max, 0u); }
    workgroupBarrier();
    let fr = frame(m);
    // Sweep 1: the largest value (non-negative floats order as their bits).
    var local_max = 0.0;
    for (var t = lid; t < P.nt; t = t + WG) {
        let pf = pair_factor(t, m, fr);
        if (pf.x == 0.0 || pf.y == 0.0) { continue; }
        let n = level_of(t);
        let w = 1.0 / f32(n * n);
        for (var j = 0u; j < n * n; j = j + 1u) {
            let sub = sub_triangle(n, j);
            local_max = max(local_max, centroid_sample(t, fr, pf.x, pf.y, sub.cen, w).g);
        }
    }
    atomicMax(&g_max, bitcast<u32>(local_max));
    workgroupBarrier();
    if (lid == 0u) { g_max_read = atomicLoad(&g_max); }
    let gm = bitcast<f32>(workgroupUniformLoad(&g_max_read));
    if (gm > 0.0) {
        // |bin| ≤ Σ g ≤ max_contrib · g_max < 2^e: scale by 2^(61 − e) (at most 2^126, a normal f32).
        let e = frexp(gm * P.max_contrib).exp;
        let scale = ldexp(1.0, min(61 - e, 126));
        let lo_bin = i32(first);
        let hi_bin = i32(first + count) - 1;
        for (var t = lid; t < P.nt; t = t + WG) {
            let pf = pair_factor(t, m, fr);
            if (pf.x == 0.0 || pf.y == 0.0) { continue; }
            let n = level_of(t);
            let w = 1.0 / f32(n * n);
            for (var j = 0u; j < n * n; j = j + 1u) {
                let sub = sub_triangle(n, j);
                let smp = centroid_sample(t, fr, pf.x, pf.y, sub.cen, w);
                if (smp.g == 0.0) { continue; }
                let cn = sub_corners(t, fr, sub, smp.ra, smp.rb);
                let kn = knots(cn.u);
                if (!kn.ok) { continue; }
                let k_lo = max(kn.k0, lo_bin);
                let k_hi = min(span_end(kn), hi_bin);
                if (k_lo > k_hi) { continue; }
                let gs = smp.g * scale;
                var gm1 = g_at(kn, f32(k_lo - 1 - kn.k0));
                var g0 = g_at(kn, f32(k_lo - kn.k0));
                for (var k = k_lo; k <= k_hi; k = k + 1) {
                    let g1 = g_at(kn, f32(k + 1 - kn.k0));
                    add_fixed(u32(k - lo_bin), gs * (gm1 - 2.0 * g0 + g1));
                    gm1 = g0;
                    g0 = g1;
                }
            }
        }
        workgroupBarrier();
        for (var k = lid; k < count; k = k + WG) {
            let hi = f32(bitcast<i32>(atomicLoad(&h_hi[k])));
            let lo = f32(atomicLoad(&h_lo[k]));
            rows[m * P.bins + first + k] = (hi * 4294967296.0 + lo) / scale;
        }
    } else {
        for (var k = lid; k < count; k = k + WG) {
            rows[m * P.bins + first + k] = 0.0;
        }
    }
}

// ----- adjoint -----

fn row_at(m: u32, k: i32) -> f32 {
    if (k < 0 || k >= i32(P.bins)) { return 0.0; }
    return rows[m * P.bins + u32(k)];
}

// `splat::to_corners`: derivatives in sorted order back to the corners.
fn to_corners(u: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let lo = min(min(u.x, u.y), u.z);
    let hi = max(max(u.x, u.y), u.z);
    var r = vec3<f32>(d.y);
    if (u.x == lo) { r.x = d.x; } else if (u.x == hi) { r.x = d.z; }
    if (u.y == lo) { r.y = d.x; } else if (u.y == hi) { r.y = d.z; }
    if (u.z == lo) { r.z = d.x; } else if (u.z == hi) { r.z = d.z; }
    return r;
}

@compute @workgroup_size(256)
fn adjoint(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x;
    if (t >= P.nt) { return; }
    let m0 = gid.y * P.chunk;
    let m1 = min(m0 + P.chunk, P.nm);
    let inv_n2 = tris[4u * t + 2u].w;
    let n = level_of(t);
    let w = 1.0 / f32(n * n);
    var acc0 = vec3<f32>(0.0);
    var acc1 = vec3<f32>(0.0);
    var acc2 = vec3<f32>(0.0);
    var acc_n = vec3<f32>(0.0);
    var acc_p = 0.0;
    for (var m = m0; m < m1; m = m + 1u) {
        let fr = frame(m);
        let pf = pair_factor(t, m, fr);
        if (pf.x == 0.0 || pf.y == 0.0) { continue; }
        let sg = pf.x;
        let s = w * pf.y;
        for (var j = 0u; j < n * n; j = j + 1u) {
            let sub = sub_triangle(n, j);
            let p = geometry(t, fr, sg, sub.cen);
            if (!p.lit) { continue; }
            let a = p.a;
            let b = p.b;
            let nrm = p.n;
            let cl = p.cl;
            let pl = p.pl;
            let cs = p.cs;
            let ps = p.ps;
            let ra = sqrt(dot(a, a));
            let rb = sqrt(dot(b, b));
            // Stage 2: the closed-form gather Σ r_k w_k and Σ r_k ∂w_k/∂(a, b, c) over the span.
            let cn = sub_corners(t, fr, sub, ra, rb);
            let kn = knots(cn.u);
            var val = 0.0;
            var dsort = vec3<f32>(0.0);
            if (kn.ok) {
                let k_lo = max(kn.k0, -1);
                let k_hi = min(span_end(kn), i32(P.bins));
                if (k_lo <= k_hi) {
                    var gm1 = g_grad(kn, f32(k_lo - 1 - kn.k0));
                    var g0 = g_grad(kn, f32(k_lo - kn.k0));
                    for (var k = k_lo; k <= k_hi; k = k + 1) {
                        let g1 = g_grad(kn, f32(k + 1 - kn.k0));
                        let r = row_at(m, k);
                        let d2 = gm1 - 2.0 * g0 + g1;
                        val = val + r * d2.x;
                        dsort = dsort + r * d2.yzw;
                        gm1 = g0;
                        g0 = g1;
                    }
                }
            }
            let d = to_corners(cn.u, dsort);
            let sum = d.x + d.y + d.z;
            // Through the centring shift (`splat::centred_grad`); node units → metres of path.
            let tcb = (ra + rb) * P.inv_dt;
            let kk = P.power / tcb;
            let usum = cn.u.x + cn.u.y + cn.u.z;
            let var_ = ((cn.u.x - cn.u.y) * (cn.u.x - cn.u.y) + (cn.u.y - cn.u.z) * (cn.u.y - cn.u.z)
                + (cn.u.x - cn.u.z) * (cn.u.x - cn.u.z)) * (1.0 / 36.0);
            let ds_du = vec3<f32>(-0.25) - kk * (3.0 * cn.u - vec3<f32>(usum)) * (1.0 / 18.0);
            let ds_dtc = 0.75 + kk * var_ / tcb;
            let av = val;
            let ad = sum * ds_dtc * P.inv_dt;
            let ct = (d + sum * ds_du) * P.inv_dt;
            // Stage 3: the centroid value's gradient (`adjoint_samples`, SPLAT).
            let bg = brdf_grad(a, b, nrm);
            let fs = bg.value;
            var gx: vec3<f32>;
            var gn: vec3<f32>;
            var sp: f32;
            var sh: f32;
            if (P.confocal != 0u) {
                let ra2 = dot(a, a);
                let inv_ra2 = 1.0 / ra2;
                let i4 = inv_ra2 * inv_ra2;
                let denom = tris[4u * t + 1u].w * (i4 * i4);
                let clpl = cl * pl;
                let q = clpl * clpl * denom;
                let h = fs * q;
                let dq_a = (clpl * denom) * (cl * nrm - pl * fr.n_l) - (4.0 * q * inv_ra2) * a;
                let dq_n = (cl * cl * denom * 2.0 * pl) * a - (q * inv_n2) * nrm;
                let gab = s * (av * (2.0 * fs * dq_a + q * bg.dl) + (2.0 * h * ad * (ra * inv_ra2)) * a);
                gx = -gab;
                gn = sg * (s * av * (fs * dq_n));
                sp = s * av * q;
                sh = s * h;
            } else {
                let ra2 = dot(a, a);
                let rb2 = dot(b, b);
                let inv = 1.0 / (ra2 * rb2);
                let inv_ra2 = rb2 * inv;
                let inv_rb2 = ra2 * inv;
                let denom = tris[4u * t + 1u].w * (inv * inv);
                let q = cl * pl * cs * ps * denom;
                let h = fs * q;
                let dq_a = (cs * ps * denom) * (cl * nrm - pl * fr.n_l) - (4.0 * q * inv_ra2) * a;
                let dq_b = (cl * pl * denom) * (cs * nrm - ps * fr.n_s) - (4.0 * q * inv_rb2) * b;
                let dq_n = (cl * cs * denom) * (ps * a + pl * b) - (q * inv_n2) * nrm;
                let ga = s * (av * (fs * dq_a + q * bg.dl) + (h * ad * (ra * inv_ra2)) * a);
                let gb = s * (av * (fs * dq_b + q * bg.ds) + (h * ad * (rb * inv_rb2)) * b);
                gx = -(ga + gb);
                gn = sg * (s * av * (fs * dq_n));
                sp = s * av * q;
                sh = s * h;
            }
            // Stage 4: the corners' path-length terms, then the barycentric distribution.
            let gc0 = (sh * ct.x) * cn.d0;
            let gc1 = (sh * ct.y) * cn.d1;
            let gc2 = (sh * ct.z) * cn.d2;
            let cu = sub.cen.x;
            let cv = sub.cen.y;
            acc0 = acc0 + (1.0 - cu - cv) * gx + (1.0 - sub.c0.x - sub.c0.y) * gc0
                + (1.0 - sub.c1.x - sub.c1.y) * gc1 + (1.0 - sub.c2.x - sub.c2.y) * gc2;
            acc1 = acc1 + cu * gx + sub.c0.x * gc0 + sub.c1.x * gc1 + sub.c2.x * gc2;
            acc2 = acc2 + cv * gx + sub.c0.y * gc0 + sub.c1.y * gc1 + sub.c2.y * gc2;
            acc_n = acc_n + gn;
            acc_p = acc_p + sp * bg.dp;
        }
    }
    let o = 16u * (gid.y * P.nt + t);
    partial[o] = acc0.x;
    partial[o + 1u] = acc0.y;
    partial[o + 2u] = acc0.z;
    partial[o + 3u] = acc1.x;
    partial[o + 4u] = acc1.y;
    partial[o + 5u] = acc1.z;
    partial[o + 6u] = acc2.x;
    partial[o + 7u] = acc2.y;
    partial[o + 8u] = acc2.z;
    partial[o + 9u] = acc_n.x;
    partial[o + 10u] = acc_n.y;
    partial[o + 11u] = acc_n.z;
    partial[o + 12u] = acc_p;
    partial[o + 13u] = 0.0;
    partial[o + 14u] = 0.0;
    partial[o + 15u] = 0.0;
}

// Adds the measurement ranges' partial sums in order (rows[16·slot + i] = Σ_ranges), deterministic.
@compute @workgroup_size(256)
fn reduce(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= 16u * P.nt) { return; }
    let ranges = (P.nm + P.chunk - 1u) / P.chunk;
    var s = 0.0;
    for (var r = 0u; r < ranges; r = r + 1u) {
        s = s + partial[16u * r * P.nt + i];
    }
    reduced[i] = s;
}
