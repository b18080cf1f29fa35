//! A Z-NLOS capture as NeTF preprocessed it (`.mat`, wall y = 0, scene at y < 0), written here for a
//! fronto-parallel plane at a known depth, reads back as a confocal grid capture in our axes whose LCT puts
//! the plane at that depth (within one bin).

use nlos_testdata::mat5;

use mat5::{Options, double, write};
use nlos_init::{LctParams, lct};
use nlos_transient::{Layout, formats::Format};

/// A NeTF file of a plane at `depth` (their frame: the plane y = −depth facing the wall y = 0), an A × B wall
/// grid over ±0.3 m, T bins of `delta` metres of **distance from the wall** (NeTF's `r = i·deltaT`); the
/// histograms by a small point-sample renderer (cos⁴/r⁴ weights of a 121 × 121 grid of plane points).
/// `data(:, ia, ib)` is the point of position column `ia·B + ib`, as NeTF flattens its grid.
fn netf_plane(depth: f64, a: usize, b: usize, bins: usize, delta: f64) -> Vec<u8> {
    let lin = |i: usize, n: usize, w: f64| -w + 2.0 * w * i as f64 / (n - 1) as f64;
    // Position column q = ia·B + ib: theirs (x, 0, z) = (lin(ia), 0, lin(ib)).
    let wall: Vec<[f64; 3]> = (0..a * b).map(|q| [lin(q / b, a, 0.3), 0.0, lin(q % b, b, 0.3)]).collect();
    let mut data = vec![0.0f64; bins * a * b];
    for (q, w) in wall.iter().enumerate() {
        // data(:, ia, ib) is stored (column-major) at ia + A·ib.
        let p = q / b + a * (q % b);
        for j in 0..121 {
            for i in 0..121 {
                let x = [lin(i, 121, 0.25), -depth, lin(j, 121, 0.25)];
                let d = [x[0] - w[0], x[1] - w[1], x[2] - w[2]];
                let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let k = (r / delta) as usize;
                if k < bins {
                    data[k + bins * p] += (depth / r).powi(4) / r.powi(4);
                }
            }
        }
    }
    let positions: Vec<f64> = wall.iter().flat_map(|w| w.iter().copied()).collect();
    let vars = vec![
        double("data", &[bins as i32, a as i32, b as i32], data),
        double("cameraGridPositions", &[3, (a * b) as i32], positions),
        double("cameraGridSize", &[1, 2], vec![0.6, 0.6]),
        double("cameraGridPoints", &[1, 2], vec![a as f64, b as f64]),
        double("cameraPosition", &[3, 1], vec![0.0, 1.0, 0.0]),
        double("deltaT", &[1, 1], vec![delta]),
        double("hiddenVolumePosition", &[3, 1], vec![0.0, -depth, 0.0]),
        double("hiddenVolumeSize", &[1, 1], vec![0.6]),
    ];
    write(&vars, Options { compress: true, big_endian: false })
}

#[test]
fn a_netf_plane_reads_as_a_confocal_grid_at_its_depth() {
    let (depth, delta) = (0.5, 0.002);
    let dir = std::env::temp_dir().join(format!("nlos-znlos-mat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let file = dir.join("plane.mat");
    std::fs::write(&file, netf_plane(depth, 24, 20, 512, delta)).expect("write");
    assert_eq!(nlos_transient::detect(&file).expect("detect"), Format::ZNlosMat);
    let t = nlos_transient::read(&file).expect("read");
    assert!(t.scan().is_confocal());
    assert_eq!(t.scan().lasers().layout, Layout::Grid { nx: 24, ny: 20 });
    assert!(!t.time().includes_device_legs, "returns begin where the hidden volume allows");
    let p = &t.scan().lasers().points;
    // Their (x, 0, z) is our (x, z, 0); x fastest.
    assert!((p[0].x + 0.3).abs() < 1e-6 && (p[0].y + 0.3).abs() < 1e-6 && p[0].z == 0.0, "{}", p[0]);
    assert!((p[23].x - 0.3).abs() < 1e-6 && (p[24 * 19].y - 0.3).abs() < 1e-6);
    let v = lct(&t, &LctParams::default()).expect("lct");
    // The brightest depth of the centre column.
    let (cx, cy) = (v.nx / 2, v.ny / 2);
    let col = &v.data[(cx + v.nx * cy) * v.nz..(cx + v.nx * cy + 1) * v.nz];
    let iz = (0..v.nz).max_by(|&i, &j| col[i].total_cmp(&col[j])).expect("voxels");
    let z = v.z.at(iz);
    eprintln!("LCT depth {z:.4} m (plane at {depth} m, bin {delta:.4} m of depth)");
    assert!((z - depth).abs() <= delta + 1e-9, "plane at {z} m, expected {depth} ± one bin");
    let _ = std::fs::remove_dir_all(&dir);
}
