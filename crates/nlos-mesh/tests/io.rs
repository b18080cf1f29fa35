//! OBJ/PLY/GLB round trips and malformed-file errors.

use glam::Vec3;
use nlos_mesh::io::{self, PlyEncoding, PlyVertexFields, TriangleSoup};
use nlos_mesh::{BuildOptions, MeshError, SurfaceMesh, shapes};

/// A mesh with awkward floats (tiny, huge, negative zero, many digits) to test exactness.
fn awkward() -> SurfaceMesh {
    let mut m = shapes::icosphere(Vec3::new(0.1, -0.2, 0.3), 0.7, 2);
    let n = m.vertices_size();
    for (i, p) in m.positions_mut().iter_mut().enumerate() {
        *p *= 1.0 + (i as f32) * 1e-7;
    }
    m.positions_mut()[0] = Vec3::new(-0.0, 1e-30, 3.402_823e38);
    m.positions_mut()[n - 1] = Vec3::new(1.0 / 3.0, -2.0 / 7.0, 0.123_456_79);
    m
}

fn assert_same(m: &SurfaceMesh, soup: &TriangleSoup) {
    let (p, t) = m.to_triangles();
    assert_eq!(p.len(), soup.positions.len());
    for (a, b) in p.iter().zip(&soup.positions) {
        assert_eq!(a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits));
    }
    assert_eq!(t, soup.triangles);
}

#[test]
fn obj_round_trip_is_exact() {
    let m = awkward();
    let bytes = io::write_obj(&m);
    let soup = io::read_obj(&bytes, "mem.obj").expect("parses");
    assert_same(&m, &soup);
    soup.into_mesh(BuildOptions::default()).expect("manifold").validate().expect("valid");
}

#[test]
fn ply_round_trips_are_exact() {
    let m = awkward();
    for enc in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian] {
        let bytes = io::write_ply(&m, enc);
        let soup = io::read_ply(&bytes, "mem.ply").expect("parses");
        assert_same(&m, &soup);
        assert_same(&m, &io::read_any(&bytes, "mem.ply").expect("detected"));
    }
}

#[test]
fn ply_support_round_trips_beside_the_albedo_and_values_outside_its_range_are_errors() {
    let m = awkward();
    let n = m.to_triangles().0.len();
    let albedo: Vec<f32> = (0..n).map(|i| (i % 5) as f32 * 0.5).collect();
    let support: Vec<f32> = (0..n).map(|i| (i % 9) as f32 / 4.0 - 1.0).collect();
    for enc in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian] {
        for albedo in [None, Some(&albedo[..])] {
            let fields = PlyVertexFields { albedo, support: Some(&support) };
            let bytes = io::write_ply_with(&m, &fields, enc).expect("one value per vertex");
            let soup = io::read_ply(&bytes, "mem.ply").expect("parses");
            assert_same(&m, &soup);
            assert_eq!(soup.support.as_deref(), Some(&support[..]));
            assert_eq!(soup.albedo.as_deref(), albedo);
        }
    }
    let mut bad = support.clone();
    bad[1] = 1.5;
    let e = io::write_ply_with(&m, &PlyVertexFields { albedo: None, support: Some(&bad) }, PlyEncoding::Ascii)
        .expect_err("out of range");
    assert!(e.to_string().contains("support"), "{e}");
    assert_eq!(io::read_ply(&io::write_ply(&m, PlyEncoding::Ascii), "mem.ply").expect("parses").support, None);
}

#[test]
fn ply_albedo_round_trips_with_grey_colours_and_bad_values_are_errors() {
    let m = awkward();
    let n = m.to_triangles().0.len();
    let albedo: Vec<f32> = (0..n).map(|i| (i % 7) as f32 * 0.25).collect();
    for enc in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian] {
        let bytes = io::write_ply_with_albedo(&m, &albedo, enc).expect("one value per vertex");
        let header = String::from_utf8_lossy(&bytes[..300]).into_owned();
        assert!(header.contains("property float albedo\nproperty uchar red"), "{header}");
        let soup = io::read_ply(&bytes, "mem.ply").expect("parses");
        assert_same(&m, &soup);
        assert_eq!(soup.albedo.as_deref(), Some(&albedo[..]));
    }
    assert_eq!(io::read_ply(&io::write_ply(&m, PlyEncoding::Ascii), "mem.ply").expect("parses").albedo, None);
    assert!(io::write_ply_with_albedo(&m, &albedo[1..], PlyEncoding::Ascii).is_err());
    let mut bad = albedo.clone();
    bad[2] = f32::NAN;
    assert!(io::write_ply_with_albedo(&m, &bad, PlyEncoding::Ascii).is_err());
    // A file whose albedo is negative is refused, naming the vertex.
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                property float albedo\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
                0 0 1 0.5\n1 0 1 -1\n0 1 1 0.5\n3 0 1 2\n";
    let e = io::read_ply(text.as_bytes(), "neg.ply").expect_err("negative albedo");
    assert!(e.to_string().contains("vertex 1 albedo"), "{e}");
}

