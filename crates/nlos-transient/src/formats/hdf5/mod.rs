//! HDF5 containers: y-tal HDF5_TAL (read/write), Zaragoza Z-NLOS (read), Stanford f-k and LCT in MATLAB
//! v7.3 (read), plus [`read_dataset_f64`] for any numeric dataset of any HDF5 or MAT v7.3 file.
//!
//! # Library
//! Files are parsed by [`hdf5_pure`](https://crates.io/crates/hdf5-pure) (pure Rust, MIT/Apache-2.0),
//! so the default build needs no system `libhdf5`. It was kept after checking that it reads every real
//! file at hand: the MATLAB v7.3 `spad_jitter.mat`, `spad_impulse_response.hdf5`, and the h5py-written
//! y-tal files with gzip chunks, a variable-length string, an empty-dataspace dataset, an h5py bool
//! (enum) and an int32 enum; and that h5py reads what it writes. Two guards wrap it:
//! - every call into it runs under [`std::panic::catch_unwind`]: a guard against a panic inside the
//!   dependency on malformed input, converted to [`TransientError::Malformed`] (this crate itself never
//!   panics on any input);
//! - a dataset is read only when its declared size is plausible for the input (at most
//!   [`MAX_EXPANSION`] times the file size plus 1 MiB, the most that deflate can expand), so a corrupt
//!   shape cannot make the reader allocate without bound.
//!
//! MAT v7.3 files reach this module as the bytes after the 512-byte MATLAB header. Their HDF5 superblock
//! records the header as its base address (512), which `hdf5_pure` honours, so the header's room is
//! restored (as zeros) before parsing; any other non-zero base address is handled the same way.
//!
//! Submodules: `tal` (y-tal), `znlos` (Z-NLOS) and `matv73` (MATLAB v7.3). Every error names the file
//! and the dataset.

use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use hdf5_pure::{AttrValue, DType};

use super::{Format, HDF5_MAGIC};
use crate::error::{Result, TransientError};
use crate::transient::Transient;

mod matv73;
mod tal;
mod znlos;

pub use tal::{GridFormat, HFormat};

/// The most a dataset may expand relative to the file that holds it (deflate's limit is about 1032:1);
/// a dataset declaring more is treated as malformed rather than allocated.
pub const MAX_EXPANSION: u64 = 1100;

/// Decides which HDF5-based format `bytes` (starting at the HDF5 superblock) hold, from the names of the
/// root datasets:
/// `H` + `H_format` → [`Format::Tal`]; `data` + `deltaT` (or `deltat`) → [`Format::ZNlos`]; `meas` →
/// [`Format::FkMat`]; `rect_data` → [`Format::LctMat`].
///
/// # Errors
/// [`TransientError::UnknownFormat`] listing the datasets found when they match no known layout;
/// [`TransientError::Malformed`] / [`TransientError::Truncated`] when the container cannot be parsed.
pub fn classify(bytes: &[u8], file: &Path) -> Result<Format> {
    let h = H5::open(bytes, file)?;
    let names = h.names()?;
    let has = |n: &str| names.iter().any(|x| x == n);
    if has("H") && has("H_format") {
        Ok(Format::Tal)
    } else if has("data") && (has("deltaT") || has("deltat")) {
        Ok(Format::ZNlos)
    } else if has("meas") {
        Ok(Format::FkMat)
    } else if has("rect_data") {
        Ok(Format::LctMat)
    } else {
        Err(TransientError::UnknownFormat {
            file: file.into(),
            reason: format!(
                "HDF5 file with datasets [{}]; expected `H` + `H_format` (y-tal HDF5_TAL), `data` + `deltaT` \
                 (Z-NLOS), `meas` (Stanford f-k, MAT v7.3) or `rect_data` (Stanford LCT, MAT v7.3)",
                names.join(", ")
            ),
        })
    }
}

