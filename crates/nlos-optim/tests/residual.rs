//! Residual back-projection (`nlos_optim::residual`): a part of the object that the mesh lacks is found
//! from the residual at its place and depth, and only there; a residual of noise adds nothing, nor does
//! one that falls slowly in time (a sensor's tail, a background); the
//! reported change is the exact change of the data term; a scan that is not a confocal grid is skipped.
#![allow(clippy::unwrap_used)]

mod common;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_optim::{
    DataTerm, LOCALISED_CONTRAST, PatchFit, ResidualParams, localisation, residual_patches, residual_rounds,
};
use nlos_render::RowSpan;
use nlos_render::{RenderParams, Renderer, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// A square facing the wall (normals −z), centred at (cx, cy) at depth z, `n × n` cells of `cell`.
fn square(cx: f32, cy: f32, z: f32, n: i32, cell: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    common::height_field(n, cell, cx, cy, |_, _| z)
}

fn union(a: (Vec<Vec3>, Vec<[u32; 3]>), b: (Vec<Vec3>, Vec<[u32; 3]>)) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let n = a.0.len() as u32;
    let mut p = a.0;
    p.extend(b.0);
    let mut t = a.1;
    t.extend(b.1.iter().map(|f| f.map(|v| v + n)));
    (p, t)
}

/// The object the mesh has (A) and the one it lacks (B, deeper and to the side).
fn object_a() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    square(-0.1, -0.05, 0.3, 6, 0.02)
}
fn object_b() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    square(0.12, 0.08, 0.45, 6, 0.02)
}

struct Setup {
    scan: Scan,
    time: TimeAxis,
    render: RenderParams,
}

fn setup() -> Setup {
    Setup {
        scan: Scan::confocal(PointSet::wall_grid(16, 16, 0.25, 0.25).unwrap()),
        time: TimeAxis::new(0.0, 0.004, 320).unwrap(),
        render: RenderParams { visibility: Visibility::Cached { level: 1 }, ..RenderParams::default() },
    }
}

fn render(s: &Setup, mesh: &(Vec<Vec3>, Vec<[u32; 3]>)) -> Vec<f32> {
    Renderer::new(&mesh.0, &mesh.1, &s.scan, &s.time, s.render).unwrap().forward(&Lambertian::new(1.0f32).unwrap())
}

fn brdf() -> nlos_render::AnyBrdf {
    nlos_render::AnyBrdf::Lambertian(Lambertian::new(1.0f32).unwrap())
}

/// Runs the back-projection of `mesh` against `measured` (L2, scale 1); returns the patches, the data term
/// before and after (from the updated rendering).
fn run(s: &Setup, mesh: &(Vec<Vec3>, Vec<[u32; 3]>), measured: &[f32]) -> (nlos_optim::Patches, f64, f64) {
    let bins = s.time.bins;
    let term = DataTerm::default();
    let row_loss = |m: usize, row: &[f32], w: std::ops::Range<usize>| {
        term.row_value_in(row, &measured[m * bins..(m + 1) * bins], m * bins, 1.0, w)
    };
    let total = |r: &[f32]| -> f64 {
        (0..s.scan.measurements()).map(|m| row_loss(m, &r[m * bins..(m + 1) * bins], 0..bins).unwrap()).sum()
    };
    let mut rendered = render(s, mesh);
    let before = total(&rendered);
    let residual: Vec<f32> = measured.iter().zip(&rendered).map(|(m, r)| m - r).collect();
    let t = Transient::new(s.scan.clone(), s.time, measured.to_vec()).unwrap();
    let p = residual_patches(
        &mesh.0,
        &mesh.1,
        &t,
        residual,
        PatchFit { render: s.render, brdf: &brdf(), rendered: &mut rendered, row_loss: &row_loss },
        &ResidualParams::default(),
    )
    .unwrap();
    let after = total(&rendered);
    (p, before, after)
}

