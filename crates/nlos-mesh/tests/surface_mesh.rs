//! Half-edge invariants under randomized operation sequences, construction errors, garbage collection.

use glam::Vec3;
use nlos_mesh::{BuildOptions, EdgeId, MeshError, SurfaceMesh, VertexId, orient_triangles, shapes};

/// The workspace's SplitMix64 (`nlos_transient::rng`).
type Rng = nlos_transient::rng::SplitMix64;

fn euler(m: &SurfaceMesh) -> i64 {
    m.n_vertices() as i64 - m.n_edges() as i64 + m.n_faces() as i64
}

fn random_live_edge(m: &SurfaceMesh, rng: &mut Rng) -> EdgeId {
    loop {
        let e = EdgeId::new(rng.below(m.edges_size()));
        if !m.is_deleted_edge(e) {
            return e;
        }
    }
}

/// Runs `steps` random split/collapse/flip operations, validating after each; returns counts.
fn random_ops(mut m: SurfaceMesh, steps: usize, seed: u64, min_faces: usize) -> (SurfaceMesh, [usize; 3]) {
    let chi = euler(&m);
    let loops = m.boundary_loops().len();
    let mut rng = Rng::new(seed);
    let mut done = [0usize; 3];
    for step in 0..steps {
        let e = random_live_edge(&m, &mut rng);
        let op = rng.below(3);
        match op {
            0 => {
                let [a, b] = m.edge_vertices(e);
                let p = (m.position(a) + m.position(b)) * 0.5;
                let nv = m.split_edge(e, p);
                assert!(!m.is_deleted_vertex(nv));
                done[0] += 1;
            }
            1 if m.n_faces() > min_faces => {
                let h = e.halfedge(rng.below(2) as u32);
                if m.is_collapse_ok(h) {
                    let keep = m.to_vertex(h);
                    let gone = m.from_vertex(h);
                    m.collapse(h);
                    assert!(m.is_deleted_vertex(gone) && !m.is_deleted_vertex(keep));
                    assert!(m.is_deleted_edge(e));
                    done[1] += 1;
                }
            }
            _ => {
                if m.is_flip_ok(e) {
                    m.flip(e);
                    done[2] += 1;
                }
            }
        }
        if let Err(err) = m.validate() {
            panic!("step {step} (op {op}) broke the mesh: {err}");
        }
        assert_eq!(euler(&m), chi, "Euler characteristic changed at step {step}");
        assert_eq!(m.boundary_loops().len(), loops, "boundary loop count changed at step {step}");
        if step % 500 == 499 {
            m.garbage_collect();
            m.validate().expect("valid after garbage collection");
        }
    }
    (m, done)
}

#[test]
fn icosphere_counts_and_closed() {
    for n in 0..4 {
        let m = shapes::icosphere(Vec3::ZERO, 2.0, n);
        m.validate().expect("valid");
        assert_eq!(m.n_faces(), 20 * 4usize.pow(n));
        assert_eq!(m.n_vertices(), 10 * 4usize.pow(n) + 2);
        assert_eq!(euler(&m), 2);
        assert!(m.boundary_loops().is_empty());
        for v in m.vertices() {
            assert!((m.position(v).length() - 2.0).abs() < 1e-5);
            // outward orientation
            assert!(m.vertex_normal(v).dot(m.position(v)) > 0.0);
        }
    }
}

