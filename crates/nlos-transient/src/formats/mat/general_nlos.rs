//! The general-NLOS capture files (Hu et al., "Non-line-of-sight imaging with irregular relay surfaces" and
//! "Fast non-line-of-sight imaging with an arbitrary scanning setup"; code and data at
//! <https://github.com/hy520484/general-NLOS>): a **paired** scan on a curved relay surface, in two MAT v5
//! files side by side.
//!
//! - `data.mat`: `data`, `A × B × T` photon counts. Measurement `(i, j)` is the pair `(i, j)` of `setup.mat`.
//! - `setup.mat`: `laserpoints` and `detectpoints`, each `A × B × 3` (metres): measurement `(i, j)` lights the
//!   wall at `laserpoints(i, j, :)` and records at `detectpoints(i, j, :)`.
//! - Our measurement order is row-major in `(i, j)`: `m = i·B + j`, both point sets
//!   [`Layout::List`](crate::Layout::List) (the spots follow the curved wall, not a planar grid).
//! - Time: the bin width is **not stored** (the published experiment's configuration says 32 ps, 9.6 mm of
//!   path at `c = 3e8` m/s), so the reader needs it from the user ([`ReadOptions::bin_width`]). Their
//!   preprocessing shifts each histogram so that its first-bounce peak (the wall legs) sits at bin 0, and
//!   their back-projection kernel indexes bin `(|x − l| + |x − s|) / (c·Δ)`: path 0 lies at the centre of
//!   bin 0, so `t0 = −Δ/2` (our bin `k` holds `[t0 + kΔ, t0 + (k+1)Δ)`), times `l → x → s` only.
//! - Wall normals are not given. The spots' positions carry calibration noise: normals from neighbouring
//!   spots of the published capture tilt by 3° on average and up to 50° at outliers. The normal of every spot
//!   is therefore that of a cubic surface `z(x, y)` fitted by least squares through all spots of both sets
//!   (1.7 mm rms off the published capture's spots), oriented towards the hidden scene (`+z`).
//! - Either file may be given: `data.mat` finds `setup.mat` beside it, and `setup.mat` finds `data.mat`.

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};

use super::v5::MatFile;
use super::{dims3, invalid, wrong_shape};
use crate::error::{Result, TransientError};
use crate::formats::{ReadOptions, read_file, with_file};
use crate::scan::{PointSet, Scan};
use crate::time_axis::TimeAxis;
use crate::transient::Transient;

/// The file holding the geometry, beside the data.
pub const SETUP_FILE: &str = "setup.mat";
/// The file holding the histograms, beside the geometry.
pub const DATA_FILE: &str = "data.mat";

/// Whether the parsed MAT-file is the geometry half (`setup.mat`) of a general-NLOS capture.
pub(super) fn is_setup(m: &MatFile<'_>) -> bool {
    m.header("laserpoints").is_some() && m.header("detectpoints").is_some()
}

/// Reads a general-NLOS capture from either of its two files (`bytes` is the content of `file`).
///
/// # Errors
/// [`TransientError::MissingField`] when no bin width is given (naming the option); the companion file's
/// [`TransientError::Io`]; wrong shapes of `data`, `laserpoints`, `detectpoints` (naming the file and the
/// variable); non-finite values; spots off the relay surface ([`Scan::validate`]).
pub(super) fn read(m: &MatFile<'_>, file: &Path, options: &ReadOptions) -> Result<Transient> {
    let (data_file, setup_file) = if is_setup(m) {
        (beside(file, DATA_FILE), file.to_path_buf())
    } else {
        (file.to_path_buf(), beside(file, SETUP_FILE))
    };
    let Some(bin_width) = options.bin_width else {
        return Err(TransientError::MissingField {
            file: file.to_path_buf(),
            field: "bin width".into(),
            hint: "general-NLOS files do not store their bin width; give it: `--bin-width-ps 32` on the command \
                   line (the published experiment's configuration says 32 ps), `bin_width_ps=32` in Python, \
                   `ReadOptions { bin_width: Some(0.0096), .. }` in Rust"
                .into(),
        });
    };
    let other_file = if is_setup(m) { &data_file } else { &setup_file };
    let other = read_file(other_file).map_err(|e| companion_error(e, file, other_file, is_setup(m)))?;
    let other = MatFile::parse(&other, other_file)?;
    let (d, s) = if is_setup(m) { (&other, m) } else { (m, &other) };
    from_pair(d, &data_file, s, &setup_file, bin_width)
}