/// Reads an HDF5 file (`bytes` start at the HDF5 superblock; for MAT v7.3, after the 512-byte MATLAB
/// header) in `format`.
///
/// # Errors
/// Any [`TransientError`], naming the file and the dataset; [`TransientError::Unsupported`] for a
/// format that is not HDF5-based here (e.g. Tsai 2019 saved as v7.3).
pub fn read(bytes: &[u8], format: Format, file: &Path) -> Result<Transient> {
    let h = H5::open(bytes, file)?;
    match format {
        Format::Tal => tal::read(&h),
        Format::ZNlos => znlos::read(&h),
        Format::FkMat => matv73::read_fk(&h),
        Format::LctMat => matv73::read_lct(&h),
        other => Err(TransientError::Unsupported {
            file: file.into(),
            what: format!("{other} in an HDF5 / MAT v7.3 container (save it with -v7 in MATLAB)"),
        }),
    }
}

/// Encodes `transient` as y-tal HDF5_TAL bytes (see the `tal` module docs for the layout).
///
/// # Errors
/// [`TransientError::CannotWrite`] when the HDF5 encoder fails.
pub fn write_tal(transient: &Transient, file: &Path) -> Result<Vec<u8>> {
    tal::write(transient, file)
}

/// Reads the real-valued dataset `name` of any numeric type from an HDF5 or MATLAB v7.3 file, as `f64`
/// values with the dataset's shape.
///
/// The shape is the HDF5 dataspace's, in C order (as h5py reports it), and the values are in that
/// order. For a MAT v7.3 file that is MATLAB's size reversed, with the values in MATLAB's column-major
/// order. A scalar has shape `[]` and one value.
///
/// # Errors
/// [`TransientError::Io`]; [`TransientError::UnknownFormat`] when the file is neither HDF5 nor MAT
/// v7.3; [`TransientError::MissingField`] when there is no such dataset; [`TransientError::WrongType`]
/// when it is not numeric; container errors.
pub fn read_dataset_f64(path: impl AsRef<Path>, name: &str) -> Result<(Vec<f64>, Vec<usize>)> {
    let path = path.as_ref();
    let bytes = super::read_file(path)?;
    read_dataset_f64_bytes(&bytes, name, path)
}

/// As [`read_dataset_f64`], for the bytes of a whole file already in memory (`file` names them in
/// errors). MAT v7.3 files are recognised by their 512-byte MATLAB header.
///
/// # Errors
/// As [`read_dataset_f64`].
pub fn read_dataset_f64_bytes(bytes: &[u8], name: &str, file: &Path) -> Result<(Vec<f64>, Vec<usize>)> {
    let body = match super::sniff(bytes) {
        Some(super::Container::Hdf5) => bytes,
        Some(super::Container::MatV73) => bytes.get(512..).unwrap_or_default(),
        _ => {
            return Err(TransientError::UnknownFormat {
                file: file.into(),
                reason: "neither an HDF5 file nor a MATLAB v7.3 MAT-file".into(),
            });
        }
    };
    let h = H5::open(body, file)?;
    let a = h.f64_array(name, "")?;
    Ok((a.values, a.shape))
}

/// A numeric dataset read as `f64`, with its C-order shape.
#[derive(Debug, Clone)]
pub(crate) struct ArrayF64 {
    pub(crate) shape: Vec<usize>,
    pub(crate) values: Vec<f64>,
}

/// An opened HDF5 file and the name it goes by in errors.
pub(crate) struct H5<'a> {
    file: hdf5_pure::File,
    path: &'a Path,
    /// Length of the input, for the plausibility bound on dataset sizes.
    input_len: u64,
}

impl std::fmt::Debug for H5<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("H5").field("path", &self.path).finish_non_exhaustive()
    }
}

/// Runs `f` (a call into `hdf5_pure`) and converts both its errors and any panic into typed errors.
///
/// The `catch_unwind` is a guard against panics inside the dependency on malformed input; this crate's
/// own code does not panic.
fn guard<T>(file: &Path, what: &str, f: impl FnOnce() -> Result<T, hdf5_pure::Error>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(h5_error(file, what, &e)),
        Err(_) => Err(TransientError::Malformed {
            file: file.into(),
            detail: format!("{what}: the HDF5 structures are corrupt (the parser gave up)"),
        }),
    }
}

