//! Where a reconstruction's depth error comes from: `cargo run --release -p nlos-mesh --example
//! depth_errors -- REC.obj GT.obj [more REC.obj …]`.
//!
//! For each reconstruction, on `nlos eval`'s 128 × 128 ray grid: the mean depth error split by the
//! pixel's distance (in pixels) to the ground truth's silhouette, the share of the mean that pixels with an
//! error above 5 / 20 mm carry, and how many of those lie in front of or behind the truth. Prints an ASCII
//! map of the error (` ` miss, `.` < 1 mm, `-` < 5 mm, `o` < 20 mm, `#` ≥ 20 mm; `x` ground truth only,
//! `+` reconstruction only). With the environment variable `DUMP` set, also lists every pixel with an error
//! above 20 mm (pixel, both depths, distance to the silhouette) and splits the missed ground-truth pixels
//! at y = 0.09 m (above it: the bunny's ears). With `WINDOW=ix,iy` set, also prints both depth maps (mm,
//! `truth/reconstruction`) over the 11 × 9 pixels around pixel `(ix, iy)`.
//!
//! The interior line is the judged metric's (`nlos eval`'s `depth_error_mean_interior`: pixels at least
//! 3 px inside the truth's silhouette), with the share of it that its pixels above 2 mm and 10 mm carry.
#![allow(missing_docs)]