/// A general-NLOS capture from its two parsed files (`d` is `data.mat` at `data_file`, `s` is `setup.mat` at
/// `setup_file`; the names go into messages) with bins of `bin_width` metres of path.
///
/// # Errors
/// As [`read`], the companion file aside.
pub(super) fn from_pair(
    d: &MatFile<'_>,
    data_file: &Path,
    s: &MatFile<'_>,
    setup_file: &Path,
    bin_width: f64,
) -> Result<Transient> {
    let (data_file, setup_file) = (data_file.to_path_buf(), setup_file.to_path_buf());
    let data = d.numeric("data", "general-NLOS data.mat holds the A×B×T histograms in `data`")?;
    let [a, b, bins] = dims3(&data, &data_file, "A×B×T (the laser/sensor pair grid × time bins)")?;
    let n = a * b;
    let spots = |name: &str| -> Result<Vec<Vec3>> {
        let v = s.numeric(name, "general-NLOS setup.mat holds the A×B×3 spot positions (metres)")?;
        if v.header.dims != [a, b, 3] {
            return Err(wrong_shape(&setup_file, &v.header, format!("{a}×{b}×3 (one x, y, z per pair of data.mat)")));
        }
        let f = v.to_f64(&setup_file)?;
        // Column-major: element (i, j, c) at i + A·j + A·B·c; our point m = i·B + j.
        let p = (0..n)
            .map(|m| {
                let (i, j) = (m / b, m % b);
                let at = |c: usize| f[i + a * j + n * c] as f32;
                Vec3::new(at(0), at(1), at(2))
            })
            .collect::<Vec<_>>();
        if let Some(i) = p.iter().position(|q| !q.is_finite()) {
            return Err(TransientError::NonFinite { file: setup_file.clone(), field: name.into(), index: i });
        }
        Ok(p)
    };
    let (lasers, sensors) = (spots("laserpoints")?, spots("detectpoints")?);
    let mut values = vec![0.0f32; n * bins];
    data.for_each_f32(&data_file, |idx, v| {
        let (i, j, k) = (idx % a, (idx / a) % b, idx / n);
        if let Some(x) = values.get_mut((i * b + j) * bins + k) {
            *x = v;
        }
    })?;
    let all: Vec<Vec3> = lasers.iter().chain(&sensors).copied().collect();
    let surface = CubicSurface::fit(&all);
    let set = |points: Vec<Vec3>| PointSet {
        normals: points.iter().map(|p| surface.normal(*p)).collect(),
        points,
        layout: crate::Layout::List,
    };
    let time = TimeAxis::new(-0.5 * bin_width, bin_width, bins).map_err(|e| with_file(e, &data_file))?;
    let scan = Scan::paired(set(lasers), set(sensors));
    scan.validate().map_err(|e| with_file(e, &setup_file))?;
    Transient::new(scan, time, values).map_err(|e| with_file(e, &data_file))
}

/// A missing companion file, said as such: the capture is two files, and the one given needs the other beside it.
fn companion_error(e: TransientError, given: &Path, other: &Path, given_is_setup: bool) -> TransientError {
    match e {
        TransientError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            let what = if given_is_setup {
                "a general-NLOS capture is two files side by side, and this one, setup.mat, holds only the spots: \
                 the histograms are in data.mat"
            } else {
                "a general-NLOS capture is two files side by side, and this one, data.mat, holds only the \
                 histograms: the laser and sensor spots are in setup.mat"
            };
            TransientError::MissingCompanion {
                file: given.to_path_buf(),
                companion: other.to_path_buf(),
                what: what.into(),
            }
        }
        e => e,
    }
}

fn beside(file: &Path, name: &str) -> PathBuf {
    file.with_file_name(name)
}

/// `z(x, y) = Σ c_k x^p y^q` over the ten monomials of degree ≤ 3, in coordinates centred and scaled to the
/// spots' extent (so the normal equations stay well conditioned).
struct CubicSurface {
    c: [f64; 10],
    centre: (f64, f64),
    scale: f64,
}

/// Exponents `(p, q)` of the monomials `x^p y^q`.
const MONOMIALS: [(i32, i32); 10] = [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2), (3, 0), (2, 1), (1, 2), (0, 3)];