#[test]
fn the_missing_part_is_found_where_it_is() {
    let s = setup();
    let measured = render(&s, &union(object_a(), object_b()));
    let mesh = object_a();
    let (p, before, after) = run(&s, &mesh, &measured);
    assert!(p.accepted >= 1 && !p.triangles.is_empty(), "{p:?}");
    // Every new vertex lies at B: within a column spacing (0.033 m) of its square and within 2 cm of its depth.
    for v in &p.positions {
        assert!((v.x - 0.12).abs() < 0.06 + 0.034 && (v.y - 0.08).abs() < 0.06 + 0.034, "vertex {v} not at B");
        assert!((v.z - 0.45).abs() < 0.02, "vertex {v} not at B's depth 0.45");
    }
    // The patches are new vertices after the mesh's.
    let n = mesh.0.len() as u32;
    assert!(p.triangles.iter().flatten().all(|&v| v >= n && v < n + p.positions.len() as u32));
    // The reported change is the change of the data term, and it is a large part of B's share.
    assert!(p.data_change < 0.0);
    assert!(((after - before) - p.data_change).abs() <= 1e-6 * before, "{} vs {}", after - before, p.data_change);
    assert!(after < 0.5 * before, "data term {before} → {after}");
}

#[test]
fn a_residual_of_noise_adds_nothing() {
    let s = setup();
    let truth = union(object_a(), object_b());
    let clean = render(&s, &truth);
    let peak = clean.iter().copied().fold(0.0f32, f32::max);
    // Zero-mean uniform noise of ±2 % of the peak (seeded, so the test is deterministic).
    let mut rng = nlos_transient::rng::Pcg32::new(7, 0);
    let measured: Vec<f32> = clean.iter().map(|&c| c + 0.04 * peak * (rng.uniform() as f32 - 0.5)).collect();
    let (p, before, after) = run(&s, &truth, &measured);
    // The noise's back-projection is proposed (regions at random depths) and refused.
    assert!(p.regions >= 1, "a proposal must be made for the test to mean anything: {p:?}");
    assert_eq!(p.accepted, 0, "{p:?}");
    assert!(p.positions.is_empty() && p.triangles.is_empty());
    assert_eq!(before, after);
}

/// A scan that is not a confocal grid (one laser spot, the sensor spots on the grid) takes the phasor field of
/// the residual instead of the LCT: the missing part is found there too, at its place and depth.
#[test]
fn a_one_laser_scan_finds_the_missing_part_through_the_phasor_field() {
    let s = setup();
    let points = PointSet::wall_grid(16, 16, 0.25, 0.25).unwrap();
    let scan = Scan::exhaustive(PointSet::wall_grid(1, 1, 0.0, 0.0).unwrap(), points);
    let s2 = Setup { scan, ..s };
    let measured = render(&s2, &union(object_a(), object_b()));
    let (p, before, after) = run(&s2, &object_a(), &measured);
    assert!(p.skipped.is_none() && p.accepted >= 1 && !p.triangles.is_empty(), "{p:?}");
    // Within two column spacings of B's square (the phasor field's wave, 3 spacings long, blurs wider than the
    // LCT's one) and 2 cm of its depth.
    for v in &p.positions {
        assert!((v.x - 0.12).abs() < 0.06 + 0.067 && (v.y - 0.08).abs() < 0.06 + 0.067, "vertex {v} not at B");
        assert!((v.z - 0.45).abs() < 0.02, "vertex {v} not at B's depth 0.45");
    }
    assert!(((after - before) - p.data_change).abs() <= 1e-6 * before, "{} vs {}", after - before, p.data_change);
    assert!(after < before, "data term {before} → {after}");
}

#[test]
fn a_residual_of_the_wrong_length_is_a_typed_error() {
    let s = setup();
    let mesh = object_a();
    let measured = render(&s, &mesh);
    let mut rendered = measured.clone();
    let t = Transient::new(s.scan.clone(), s.time, measured.clone()).unwrap();
    let term = DataTerm::default();
    let bins = s.time.bins;
    let row_loss = |m: usize, row: &[f32], w: std::ops::Range<usize>| {
        term.row_value_in(row, &measured[m * bins..(m + 1) * bins], m * bins, 1.0, w)
    };
    let e = residual_patches(
        &mesh.0,
        &mesh.1,
        &t,
        vec![0.0; 7],
        PatchFit { render: s.render, brdf: &brdf(), rendered: &mut rendered, row_loss: &row_loss },
        &ResidualParams::default(),
    );
    assert!(matches!(e, Err(nlos_optim::OptimError::LengthMismatch { what: "residual", .. })), "{e:?}");
}