use nlos_mesh::metrics::{EvalParams, SILHOUETTE_BAND, depth_map, interior_mask};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: depth_errors REC.obj GT.obj [REC.obj …]");
        std::process::exit(2);
    }
    let params = EvalParams::default();
    let n = params.grid;
    let load = |p: &str| match nlos_mesh::io::load(p) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("{p}: {e}");
            std::process::exit(1);
        }
    };
    let gt = depth_map(&load(&args[1]), &params).expect("ground-truth depth map");
    // The judged interior, as `nlos eval` takes it.
    let interior = interior_mask(&gt, n, SILHOUETTE_BAND);
    // Distance (in pixels, chessboard) of every ground-truth pixel to the nearest pixel the truth misses.
    let mut dist = vec![u32::MAX; n * n];
    for (i, d) in dist.iter_mut().enumerate() {
        if gt[i].is_nan() {
            *d = 0;
        }
    }
    for _ in 0..n {
        let mut changed = false;
        for iy in 0..n {
            for ix in 0..n {
                let i = ix + n * iy;
                if dist[i] == 0 {
                    continue;
                }
                let mut best = dist[i];
                for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1), (-1, -1), (1, 1), (-1, 1), (1, -1)] {
                    let (x, y) = (ix as i64 + dx, iy as i64 + dy);
                    let nb = if x < 0 || y < 0 || x >= n as i64 || y >= n as i64 {
                        0
                    } else {
                        dist[x as usize + n * y as usize]
                    };
                    best = best.min(nb.saturating_add(1));
                }
                if best < dist[i] {
                    dist[i] = best;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    for rec_path in &args[0..1].iter().chain(&args[2..]).cloned().collect::<Vec<_>>() {
        let rec = depth_map(&load(rec_path), &params).expect("depth map");
        if let Some((wx, wy)) = std::env::var("WINDOW").ok().and_then(|w| {
            let (x, y) = w.split_once(',')?;
            Some((x.trim().parse::<usize>().ok()?, y.trim().parse::<usize>().ok()?))
        }) {
            for iy in (wy.saturating_sub(4)..=(wy + 4).min(n - 1)).rev() {
                let mut line = format!("y {iy:3}:");
                for ix in wx.saturating_sub(5)..=(wx + 5).min(n - 1) {
                    let i = ix + n * iy;
                    line += &format!(" {:>4.0}/{:<4.0}", gt[i] * 1e3, rec[i] * 1e3);
                }
                println!("{line}");
            }
        }
        let (mut both, mut sum) = (0usize, 0.0f64);
        let mut rings = [(0usize, 0.0f64); 5];
        let (mut big5, mut big20, mut front, mut behind) = (0.0f64, 0.0f64, 0usize, 0usize);
        let mut interior_signed: Vec<f32> = Vec::new();
        // The judged interior: count, error sum, and the sums of its errors > 2 / 10 mm.
        let (mut inner, mut inner_sum, mut inner2, mut inner10, mut inner2_count) = (0usize, 0.0f64, 0.0f64, 0.0f64, 0);
        let mut map = String::new();
        for iy in (0..n).rev().step_by(2) {
            for ix in (0..n).step_by(2) {
                let i = ix + n * iy;
                let c = match (gt[i].is_nan(), rec[i].is_nan()) {
                    (true, true) => ' ',
                    (false, true) => 'x',
                    (true, false) => '+',
                    (false, false) => {
                        let e = (rec[i] - gt[i]).abs();
                        if e < 1e-3 {
                            '.'
                        } else if e < 5e-3 {
                            '-'
                        } else if e < 2e-2 {
                            'o'
                        } else {
                            '#'
                        }
                    }
                };
                map.push(c);
            }
            map.push('\n');
        }
        if std::env::var_os("DUMP").is_some() {
            let (mut miss_hi, mut miss_lo) = (0, 0);
            for i in 0..n * n {
                if !gt[i].is_nan() && rec[i].is_nan() {
                    if params.pixel_center(i % n, i / n).1 > 0.09 { miss_hi += 1 } else { miss_lo += 1 }
                }
            }
            println!("missed: {miss_hi} above y = 0.09 m, {miss_lo} below");
        }
        for i in 0..n * n {
            if gt[i].is_nan() || rec[i].is_nan() {
                continue;
            }
            let e = f64::from((rec[i] - gt[i]).abs());
            both += 1;
            sum += e;
            let ring = (dist[i] as usize).saturating_sub(1).min(4);
            rings[ring].0 += 1;
            rings[ring].1 += e;
            if ring == 4 {
                interior_signed.push(rec[i] - gt[i]);
            }
            if interior[i] {
                inner += 1;
                inner_sum += e;
                if e > 2e-3 {
                    inner2 += e;
                    inner2_count += 1;
                }
                if e > 1e-2 {
                    inner10 += e;
                }
            }
            if e > 5e-3 {
                big5 += e;
                if rec[i] < gt[i] { front += 1 } else { behind += 1 }
            }
            if e > 2e-2 {
                big20 += e;
                if std::env::var_os("DUMP").is_some() {
                    println!("big {} {} rec {:.1} gt {:.1} ring {}", i % n, i / n, rec[i] * 1e3, gt[i] * 1e3, dist[i]);
                }
            }
        }
        let mean = sum / both.max(1) as f64;
        println!("{rec_path}: {both} pixels on both, mean depth error {:.2} mm", mean * 1e3);
        for (k, (c, s)) in rings.iter().enumerate() {
            let label = if k == 4 { "≥ 5".to_string() } else { format!("{}", k + 1) };
            println!(
                "  {label:>3} px from the silhouette: {c:5} pixels, mean {:6.2} mm, share of the total error {:5.1} %",
                s / (*c).max(1) as f64 * 1e3,
                100.0 * s / sum.max(1e-30)
            );
        }
        println!(
            "  errors > 5 mm carry {:.1} % of the total ({front} in front of the truth, {behind} behind); > 20 mm {:.1} %",
            100.0 * big5 / sum.max(1e-30),
            100.0 * big20 / sum.max(1e-30)
        );
        println!(
            "  interior (the judged metric's pixels): {inner} pixels, mean {:.3} mm; the {inner2_count} above 2 mm carry \
             {:.1} % of it, those above 10 mm {:.1} % (without the pixels above 2 mm: {:.3} mm)",
            inner_sum / inner.max(1) as f64 * 1e3,
            100.0 * inner2 / inner_sum.max(1e-30),
            100.0 * inner10 / inner_sum.max(1e-30),
            (inner_sum - inner2) / (inner - inner2_count).max(1) as f64 * 1e3
        );
        interior_signed.sort_by(f32::total_cmp);
        let q = |f: f64| interior_signed.get((f * interior_signed.len() as f64) as usize).copied().unwrap_or(f32::NAN);
        println!(
            "  interior (≥ 5 px in), signed z_rec − z_gt: quartiles {:+.2} / {:+.2} / {:+.2} mm (negative: in front)",
            q(0.25) * 1e3,
            q(0.5) * 1e3,
            q(0.75) * 1e3
        );
        println!("{map}");
    }
}