#[test]
fn glb_round_trip_and_gltf_crate_accepts_it() {
    let m = awkward();
    let bytes = io::write_glb(&m);
    assert_eq!(bytes.len() % 4, 0);
    let soup = io::read_glb(&bytes, "mem.glb").expect("parses");
    assert_same(&m, &soup);
    // independent check with the gltf crate
    let g = gltf::Gltf::from_slice(&bytes).expect("valid GLB for gltf");
    let blob = g.blob.clone().expect("BIN chunk");
    let mesh = g.meshes().next().expect("one mesh");
    let prim = mesh.primitives().next().expect("one primitive");
    assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
    let reader = prim.reader(|_| Some(&blob));
    let pos: Vec<[f32; 3]> = reader.read_positions().expect("positions").collect();
    let idx: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
    let (p, t) = m.to_triangles();
    assert_eq!(pos, p.iter().map(|v| v.to_array()).collect::<Vec<_>>());
    assert_eq!(idx, t.iter().flatten().copied().collect::<Vec<_>>());
}

#[test]
fn save_and_load_files() {
    let m = shapes::open_cone(1.0, 1.0, 12, 3);
    let dir = std::env::temp_dir().join(format!("nlos-mesh-io-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    for ext in ["obj", "ply", "glb"] {
        let path = dir.join(format!("cone.{ext}"));
        io::save(&m, &path).expect("saved");
        let back = io::load(&path).expect("loaded");
        back.validate().expect("valid");
        assert_eq!(back.to_triangles(), m.to_triangles());
    }
    assert!(matches!(io::save(&m, dir.join("cone.stl")), Err(MeshError::Format { .. })));
    assert!(matches!(io::load(dir.join("missing.obj")), Err(MeshError::Io { .. })));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ply_polygons_other_elements_and_big_endian() {
    let ascii = b"ply\nformat ascii 1.0\ncomment quad\nelement vertex 4\nproperty double x\nproperty double y\n\
property double z\nproperty uchar red\nelement face 1\nproperty uchar flags\nproperty list uchar uint vertex_indices\n\
element edge 1\nproperty int a\nproperty int b\nend_header\n0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n7 4 0 1 2 3\n0 1\n";
    let s = io::read_ply(ascii, "quad.ply").expect("parses");
    assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(s.positions[2], Vec3::new(1.0, 1.0, 0.0));
    let mut be = b"ply\r\nformat binary_big_endian 1.0\r\nelement vertex 3\r\nproperty float x\r\nproperty float y\r\n\
property float z\r\nelement face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n"
        .to_vec();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        be.extend_from_slice(&v.to_be_bytes());
    }
    be.push(3);
    for i in [0i32, 1, 2] {
        be.extend_from_slice(&i.to_be_bytes());
    }
    let s = io::read_ply(&be, "be.ply").expect("parses");
    assert_eq!(s.triangles, vec![[0, 1, 2]]);
    assert_eq!(s.positions[1], Vec3::X);
}

fn expect_format_error(r: Result<TriangleSoup, MeshError>, needle: &str) {
    match r {
        Err(e @ MeshError::Format { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains(needle), "message {msg:?} should mention {needle:?}");
        }
        other => panic!("expected a format error mentioning {needle:?}, got {other:?}"),
    }
}

#[test]
fn malformed_ply_gives_typed_errors() {
    let good = io::write_ply(&shapes::plane_grid(1.0, 1.0, 2, 2), PlyEncoding::BinaryLittleEndian);
    // every truncation is an error, never a panic
    for cut in 0..good.len() {
        assert!(io::read_ply(&good[..cut], "cut.ply").is_err(), "truncated at {cut} parsed");
    }
    expect_format_error(
        io::read_ply(
            b"ply\nformat ascii 1.0\nelement vertex 99999999999\nproperty float x\n\
property float y\nproperty float z\nend_header\n1 2 3\n",
            "huge.ply",
        ),
        "count",
    );
    expect_format_error(io::read_ply(b"ply\nformat ascii 2.0\nend_header\n", "v.ply"), "version");
    expect_format_error(
        io::read_ply(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n", "xy.ply"),
        "x, y and z",
    );
    expect_format_error(
        io::read_ply(
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
            "idx.ply",
        ),
        "out of range",
    );
    expect_format_error(
        io::read_ply(
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nend_header\nnan 0 0\n",
            "nan.ply",
        ),
        "non-finite",
    );
    expect_format_error(
        io::read_ply(
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nend_header\n0 zero 0\n",
            "word.ply",
        ),
        "not a number",
    );
    expect_format_error(
        io::read_ply(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty list float int x\nend_header\n", "list.ply"),
        "integer",
    );
    expect_format_error(io::read_ply(b"plyformat", "nohead.ply"), "end_header");
    // deterministic byte flips never panic
    let mut rng = nlos_transient::rng::SplitMix64::new(0x9E37_79B9_7F4A_7C15);
    for _ in 0..2000 {
        let mut b = good.clone();
        for _ in 0..4 {
            let bits = rng.next_u64();
            let i = (bits >> 33) as usize % b.len();
            b[i] = (bits >> 17) as u8;
        }
        let _ = io::read_ply(&b, "fuzz.ply");
    }
}

#[test]
fn malformed_obj_and_glb_give_typed_errors() {
    expect_format_error(io::read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "bad.obj"), "line 4");
    expect_format_error(io::read_obj(b"v 0 0 zz\nf 1 1 1\n", "bad.obj"), "not a number");
    expect_format_error(io::read_obj(b"v 0 0\n", "bad.obj"), "three coordinates");
    expect_format_error(io::read_obj(b"v 0 0 0\nv 1 0 0\nf 1 2\n", "bad.obj"), "at least 3");
    expect_format_error(io::read_obj(b"v 0 0 0\nf 0 1 1\n", "bad.obj"), "out of range");
    let rel = io::read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf -3/1/1 -2//1 -1\n", "rel.obj").expect("ok");
    assert_eq!(rel.triangles, vec![[0, 1, 2]]);
    let good = io::write_glb(&shapes::plane_grid(1.0, 1.0, 2, 2));
    for cut in 0..good.len() {
        assert!(io::read_glb(&good[..cut], "cut.glb").is_err(), "truncated at {cut} parsed");
    }
    expect_format_error(io::read_glb(b"glTF\x01\0\0\0", "v1.glb"), "glTF 2.0");
    // a non-manifold OBJ reads fine as a soup and fails at construction with a typed error
    let fin = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n";
    let soup = io::read_obj(fin, "fin.obj").expect("soup");
    assert!(matches!(soup.into_mesh(BuildOptions::default()), Err(MeshError::NonManifoldEdge { .. })));
}

#[test]
fn obj_groups_are_welded() {
    let two = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ng a\nf 1 2 3\ng b\nf 2 4 3\n";
    let soup = io::read_obj(two, "groups.obj").expect("parses");
    assert_eq!(soup.positions.len(), 4);
    let m = soup.into_mesh(BuildOptions::default()).expect("one connected quad");
    assert_eq!(m.connected_components().1, 1);
}

#[test]
fn loads_the_shared_bunny() {
    let Some(path) = nlos_testdata::shared("meshes/bunny_centered.obj") else { return };
    let m = io::load(path).expect("bunny loads");
    m.validate().expect("valid");
    assert_eq!(m.n_faces(), 69_630);
    assert_eq!(m.n_vertices(), 34_817);
    assert!(m.boundary_loops().is_empty());
    let bytes = io::write_obj(&m);
    let back = io::read_obj(&bytes, "bunny.obj").expect("re-reads");
    assert_eq!((back.positions, back.triangles), m.to_triangles());
}