#[test]
fn a_hot_pixel_is_not_explained_by_surface() {
    // One measurement's histogram carries a spike (one bin, the height of the signal's peak) that no
    // surface made it. Its back-projection is a spherical shell about that spot, coherent enough to be
    // proposed. Rendered, a shell piece lights every measurement it faces: a patch that faces the wall adds
    // more error than it explains and is refused; pieces tilted to 70° (which light mostly that spot) and
    // at least `min_faces` large may still lower the L2 term a little, but they must explain only a sliver
    // of the spike (a whole-region test once accepted shell pieces worth a quarter of it at five times the
    // height).
    let s = setup();
    let truth = union(object_a(), object_b());
    let mut measured = render(&s, &truth);
    let peak = measured.iter().copied().fold(0.0f32, f32::max);
    let (m, bin) = (5 * 16 + 11, 200);
    measured[m * s.time.bins + bin] += peak;
    let (p, before, after) = run(&s, &truth, &measured);
    assert!(p.regions >= 1, "the shell must be proposed for the test to mean anything: {p:?}");
    assert!(after <= before);
    assert!(before - after < 0.05 * before, "{before} → {after}");
}

/// The contrast of `localisation` on one row of 400 bins of 4 mm: the patch's light on bins 100..105,
/// against a residual given per bin.
fn contrast_of(residual: impl Fn(usize) -> f32) -> f64 {
    let bins = 400;
    let span = RowSpan { measurement: 1, first_bin: 100, values: vec![1.0; 5] };
    let mut r = vec![0.0f32; 2 * bins];
    for k in 0..bins {
        r[bins + k] = residual(k);
    }
    localisation(std::iter::once(std::slice::from_ref(&span)), &r, bins, 0.004)
}

#[test]
fn localisation_tells_a_return_from_a_background_and_a_tail() {
    let light = |k: usize| if (100..105).contains(&k) { 1.0 } else { 0.0 };
    // The patch's own return, alone or on a flat background: far above the threshold.
    assert_eq!(contrast_of(light), f64::INFINITY);
    let on_background = contrast_of(|k| light(k) + 0.1);
    assert!((on_background - 11.0).abs() < 1e-6, "{on_background}");
    // A background the model lacks matches as well anywhere: contrast 1.
    assert!((contrast_of(|_| 0.3) - 1.0).abs() < 1e-12);
    // A falling tail matches better before the patch: contrast below 1.
    let tail = contrast_of(|k| (-(k as f32) / 60.0).exp());
    assert!(tail < 1.0, "{tail}");
    // A residual that is negative at the patch: 0.
    assert_eq!(contrast_of(|k| -light(k)), 0.0);
    assert!(LOCALISED_CONTRAST > 1.0 && on_background >= LOCALISED_CONTRAST && tail < LOCALISED_CONTRAST);
}

/// What a gated capture keeps besides the object and a model without background lacks: a floor of ambient
/// light and dark counts, and the direct light's diffusion tail falling slowly across the axis. The
/// back-projection of that residual proposes surface, the data test takes some of it (it does lower an L2
/// term), and the localisation test refuses every such patch.
///
/// (A tail that begins exactly at a return is another matter: a large surface just behind the object
/// begins the same way, and the test keeps it when its light lies in that tail's first stretch.)
#[test]
fn a_background_and_a_slow_tail_are_not_explained_by_surface() {
    let s = setup();
    let truth = object_a();
    let mut measured = render(&s, &truth);
    let bins = s.time.bins;
    let peak = measured.iter().copied().fold(0.0f32, f32::max);
    for row in measured.chunks_exact_mut(bins) {
        for (k, v) in row.iter_mut().enumerate() {
            let path = (k as f32 + 0.5) * 0.004;
            *v += 0.05 * peak * (1.0 + (-path / 0.3).exp());
        }
    }
    let (p, before, after) = run(&s, &truth, &measured);
    assert!(!p.notes.is_empty(), "a patch must pass the data test for the test to mean anything: {p:?}");
    assert!(p.notes.iter().all(|n| !n.kept && n.contrast.is_none_or(|c| c < LOCALISED_CONTRAST)), "{:?}", p.notes);
    assert_eq!(p.accepted, 0);
    assert!(p.triangles.is_empty());
    assert_eq!(before, after);
}