/// Maps an `hdf5_pure` error to [`TransientError::Truncated`] (the file ends early) or
/// [`TransientError::Malformed`].
fn h5_error(file: &Path, what: &str, e: &hdf5_pure::Error) -> TransientError {
    let msg = e.to_string();
    let lower = msg.to_ascii_lowercase();
    if lower.contains("eof") || lower.contains("end of") || lower.contains("truncat") {
        TransientError::Truncated { file: file.into(), detail: format!("{what}: {msg}") }
    } else {
        TransientError::Malformed { file: file.into(), detail: format!("{what}: {msg}") }
    }
}

/// Reads the `i`-th address after the base address field (0 = the base address itself) of the HDF5
/// superblock at the start of `bytes`; `None` when the superblock is too short or unknown.
fn superblock_address(bytes: &[u8], i: usize) -> Option<u64> {
    let version = bytes.get(8).copied()?;
    // (offset of "size of offsets", offset of the base address) per superblock version.
    let (size_at, base_at) = match version {
        0 => (13, 24),
        1 => (13, 28),
        2 | 3 => (9, 12),
        _ => return None,
    };
    let size = usize::from(*bytes.get(size_at)?);
    if !(1..=8).contains(&size) {
        return None;
    }
    let at = base_at + i * size;
    let raw = bytes.get(at..at + size)?;
    Some(raw.iter().rev().fold(0u64, |acc, &b| (acc << 8) | u64::from(b)))
}

/// The base address recorded in the superblock (0 when unreadable; the parser then reports the real
/// problem).
fn superblock_base_address(bytes: &[u8]) -> u64 {
    superblock_address(bytes, 0).unwrap_or(0)
}

/// The end-of-file address recorded in the superblock (the third address field in every superblock
/// version).
fn superblock_eof(bytes: &[u8]) -> Option<u64> {
    superblock_address(bytes, 2)
}

impl<'a> H5<'a> {
    /// Parses the HDF5 file in `bytes` (which start with the HDF5 signature).
    pub(crate) fn open(bytes: &[u8], path: &'a Path) -> Result<Self> {
        if !bytes.starts_with(HDF5_MAGIC) {
            return Err(if bytes.len() < HDF5_MAGIC.len() {
                TransientError::Truncated { file: path.into(), detail: "HDF5 signature cut short".into() }
            } else {
                TransientError::UnknownFormat { file: path.into(), reason: "no HDF5 signature".into() }
            });
        }
        let base = superblock_base_address(bytes);
        match superblock_eof(bytes) {
            None => {
                return Err(TransientError::Truncated {
                    file: path.into(),
                    detail: format!("HDF5 superblock cut short ({} bytes)", bytes.len()),
                });
            }
            // The parser would read past the end as zeros; the HDF5 library refuses such files too.
            // (Writers, libhdf5 included, count the userblock in the end-of-file address.)
            Some(eof) if eof > (bytes.len() as u64).saturating_add(base) => {
                return Err(TransientError::Truncated {
                    file: path.into(),
                    detail: format!("HDF5 file declares {eof} bytes but has {}", bytes.len() as u64 + base),
                });
            }
            Some(_) => {}
        }
        let owned = if base == 0 {
            bytes.to_vec()
        } else if base.is_power_of_two() && (512..=1 << 20).contains(&base) {
            // A userblock that was stripped (MAT v7.3): give the parser its room back.
            let base = base as usize;
            let mut v = Vec::with_capacity(base + bytes.len());
            v.resize(base, 0);
            v.extend_from_slice(bytes);
            v
        } else {
            return Err(TransientError::Malformed {
                file: path.into(),
                detail: format!("HDF5 superblock: base address {base} is not a valid userblock size"),
            });
        };
        let file = guard(path, "HDF5 superblock", || hdf5_pure::File::from_bytes(owned))?;
        Ok(Self { file, path, input_len: bytes.len() as u64 })
    }

    /// The file's name for errors.
    pub(crate) fn path(&self) -> &Path {
        self.path
    }

    /// Names of the datasets in the root group.
    pub(crate) fn names(&self) -> Result<Vec<String>> {
        guard(self.path, "root group", || self.file.root().datasets())
    }

    /// Whether the root group holds a dataset `name`.
    pub(crate) fn has(&self, name: &str) -> bool {
        guard(self.path, name, || self.file.dataset(name)).is_ok()
    }