#[test]
fn grid_and_cone_have_one_boundary_loop() {
    let g = shapes::plane_grid(2.0, 1.0, 8, 4);
    g.validate().expect("valid");
    assert_eq!(g.n_faces(), 64);
    assert_eq!(euler(&g), 1);
    let loops = g.boundary_loops();
    assert_eq!(loops.len(), 1);
    assert_eq!(loops[0].len(), 2 * (8 + 4));
    assert!((g.surface_area() - 2.0).abs() < 1e-6);
    for f in g.faces() {
        assert!((g.face_normal(f) - Vec3::Z).length() < 1e-6);
    }
    let c = shapes::open_cone(1.0, 2.0, 16, 4);
    c.validate().expect("valid");
    assert_eq!(euler(&c), 1);
    assert_eq!(c.boundary_loops().len(), 1);
    assert_eq!(c.boundary_loops()[0].len(), 16);
    for f in c.faces() {
        let n = c.face_normal(f);
        let p = c.face_centroid(f);
        assert!(n.dot(Vec3::new(p.x, p.y, 0.0)) > 0.0, "cone normals point outward");
    }
    let h = shapes::height_field(1.0, 1.0, 5, 5, |x, y| x * y).expect("finite");
    assert!((h.position(VertexId(35)).z - 1.0).abs() < 1e-6);
    assert!(matches!(shapes::height_field(1.0, 1.0, 2, 2, |_, _| f32::NAN), Err(MeshError::NonFinitePosition { .. })));
}

#[test]
fn random_operations_on_icosphere_keep_invariants() {
    let m = shapes::icosphere(Vec3::ZERO, 1.0, 2);
    let (m, done) = random_ops(m, 4000, 0x1234_5678_9abc_def1, 40);
    assert!(done.iter().all(|&d| d > 200), "each operation ran often: {done:?}");
    assert!(m.boundary_loops().is_empty());
}

#[test]
fn random_operations_on_open_grid_keep_invariants() {
    let m = shapes::plane_grid(1.0, 1.0, 10, 10);
    let (m, done) = random_ops(m, 4000, 0x0dd_ba11_cafe_f00d, 30);
    assert!(done.iter().all(|&d| d > 200), "each operation ran often: {done:?}");
    assert_eq!(m.boundary_loops().len(), 1);
}

#[test]
fn random_collapses_down_to_minimal_meshes() {
    // Collapse as long as anything is collapsible: the link condition must stop before breaking topology.
    for (m, chi) in [(shapes::icosphere(Vec3::ZERO, 1.0, 1), 2), (shapes::plane_grid(1.0, 1.0, 4, 4), 1)] {
        let mut m = m;
        let mut rng = Rng::new(99);
        for _ in 0..20_000 {
            let e = random_live_edge(&m, &mut rng);
            let h = e.halfedge(rng.below(2) as u32);
            if m.is_collapse_ok(h) {
                m.collapse(h);
                m.validate().expect("valid after collapse");
                assert_eq!(euler(&m), chi);
            }
        }
        assert!(m.n_faces() <= 8, "collapsed down to {} faces", m.n_faces());
    }
}

#[test]
fn boundary_split_and_collapse() {
    let mut m = shapes::plane_grid(1.0, 1.0, 2, 2);
    let e = m.edges().find(|&e| m.is_boundary_edge(e)).expect("boundary edge");
    let before = m.boundary_loops()[0].len();
    let v = m.split_edge(e, Vec3::new(0.5, 0.0, 0.0));
    m.validate().expect("valid");
    assert!(m.is_boundary_vertex(v));
    assert_eq!(m.valence(v), 3);
    assert_eq!(m.boundary_loops()[0].len(), before + 1);
    // collapse the new boundary vertex back along the boundary
    let h = m.vertex_halfedges(v).find(|&h| m.is_boundary_halfedge(h)).expect("boundary halfedge");
    assert!(m.is_collapse_ok(h));
    m.collapse(h);
    m.validate().expect("valid");
    assert_eq!(m.boundary_loops()[0].len(), before);
    // an interior edge joining two boundary vertices cannot collapse
    let mut quad =
        SurfaceMesh::from_triangles(&[Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y], &[[0, 1, 2], [0, 2, 3]])
            .expect("quad");
    let diag = quad.find_edge(VertexId(0), VertexId(2));
    assert!(!quad.is_collapse_ok(diag.halfedge(0)) && !quad.is_collapse_ok(diag.halfedge(1)));
    assert!(quad.is_flip_ok(diag));
    quad.flip(diag);
    quad.validate().expect("valid");
    assert!(quad.find_edge(VertexId(1), VertexId(3)).is_valid());
    assert!(!quad.find_edge(VertexId(0), VertexId(2)).is_valid());
    // boundary edges cannot flip
    let b = quad.find_edge(VertexId(0), VertexId(1));
    assert!(!quad.is_flip_ok(b));
}

