use glam::{DVec3, Vec3};
use nlos_mesh::remeshing::{RemeshParams, uniform_remeshing};
use nlos_mesh::shapes::plane_grid;

use super::{FaceField, Remap, Source, Surface, VertexField};
use crate::adam::Moments;
use crate::error::OptimError;

/// A field no topology operation knows of: declared here, in the test, as a user's would be.
const HEIGHT: VertexField<f64> = VertexField::new("test.height", -1.0);
const MARK: VertexField<bool> = VertexField::new("test.mark", false);
const TAG: FaceField<f64> = FaceField::new("test.tag", 7.0);

fn grid(n: usize) -> Surface {
    Surface::from_mesh(&plane_grid(0.2, 0.2, n, n)).expect("grid")
}

/// Writes the x coordinate of every vertex into HEIGHT and the face index into TAG.
fn with_fields(mut s: Surface) -> Surface {
    let x: Vec<f64> = s.positions().iter().map(|p| f64::from(p.x)).collect();
    s.vertex_mut(HEIGHT).expect("new field").copy_from_slice(&x);
    for (i, t) in s.face_mut(TAG).expect("new field").iter_mut().enumerate() {
        *t = i as f64;
    }
    s
}

/// Kept faces renumber their vertices in order of first use, and every field follows: vertex values by
/// their old vertex, face values by their old face.
#[test]
fn keeping_faces_carries_every_field() {
    let s = with_fields(grid(4));
    // The first quad's two triangles go with the rest: the corner vertex they alone use goes too.
    let keep: Vec<bool> = (0..s.n_faces()).map(|f| f >= 2 && f % 5 != 3).collect();
    let remap = Remap::keep_faces(&s, &keep);
    let mut t = s.clone();
    t.apply(remap.clone()).expect("apply");
    assert_eq!(t.n_faces(), keep.iter().filter(|k| **k).count());
    for (new, source) in remap.vertices.iter().enumerate() {
        let Source::Kept(old) = *source else { panic!("a kept vertex: {source:?}") };
        assert_eq!(t.positions()[new], s.positions()[old as usize]);
        assert_eq!(t.vertex(HEIGHT).expect("kept")[new], s.vertex(HEIGHT).expect("set")[old as usize]);
    }
    let kept_faces: Vec<f64> = (0..s.n_faces()).filter(|&f| keep[f]).map(|f| f as f64).collect();
    assert_eq!(t.face(TAG).expect("kept"), kept_faces.as_slice());
    assert!(t.n_vertices() < s.n_vertices(), "unused vertices go");
    t.validate().expect("valid");
}

/// Appended vertices and faces start at the field's initial value; the old ones keep theirs.
#[test]
fn appended_elements_start_at_the_initial_value() {
    let mut s = with_fields(grid(2));
    s.vertex_mut(MARK).expect("new")[0] = true;
    let (nv, nf) = (s.n_vertices(), s.n_faces());
    let before = s.clone();
    let p = [Vec3::new(0.0, 0.0, 0.6), Vec3::new(0.01, 0.0, 0.6), Vec3::new(0.0, 0.01, 0.6)];
    let base = nv as u32;
    let remap = Remap::append(&s, &p, &[[base, base + 2, base + 1]]);
    s.apply(remap).expect("apply");
    assert_eq!((s.n_vertices(), s.n_faces()), (nv + 3, nf + 1));
    assert_eq!(&s.vertex(HEIGHT).expect("kept")[..nv], before.vertex(HEIGHT).expect("set"));
    assert_eq!(&s.vertex(HEIGHT).expect("kept")[nv..], &[-1.0; 3]);
    assert_eq!(s.vertex(MARK).expect("kept")[..2], [true, false]);
    assert_eq!(s.face(TAG).expect("kept")[nf], 7.0);
}