    /// The first of `names` that exists.
    pub(crate) fn first_of<'n>(&self, names: &[&'n str]) -> Option<&'n str> {
        names.iter().copied().find(|n| self.has(n))
    }

    fn dataset(&self, name: &str, hint: &str) -> Result<hdf5_pure::Dataset> {
        if !self.has(name) {
            return Err(TransientError::MissingField {
                file: self.path.into(),
                field: name.into(),
                hint: if hint.is_empty() { "no dataset of this name in the HDF5 file".into() } else { hint.into() },
            });
        }
        guard(self.path, name, || self.file.dataset(name))
    }

    /// The dataset's shape (C order) and element type; `None` shape for an empty (null) dataspace.
    fn shape_and_type(&self, d: &hdf5_pure::Dataset, name: &str) -> Result<(Vec<usize>, DType)> {
        let shape = guard(self.path, name, || d.shape())?;
        let dtype = guard(self.path, name, || d.dtype())?;
        let shape: Vec<usize> = shape
            .into_iter()
            .map(usize::try_from)
            .collect::<Result<_, _>>()
            .map_err(|_| self.malformed(name, "a dimension does not fit in memory"))?;
        Ok((shape, dtype))
    }

    fn malformed(&self, name: &str, detail: &str) -> TransientError {
        TransientError::Malformed { file: self.path.into(), detail: format!("dataset `{name}`: {detail}") }
    }

    /// Checks that a dataset of `shape` with `elem` bytes per element is plausible for this input.
    fn check_size(&self, name: &str, shape: &[usize], elem: u64) -> Result<usize> {
        let n = shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
        let bytes = n.and_then(|n| (n as u64).checked_mul(elem));
        let limit = self.input_len.saturating_mul(MAX_EXPANSION).saturating_add(1 << 20);
        match (n, bytes) {
            (Some(n), Some(b)) if b <= limit => Ok(n),
            _ => Err(self.malformed(
                name,
                &format!("declared shape {shape:?} is larger than a {}-byte file can hold", self.input_len),
            )),
        }
    }

    /// Reads the numeric dataset `name` as `f64` (integers, floats, enums and h5py booleans).
    ///
    /// An empty dataspace reads as shape `[0]` with no values.
    pub(crate) fn f64_array(&self, name: &str, hint: &str) -> Result<ArrayF64> {
        let d = self.dataset(name, hint)?;
        let (shape, dtype) = self.shape_and_type(&d, name)?;
        let elem = numeric_size(&dtype).ok_or_else(|| self.wrong_type(name, &dtype))?;
        let n = self.check_size(name, &shape, elem)?;
        let values = guard(self.path, name, || d.read_f64())?;
        self.finish(name, shape, n, values)
    }

    /// Reads the numeric dataset `name` as `f32` (read natively when stored as f32, so the values are
    /// bit-exact; other types are converted).
    pub(crate) fn f32_array(&self, name: &str, hint: &str) -> Result<(Vec<usize>, Vec<f32>)> {
        let d = self.dataset(name, hint)?;
        let (shape, dtype) = self.shape_and_type(&d, name)?;
        let elem = numeric_size(&dtype).ok_or_else(|| self.wrong_type(name, &dtype))?;
        let n = self.check_size(name, &shape, elem)?;
        let values = if dtype == DType::F32 {
            guard(self.path, name, || d.read_f32())?
        } else {
            guard(self.path, name, || d.read_f64())?.into_iter().map(|v| v as f32).collect()
        };
        if values.len() != n && !(values.is_empty() && shape.is_empty()) {
            return Err(self.malformed(name, &format!("{} values for shape {shape:?}", values.len())));
        }
        Ok((if values.is_empty() && shape.is_empty() { vec![0] } else { shape }, values))
    }

    fn finish(&self, name: &str, shape: Vec<usize>, n: usize, values: Vec<f64>) -> Result<ArrayF64> {
        if values.is_empty() && shape.is_empty() {
            // Empty (null) dataspace, as h5py writes for `h5py.Empty`.
            return Ok(ArrayF64 { shape: vec![0], values });
        }
        if values.len() != n {
            return Err(self.malformed(name, &format!("{} values for shape {shape:?}", values.len())));
        }
        Ok(ArrayF64 { shape, values })
    }

    fn wrong_type(&self, name: &str, dtype: &DType) -> TransientError {
        TransientError::WrongType {
            file: self.path.into(),
            field: name.into(),
            expected: "a numeric dataset (integer, float, enum or bool)".into(),
            found: dtype.to_string(),
        }
    }

    /// Reads a numeric dataset that must hold exactly one value (scalar, `(1,)`, `(1, 1)`, …).
    pub(crate) fn scalar(&self, name: &str, hint: &str) -> Result<f64> {
        let a = self.f64_array(name, hint)?;
        match a.values.as_slice() {
            [v] => Ok(*v),
            _ => Err(TransientError::WrongShape {
                file: self.path.into(),
                field: name.into(),
                expected: "a single value".into(),
                found: shape_str(&a.shape),
            }),
        }
    }

    /// Reads a finite scalar.
    pub(crate) fn finite_scalar(&self, name: &str, hint: &str) -> Result<f64> {
        let v = self.scalar(name, hint)?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(TransientError::NonFinite { file: self.path.into(), field: name.into(), index: 0 })
        }
    }

    /// The attributes of dataset `name` (empty when it has none or they cannot be decoded).
    pub(crate) fn dataset_attrs(&self, name: &str) -> HashMap<String, AttrValue> {
        self.dataset(name, "").and_then(|d| guard(self.path, name, || d.attrs())).unwrap_or_default()
    }

    /// The attributes of the root group (empty when there are none or they cannot be decoded).
    pub(crate) fn root_attrs(&self) -> HashMap<String, AttrValue> {
        guard(self.path, "root attributes", || self.file.root().attrs()).unwrap_or_default()
    }
}