#[test]
fn tetrahedron_flip_is_refused() {
    let m = SurfaceMesh::from_triangles(
        &[Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
        &[[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
    )
    .expect("tetrahedron");
    m.validate().expect("valid");
    for e in m.edges() {
        assert!(!m.is_flip_ok(e), "flipping a tetrahedron edge would duplicate an edge");
    }
}

#[test]
fn garbage_collection_preserves_geometry_and_topology() {
    let mut m = shapes::icosphere(Vec3::ZERO, 1.0, 2);
    let mut rng = Rng::new(7);
    for _ in 0..150 {
        let e = random_live_edge(&m, &mut rng);
        if m.is_collapse_ok(e.halfedge(0)) {
            m.collapse(e.halfedge(0));
        }
    }
    assert!(m.has_garbage());
    let (pos_before, tris_before) = m.to_triangles();
    let edges_before: Vec<[Vec3; 2]> = m.edges().map(|e| m.edge_vertices(e).map(|v| m.position(v))).collect();
    let old = m.clone();
    let remap = m.garbage_collect();
    m.validate().expect("valid after gc");
    assert!(!m.has_garbage());
    let (pos_after, tris_after) = m.to_triangles();
    assert_eq!(pos_before, pos_after);
    assert_eq!(tris_before, tris_after);
    assert_eq!(m.positions(), pos_after.as_slice());
    let edges_after: Vec<[Vec3; 2]> = m.edges().map(|e| m.edge_vertices(e).map(|v| m.position(v))).collect();
    assert_eq!(edges_before, edges_after);
    // the remap sends every live old element to its new index
    for v in old.vertices() {
        assert_eq!(old.position(v), m.position(remap.vertices[v.idx()]));
    }
    for f in old.faces() {
        let nf = remap.faces[f.idx()];
        assert_eq!(old.face_points(f), m.face_points(nf));
    }
    for h in old.halfedges() {
        let nh = remap.halfedge(h);
        assert_eq!(old.position(old.to_vertex(h)), m.position(m.to_vertex(nh)));
    }
    for v in 0..old.vertices_size() {
        assert_eq!(old.is_deleted_vertex(VertexId::new(v)), !remap.vertices[v].is_valid());
    }
    assert_eq!(euler(&m), 2);
}

#[test]
fn construction_errors_are_typed() {
    let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(-1.0, 0.0, 0.0), Vec3::new(0.0, -1.0, 0.0), Vec3::Z];
    // bow tie: two triangles sharing only vertex 0
    let bow = [[0, 1, 2], [0, 3, 4]];
    match SurfaceMesh::from_triangles(&p[..5], &bow) {
        Err(MeshError::NonManifoldVertex { vertex: 0, fans: 2 }) => {}
        other => panic!("expected NonManifoldVertex, got {other:?}"),
    }
    let fixed = SurfaceMesh::from_triangles_with(&p[..5], &bow, BuildOptions { split_non_manifold_vertices: true })
        .expect("repaired");
    fixed.validate().expect("valid");
    assert_eq!(fixed.n_vertices(), 6);
    assert_eq!(fixed.position(VertexId(5)), Vec3::ZERO);
    assert_eq!(fixed.connected_components().1, 2);
    // three triangles on edge (0, 1)
    let fin = [[0, 1, 2], [1, 0, 4], [0, 1, 5]];
    assert!(matches!(SurfaceMesh::from_triangles(&p, &fin), Err(MeshError::NonManifoldEdge { .. })));
    // inconsistent orientation, then fixed by orient_triangles
    let mut bad = [[0, 1, 2], [0, 1, 4]];
    assert!(matches!(SurfaceMesh::from_triangles(&p, &bad), Err(MeshError::InconsistentOrientation { .. })));
    assert_eq!(orient_triangles(p.len(), &mut bad).expect("in range"), 1);
    SurfaceMesh::from_triangles(&p, &bad).expect("oriented").validate().expect("valid");
    // indices, degenerate faces, NaN
    assert!(matches!(SurfaceMesh::from_triangles(&p, &[[0, 1, 9]]), Err(MeshError::IndexOutOfRange { .. })));
    assert!(matches!(SurfaceMesh::from_triangles(&p, &[[0, 1, 1]]), Err(MeshError::DegenerateFace { .. })));
    let nan = [Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)];
    assert!(matches!(SurfaceMesh::from_triangles(&nan, &[[0, 1, 2]]), Err(MeshError::NonFinitePosition { .. })));
    // messages name the fix
    let msg = SurfaceMesh::from_triangles(&p[..5], &bow).expect_err("bow tie").to_string();
    assert!(msg.contains("split_non_manifold_vertices"), "{msg}");
}

#[test]
fn orient_triangles_repairs_a_scrambled_sphere() {
    let m = shapes::icosphere(Vec3::ZERO, 1.0, 2);
    let (p, mut t) = m.to_triangles();
    for (i, tri) in t.iter_mut().enumerate() {
        if i % 3 == 1 {
            tri.swap(0, 1);
        }
    }
    let flipped = orient_triangles(p.len(), &mut t).expect("in range");
    assert!(flipped > 0);
    let m2 = SurfaceMesh::from_triangles(&p, &t).expect("consistent");
    m2.validate().expect("valid");
    // face 0 kept its orientation, so the whole sphere points outward again
    let f0 = m2.faces().next().expect("face");
    assert!(m2.face_normal(f0).dot(m2.face_centroid(f0)) > 0.0);
}

#[test]
fn components_and_largest_component() {
    let a = shapes::icosphere(Vec3::ZERO, 1.0, 2);
    let b = shapes::icosphere(Vec3::new(5.0, 0.0, 0.0), 1.0, 1);
    let (mut p, mut t) = a.to_triangles();
    let (pb, tb) = b.to_triangles();
    let off = p.len() as u32;
    p.extend(pb);
    t.extend(tb.iter().map(|x| x.map(|i| i + off)));
    p.push(Vec3::splat(9.0)); // an isolated vertex
    let mut m = SurfaceMesh::from_triangles(&p, &t).expect("two spheres");
    assert_eq!(m.connected_components().1, 3);
    let removed = m.keep_largest_component();
    assert_eq!(removed, 80);
    m.validate().expect("valid");
    m.garbage_collect();
    m.validate().expect("valid");
    assert_eq!(m.n_faces(), 320);
    assert_eq!(m.n_vertices(), 162);
}

#[test]
fn delete_face_and_vertex_keep_invariants() {
    let mut m = shapes::plane_grid(1.0, 1.0, 6, 6);
    // a corner face: deleting it deletes its boundary edges and the corner vertex
    let corner = VertexId(0);
    let f = m.vertex_faces(corner).next().expect("face");
    let nf = m.n_faces();
    m.delete_face(f);
    m.validate().expect("valid");
    assert_eq!(m.n_faces(), nf - 1);
    // an interior vertex whose one-ring is interior too: deleting it opens a hole
    let v = VertexId(24);
    assert!(m.vertex_vertices(v).all(|w| !m.is_boundary_vertex(w)));
    m.delete_vertex(v);
    m.validate().expect("valid");
    assert_eq!(m.boundary_loops().len(), 2);
    m.garbage_collect();
    m.validate().expect("valid");
    let mut s = shapes::icosphere(Vec3::ZERO, 1.0, 1);
    s.delete_vertex(VertexId(0));
    s.validate().expect("valid");
    assert_eq!(s.boundary_loops().len(), 1);
}