impl CubicSurface {
    /// The least-squares fit, with a ridge of 10⁻⁹ of the normal matrix's scale so that monomials the spots do
    /// not determine (three rows determine no `y³`) come out zero rather than arbitrary; the plane `z = mean`
    /// when even that fails (no spots).
    fn fit(points: &[Vec3]) -> Self {
        let k = points.len().max(1) as f64;
        let (sx, sy) = points.iter().fold((0.0, 0.0), |(a, b), p| (a + f64::from(p.x), b + f64::from(p.y)));
        let centre = (sx / k, sy / k);
        let scale = points
            .iter()
            .map(|p| (f64::from(p.x) - centre.0).abs().max((f64::from(p.y) - centre.1).abs()))
            .fold(0.0, f64::max)
            .max(1e-9);
        let mut s = Self { c: [0.0; 10], centre, scale };
        let mean_z = points.iter().map(|p| f64::from(p.z)).sum::<f64>() / k;
        s.c[0] = mean_z;
        let mut ata = [[0.0f64; 10]; 10];
        let mut atz = [0.0f64; 10];
        for p in points {
            let row = s.row(f64::from(p.x), f64::from(p.y));
            for ((ata_r, atz_r), &x_r) in ata.iter_mut().zip(atz.iter_mut()).zip(&row) {
                *atz_r += x_r * (f64::from(p.z) - mean_z);
                for (a, &x_c) in ata_r.iter_mut().zip(&row) {
                    *a += x_r * x_c;
                }
            }
        }
        let ridge = 1e-9 * (0..10).map(|i| ata[i][i]).fold(0.0, f64::max);
        // The constant is not penalised: heights are fitted about their mean.
        for (i, row) in ata.iter_mut().enumerate().skip(1) {
            row[i] += ridge;
        }
        if let Some(c) = solve(ata, atz) {
            s.c = c;
            s.c[0] += mean_z;
        }
        s
    }

    fn row(&self, x: f64, y: f64) -> [f64; 10] {
        let (u, v) = ((x - self.centre.0) / self.scale, (y - self.centre.1) / self.scale);
        MONOMIALS.map(|(p, q)| u.powi(p) * v.powi(q))
    }

    /// The unit normal `(−∂z/∂x, −∂z/∂y, 1)/‖·‖` at `p`'s `(x, y)`.
    fn normal(&self, p: Vec3) -> Vec3 {
        let (u, v) = ((f64::from(p.x) - self.centre.0) / self.scale, (f64::from(p.y) - self.centre.1) / self.scale);
        let (mut dzdu, mut dzdv) = (0.0, 0.0);
        for (c, (e, f)) in self.c.iter().zip(MONOMIALS) {
            if e > 0 {
                dzdu += c * f64::from(e) * u.powi(e - 1) * v.powi(f);
            }
            if f > 0 {
                dzdv += c * f64::from(f) * u.powi(e) * v.powi(f - 1);
            }
        }
        DVec3::new(-dzdu / self.scale, -dzdv / self.scale, 1.0).normalize().as_vec3()
    }
}

/// Solves the 10 × 10 system by Gaussian elimination with partial pivoting; `None` when it is singular.
fn solve(mut a: [[f64; 10]; 10], mut b: [f64; 10]) -> Option<[f64; 10]> {
    let norm = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    for col in 0..10 {
        let piv = (col..10).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() <= 1e-12 * norm {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        let (pivot, pivot_b) = (a[col], b[col]);
        for (row, rb) in a.iter_mut().zip(b.iter_mut()).skip(col + 1) {
            let f = row[col] / pivot[col];
            for (x, p) in row[col..].iter_mut().zip(&pivot[col..]) {
                *x -= f * p;
            }
            *rb -= f * pivot_b;
        }
    }
    let mut x = [0.0; 10];
    for r in (0..10).rev() {
        let s: f64 = (r + 1..10).map(|c| a[r][c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

/// Checks the bin width a user gave (metres of path).
pub(crate) fn check_bin_width(bin_width: f64, file: &Path) -> Result<()> {
    if bin_width.is_finite() && bin_width > 0.0 && bin_width < 1.0 {
        Ok(())
    } else {
        Err(invalid(
            file,
            "bin width",
            format!("{bin_width} m of path is not a bin width (finite, > 0, below 1 m; 32 ps is 0.0096 m)"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cubic_fit_recovers_a_curved_walls_normals() {
        // z = 0.02·(x² − y³) over [−0.75, 0.75]²: exact in the cubic basis.
        let z = |x: f32, y: f32| 0.02 * (x * x - y * y * y);
        let pts: Vec<Vec3> = (0..16)
            .flat_map(|i| (0..16).map(move |j| (i, j)))
            .map(|(i, j)| {
                let (x, y) = (-0.75 + 0.1 * i as f32, -0.75 + 0.1 * j as f32);
                Vec3::new(x, y, z(x, y))
            })
            .collect();
        let s = CubicSurface::fit(&pts);
        for p in [Vec3::new(0.3, -0.2, 0.0), Vec3::new(-0.7, 0.6, 0.0)] {
            let want = Vec3::new(-0.04 * p.x, 0.06 * p.y * p.y, 1.0).normalize();
            assert!(s.normal(p).angle_between(want) < 1e-4, "{:?} vs {want:?}", s.normal(p));
        }
    }

    #[test]
    fn too_few_spots_give_the_plane() {
        let s = CubicSurface::fit(&[Vec3::new(0.0, 0.0, 0.1), Vec3::new(1.0, 0.0, 0.1)]);
        assert_eq!(s.normal(Vec3::ZERO), Vec3::Z);
    }
}