/// A strip facing the wall from x0 to x1 (`n` cells along x), `width` wide about y = 0, at depth z.
fn strip(x0: f32, x1: f32, width: f32, z: f32, n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for i in 0..=n {
        let x = x0 + (x1 - x0) * i as f32 / n as f32;
        p.extend([Vec3::new(x, -width / 2.0, z), Vec3::new(x, width / 2.0, z)]);
    }
    // (v1 − v0) × (v2 − v0) points to −z, toward the wall.
    let t = (0..n).flat_map(|i| [[2 * i, 2 * i + 1, 2 * i + 2], [2 * i + 2, 2 * i + 1, 2 * i + 3]]).collect();
    (p, t)
}

/// The area of the patches' triangles whose centroids lie within the rectangle `x × y` (the patches' vertex
/// indices follow the mesh's `n` vertices).
fn area_within(p: &nlos_optim::Patches, n: usize, x: (f32, f32), y: (f32, f32)) -> f32 {
    p.triangles
        .iter()
        .map(|t| t.map(|v| p.positions[v as usize - n]))
        .filter(|[a, b, c]| {
            let m = (*a + *b + *c) / 3.0;
            (x.0..=x.1).contains(&m.x) && (y.0..=y.1).contains(&m.y)
        })
        .map(|[a, b, c]| 0.5 * (b - a).cross(c - a).length())
        .sum()
}

/// A start that lacks a limb grows it back: a body and, attached to it at the same depth, a thin limb
/// (4 × 15 cm, about one column of the scan wide) are measured; the mesh has the body only. The limb's
/// columns beyond the separation from the body's rim become a patch along the limb, out to its far end, and
/// nowhere else; so too with one laser spot at the wall's centre (the phasor field of the residual). Without
/// growth the mesh would keep none of the limb.
#[test]
fn a_limb_cut_off_the_start_grows_back() {
    let confocal = setup();
    let grid = PointSet::wall_grid(16, 16, 0.25, 0.25).unwrap();
    let one_laser = Scan::exhaustive(PointSet::wall_grid(1, 1, 0.0, 0.0).unwrap(), grid);
    let body = square(-0.08, 0.0, 0.35, 5, 0.025);
    let (x0, x1, width) = (-0.0175, 0.1325, 0.04);
    let limb = strip(x0, x1, width, 0.35, 6);
    for s in [Setup { scan: one_laser, ..setup() }, confocal] {
        let measured = render(&s, &union(body.clone(), limb.clone()));
        let (p, before, after) = run(&s, &body, &measured);
        assert!(p.accepted >= 1, "{p:?}");
        // Within two column spacings of the limb (the phasor field blurs wider than the LCT) and 2 cm of its depth.
        let margin = 0.067;
        for v in &p.positions {
            assert!(
                v.x > x0 - margin && v.x < x1 + margin && v.y.abs() < width / 2.0 + margin,
                "vertex {v} off the limb"
            );
            assert!((v.z - 0.35).abs() < 0.02, "vertex {v} not at the limb's depth 0.35");
        }
        let n = body.0.len();
        let limb_area = (x1 - x0) * width;
        let grown = area_within(&p, n, (x0, x1 + margin), (-width / 2.0 - margin, width / 2.0 + margin));
        let far = area_within(&p, n, ((x0 + x1) / 2.0, x1 + margin), (-1.0, 1.0));
        assert!(grown >= 0.5 * limb_area, "grew {grown} m² of the limb's {limb_area}");
        assert!(far >= 0.2 * limb_area, "grew {far} m² on the limb's far half: {p:?}");
        assert!(after < 0.5 * before, "data term {before} → {after}");
    }
}

/// A start on a capture of noise alone (no object at all) grows nothing: the residual is the whole capture,
/// its back-projection proposes regions, and none lowers the data term by more than the margin.
#[test]
fn a_start_on_a_capture_of_noise_grows_nothing() {
    let s = setup();
    let start = square(0.0, 0.0, 0.35, 5, 0.025);
    let peak = render(&s, &start).iter().copied().fold(0.0f32, f32::max);
    let mut rng = nlos_transient::rng::Pcg32::new(11, 0);
    let measured: Vec<f32> =
        (0..s.scan.measurements() * s.time.bins).map(|_| 0.05 * peak * (rng.uniform() as f32 - 0.5)).collect();
    let (p, before, after) = run(&s, &start, &measured);
    assert!(p.regions >= 1, "a proposal must be made for the test to mean anything: {p:?}");
    assert_eq!(p.accepted, 0, "{p:?}");
    assert!(p.triangles.is_empty());
    assert_eq!(before, after);
}