/// Bytes per element of a numeric (or enum/bool) HDF5 type; `None` for strings, compounds, references.
fn numeric_size(d: &DType) -> Option<u64> {
    Some(match d {
        DType::F64 | DType::I64 | DType::U64 => 8,
        DType::F32 | DType::I32 | DType::U32 => 4,
        DType::I16 | DType::U16 => 2,
        DType::I8 | DType::U8 => 1,
        // Enum base sizes vary (h5py bools are 1 byte, y-tal enums 4); 8 is an upper bound.
        DType::Enum(_) => 8,
        _ => return None,
    })
}

/// A shape as `a×b×c` (`scalar` for `[]`).
pub(crate) fn shape_str(shape: &[usize]) -> String {
    if shape.is_empty() { "scalar".into() } else { shape.iter().map(usize::to_string).collect::<Vec<_>>().join("×") }
}

/// The text of a string attribute value.
pub(crate) fn attr_text(v: &AttrValue) -> Option<String> {
    if let Some(s) = v.as_str() {
        return Some(s.trim_end_matches('\0').to_string());
    }
    v.as_strings().and_then(|s| s.first()).map(|s| s.trim_end_matches('\0').to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_address_of_each_superblock_version() {
        let mut v0 = vec![0u8; 40];
        v0[..8].copy_from_slice(HDF5_MAGIC);
        v0[13] = 8;
        v0[24..26].copy_from_slice(&[0x00, 0x02]);
        assert_eq!(superblock_base_address(&v0), 512);
        let mut v2 = vec![0u8; 40];
        v2[..8].copy_from_slice(HDF5_MAGIC);
        v2[8] = 2;
        v2[9] = 8;
        v2[12..14].copy_from_slice(&[0x00, 0x04]);
        assert_eq!(superblock_base_address(&v2), 1024);
        assert_eq!(superblock_base_address(&v2[..13]), 0);
    }

    #[test]
    fn open_rejects_non_hdf5_and_odd_base_addresses() {
        let f = Path::new("x.h5");
        assert!(matches!(H5::open(b"\x89HD", f), Err(TransientError::Truncated { .. })));
        assert!(matches!(H5::open(b"not an hdf5 file", f), Err(TransientError::UnknownFormat { .. })));
        let mut v0 = vec![0u8; 96];
        v0[..8].copy_from_slice(HDF5_MAGIC);
        v0[13] = 8;
        v0[24] = 3;
        assert!(matches!(H5::open(&v0, f), Err(TransientError::Malformed { .. })));
    }

    #[test]
    fn shape_strings() {
        assert_eq!(shape_str(&[]), "scalar");
        assert_eq!(shape_str(&[2, 3]), "2×3");
    }
}