/// Remeshing moves every vertex: a field linear over a plane is interpolated exactly at the new vertices
/// (closest point, barycentric), the Adam moments by the same weights, and every new face takes the old
/// face under its centroid.
#[test]
fn remeshing_interpolates_vertex_fields_and_picks_face_fields() {
    let mut s = with_fields(grid(6));
    let n = s.n_vertices();
    for (i, m) in s.vertex_mut(crate::reconstruct::SHAPE_MOMENTS).expect("new").iter_mut().enumerate() {
        *m = Moments { m: DVec3::new(i as f64, 0.0, 0.0), v: 2.0 };
    }
    let mut mesh = s.mesh().expect("mesh");
    uniform_remeshing(&mut mesh, 0.02, &RemeshParams::default()).expect("remesh");
    let remap = Remap::closest(&s, &mesh).expect("map");
    assert!(remap.positions.len() != n, "the remeshing changed the vertex count");
    let old = s.clone();
    s.apply(remap.clone()).expect("apply");
    for (p, h) in s.positions().iter().zip(s.vertex(HEIGHT).expect("carried")) {
        assert!((f64::from(p.x) - h).abs() < 1e-5, "x {} carried as {h}", p.x);
    }
    for (m, source) in s.vertex(crate::reconstruct::SHAPE_MOMENTS).expect("carried").iter().zip(&remap.vertices) {
        let Source::Interpolated(w) = *source else { panic!("interpolated: {source:?}") };
        let want: f64 = w.iter().map(|&(j, wj)| f64::from(wj) * j as f64).sum();
        assert!((m.m.x - want).abs() < 1e-9 && (m.v - 2.0).abs() < 1e-5, "{m:?} against {want}");
    }
    let tags = s.face(TAG).expect("carried");
    for (t, &tag) in s.triangles().iter().zip(tags) {
        let c = (s.positions()[t[0] as usize] + s.positions()[t[1] as usize] + s.positions()[t[2] as usize]) / 3.0;
        let f = old.triangles()[tag as usize].map(|v| old.positions()[v as usize]);
        let (lo, hi) = (f[0].min(f[1]).min(f[2]), f[0].max(f[1]).max(f[2]));
        assert!(c.x >= lo.x - 1e-6 && c.x <= hi.x + 1e-6 && c.y >= lo.y - 1e-6 && c.y <= hi.y + 1e-6, "face {tag}");
    }
}

/// The boundary flags derived from the triangles are the half-edge mesh's, before and after faces go.
#[test]
fn boundary_vertices_are_the_half_edge_meshs() {
    let s = grid(5);
    let keep: Vec<bool> = (0..s.n_faces()).map(|f| f != 20 && f != 21).collect();
    let mut t = s.clone();
    t.apply(Remap::keep_faces(&s, &keep)).expect("apply");
    for surface in [&s, &t] {
        let mesh = surface.mesh().expect("mesh");
        let want: Vec<bool> = mesh.vertices().map(|v| mesh.is_boundary_vertex(v)).collect();
        assert_eq!(surface.boundary_vertices(), want);
    }
    assert!(
        t.boundary_vertices().iter().filter(|b| **b).count() > s.boundary_vertices().iter().filter(|b| **b).count()
    );
}

/// Reading a field never written, or a name under another type, is a typed error naming the field.
#[test]
fn a_field_is_read_by_its_name_and_type() {
    let mut s = grid(2);
    let e = s.vertex(HEIGHT).expect_err("never written");
    assert!(matches!(&e, OptimError::Field { name, .. } if name == "test.height"), "{e:?}");
    s.vertex_mut(HEIGHT).expect("created");
    const SAME_NAME: VertexField<bool> = VertexField::new("test.height", false);
    let e = s.vertex_mut(SAME_NAME).expect_err("another type");
    assert!(e.to_string().contains("another type than bool"), "{e}");
}

/// A surface goes through JSON exactly (the checkpoint's format), fields included.
#[test]
fn a_surface_round_trips_exactly() {
    let mut s = with_fields(grid(3));
    s.vertex_mut(crate::reconstruct::SHAPE_MOMENTS).expect("new")[1] =
        Moments { m: DVec3::new(0.1, 1e-17, -3.3), v: 1e-9 };
    let mut p = s.positions().to_vec();
    p[0] = Vec3::new(0.1, 0.2 + 1e-7, 0.3);
    s.set_positions(p).expect("same count");
    let back: Surface = serde_json::from_str(&serde_json::to_string(&s).expect("json")).expect("parse");
    assert_eq!(back, s);
    let mut broken = serde_json::to_value(&s).expect("json");
    broken["triangles"][0][0] = serde_json::json!(10_000);
    let broken: Surface = serde_json::from_value(broken).expect("parse");
    assert!(broken.validate().is_err());
}