/// Rounds ([`residual_rounds`]): a second round looks at the residual the first round's patches leave. Here
/// the first round grows the limb and a second patch grows next to it or farther out; every round's vertex
/// indices follow the mesh's and the earlier rounds', the rendering is the grown mesh's, and the rounds end
/// at the first that accepts nothing.
#[test]
fn rounds_grow_what_the_first_round_left() {
    let s = setup();
    let body = square(-0.08, 0.0, 0.35, 5, 0.025);
    let limb = strip(-0.0175, 0.1325, 0.04, 0.35, 6);
    // A dim part apart from both: a small square deeper and across the wall.
    let dim = square(-0.1, 0.15, 0.45, 2, 0.02);
    let measured = render(&s, &union(union(body.clone(), limb), dim));
    let bins = s.time.bins;
    let term = DataTerm::default();
    let row_loss = |m: usize, row: &[f32], w: std::ops::Range<usize>| {
        term.row_value_in(row, &measured[m * bins..(m + 1) * bins], m * bins, 1.0, w)
    };
    let t = Transient::new(s.scan.clone(), s.time, measured.clone()).unwrap();
    let grow = |rounds: usize, round_gain: f64| {
        let mut rendered = render(&s, &body);
        let mut residual_of =
            |r: &[f32]| -> nlos_optim::Result<Vec<f32>> { Ok(measured.iter().zip(r).map(|(m, r)| m - r).collect()) };
        let fit = PatchFit { render: s.render, brdf: &brdf(), rendered: &mut rendered, row_loss: &row_loss };
        let params = ResidualParams { rounds, round_gain, ..ResidualParams::default() };
        let p = residual_rounds(&body.0, &body.1, &t, &mut residual_of, fit, &params).unwrap();
        (p, rendered)
    };
    let (one, _) = grow(1, 0.0);
    let (three, rendered) = grow(3, 0.0);
    // A second round follows only a first that explained at least `round_gain` of the data term.
    let (demanding, _) = grow(3, 1.0);
    assert_eq!(one.len(), 1);
    assert_eq!(demanding.len(), 1);
    assert_eq!(one[0], three[0], "the first round does not depend on the rounds after it");
    assert!(three.len() >= 2 && three[1].accepted >= 1, "the second round grew nothing: {three:?}");
    // With no gain demanded, the rounds still end at the first that grows nothing.
    assert!(three.iter().rev().skip(1).all(|p| p.accepted > 0), "rounds went on after one that grew nothing");
    let (ten, _) = grow(10, 0.0);
    assert!(ten.len() < 10 && ten.last().unwrap().accepted == 0, "{} rounds", ten.len());
    // The limb is most of the data term: the default gain lets the second round follow too.
    assert!(grow(3, ResidualParams::default().round_gain).0.len() >= 2);
    // The grown mesh, rounds appended in order, renders what the rounds left in `rendered` (up to the shadows
    // patches and mesh cast on each other: a patch's share is rendered alone, the module docs).
    let mut mesh = body.clone();
    for p in &three {
        let n = mesh.0.len() as u32;
        assert!(p.triangles.iter().flatten().all(|&v| v < n + p.positions.len() as u32));
        mesh.0.extend_from_slice(&p.positions);
        mesh.1.extend_from_slice(&p.triangles);
    }
    let direct = render(&s, &mesh);
    let peak = direct.iter().copied().fold(0.0f32, f32::max);
    let worst = direct.iter().zip(&rendered).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst <= 5e-3 * peak, "the rounds' rendering is off the grown mesh's by {worst} (peak {peak})");
    let total = |r: &[f32]| -> f64 {
        (0..s.scan.measurements()).map(|m| row_loss(m, &r[m * bins..(m + 1) * bins], 0..bins).unwrap()).sum()
    };
    let change: f64 = three.iter().map(|p| p.data_change).sum();
    assert!(((total(&rendered) - total(&render(&s, &body))) - change).abs() <= 1e-6 * total(&render(&s, &body)));
    assert!(three[1].data_change < 0.0);
}
