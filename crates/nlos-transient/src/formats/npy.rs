//! `.npy` data with a `.json` sidecar: this project's exchange format (schema: `docs/formats/npy-json.md`).
//!
//! - The `.npy` holds the histograms: NumPy format v1.0, little-endian `float32` (`<f4`), C order. A
//!   confocal **grid** scan (or a paired scan whose laser spots form a grid) is written with shape
//!   `(ny, nx, bins)`, so that `np.load` gives an image-shaped cube (`cube[iy, ix, k]`); every other scan with
//!   shape `(measurements, bins)`.
//! - The `.json` sidecar beside it (same stem) holds the scan geometry and time axis:
//!   `{"format": "nlos-transient", "version": 1, "data": "x.npy", "dtype": "<f4", "shape": [...],
//!   "time": {...}, "scan": {...}}`.
//!
//! Reading accepts NumPy format versions 1.0, 2.0 and 3.0; either byte order; `float16/32/64`, signed and
//! unsigned integers of 1–8 bytes and `bool` (converted to `f32`, rounding to nearest); C or Fortran order;
//! shape `(measurements, bins)`, or `(ny, nx, bins)` for a confocal grid (or a paired scan's laser grid), or
//! `(lasers, sensors, bins)` for an exhaustive scan. Non-finite values are rejected ([`TransientError::NonFinite`]).
//!
//! [`read_npy_array`] loads a bare `.npy` (no sidecar) as `(values, shape)`, e.g. for reference data.

use std::path::Path;

use crate::error::{Result, TransientError};
use crate::formats::sidecar::{self, Ctx, DataEntries};
use crate::scan::{Layout, ScanPattern};
use crate::transient::Transient;

/// The NumPy magic string.
const MAGIC: &[u8; 6] = b"\x93NUMPY";
/// Deepest nesting accepted in a header dict (real headers nest two levels).
const MAX_DEPTH: usize = 16;

/// Reads the pair (`.npy` file, `.json` sidecar) from disk.
///
/// # Errors
/// [`TransientError::MissingField`] naming the sidecar path when it does not exist; [`TransientError::Io`];
/// any decoding error of [`read`].
pub fn read_pair(npy: &Path, json: &Path) -> Result<Transient> {
    let npy_bytes = super::read_file(npy)?;
    let json_bytes = match std::fs::read(json) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(missing_sidecar(json)),
        Err(source) => return Err(TransientError::Io { file: json.into(), source }),
    };
    decode(&npy_bytes, &json_bytes, npy, json)
}

/// The error for a `.npy` without its sidecar.
fn missing_sidecar(json: &Path) -> TransientError {
    TransientError::MissingField {
        file: json.into(),
        field: "sidecar".into(),
        hint: format!(
            "the .npy needs a JSON sidecar at {} describing the scan and time axis; write it as documented in \
             docs/formats/npy-json.md, or load the bare array with nlos_transient::formats::npy::read_npy_array",
            json.display()
        ),
    }
}

/// Decodes `.npy` bytes with their sidecar. `file` is the `.npy` path (for messages); the sidecar is
/// named `file` with the extension `.json`.
///
/// # Errors
/// Any [`TransientError`], naming the `.npy` for data errors and the sidecar for geometry errors.
pub fn read(npy: &[u8], json: &[u8], file: &Path) -> Result<Transient> {
    decode(npy, json, file, &file.with_extension("json"))
}

fn decode(npy: &[u8], json: &[u8], npy_file: &Path, json_file: &Path) -> Result<Transient> {
    let array = parse_npy(npy, npy_file)?;
    let ctx = Ctx { file: json_file, prefix: "sidecar" };
    let header = sidecar::parse(json, &ctx)?;
    let bins = header.time.bins;
    let m = header.measurements();
    let shape = &array.shape;
    let fits = match shape.as_slice() {
        [a, b] => (*a, *b) == (m, bins),
        [a, b, c] => header.image_dims() == Some((*a, *b)) && *c == bins,
        _ => false,
    };
    if !fits {
        let mut expected = format!("({m}, {bins}) (measurements, bins, from the sidecar)");
        if let Some((a, b)) = header.image_dims() {
            let what =
                if header.is_confocal() || header.is_paired() { "ny, nx, bins" } else { "lasers, sensors, bins" };
            expected.push_str(&format!(" or ({a}, {b}, {bins}) ({what})"));
        }
        return Err(TransientError::WrongShape {
            file: npy_file.into(),
            field: "npy header.shape".into(),
            expected,
            found: fmt_shape(shape),
        });
    }
    if let Some(s) = sidecar::usize_list(&ctx, &header.top, "shape")?
        && &s != shape
    {
        return Err(TransientError::WrongShape {
            file: json_file.into(),
            field: "sidecar.shape".into(),
            expected: format!("{} (the shape in {})", fmt_shape(shape), npy_file.display()),
            found: fmt_shape(&s),
        });
    }
    if let Some(d) = sidecar::string(&ctx, &header.top, "dtype")?
        && d != array.descr
    {
        return Err(TransientError::WrongType {
            file: json_file.into(),
            field: "sidecar.dtype".into(),
            expected: format!("{:?} (the dtype in {})", array.descr, npy_file.display()),
            found: format!("{d:?}"),
        });
    }
    sidecar::string(&ctx, &header.top, "data")?;
    let (scan, time) = header.into_parts();
    Transient::new(scan, time, array.values).map_err(|e| super::with_file(e, json_file))
}

/// Encodes `transient` as (`.npy` bytes, `.json` sidecar bytes). `file` is the `.npy` path: its file name
/// goes into the sidecar's `data` entry.
///
/// # Errors
/// [`TransientError::CannotWrite`] if the geometry cannot be encoded (never for a valid transient).
pub fn write(transient: &Transient, file: &Path) -> Result<(Vec<u8>, Vec<u8>)> {
    let (m, bins) = (transient.measurements(), transient.bins());
    let shape = match &transient.scan().pattern {
        ScanPattern::Confocal(p) | ScanPattern::Paired { lasers: p, .. } => match p.layout {
            Layout::Grid { nx, ny } if nx.checked_mul(ny) == Some(m) => vec![ny, nx, bins],
            _ => vec![m, bins],
        },
        ScanPattern::Exhaustive { .. } => vec![m, bins],
    };
    let npy = encode_npy_f32(transient.data(), &shape).map_err(|e| TransientError::CannotWrite {
        file: file.into(),
        format: "npy".into(),
        reason: e.to_string(),
    })?;
    let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let entries = DataEntries { data: &name, dtype: "<f4", shape: &shape };
    let json_file = file.with_extension("json");
    let mut json = sidecar::to_json(transient.scan(), transient.time(), Some(&entries), true, &json_file, "npy")?;
    json.push(b'\n');
    Ok((npy, json))
}

/// Loads a bare `.npy` array (no sidecar) as `(values, shape)`, values converted to `f32` in C order.
///
/// Accepts what the `.npy` reader of this module accepts (format 1.0–3.0, float/int/uint/bool dtypes of
/// either byte order, C or Fortran order).
///
/// # Errors
/// [`TransientError::Io`]; as [`decode_npy_array`].
pub fn read_npy_array(path: impl AsRef<Path>) -> Result<(Vec<f32>, Vec<usize>)> {
    let path = path.as_ref();
    decode_npy_array(&super::read_file(path)?, path)
}

/// Decodes `.npy` bytes as `(values, shape)`, values converted to `f32` in C order. `file` names the
/// bytes in errors.
///
/// # Errors
/// [`TransientError::Truncated`], [`TransientError::Malformed`] for a bad header,
/// [`TransientError::WrongType`] for an unsupported dtype, [`TransientError::NonFinite`] for NaN/Inf
/// (field `npy data`, C-order index).
pub fn decode_npy_array(bytes: &[u8], file: &Path) -> Result<(Vec<f32>, Vec<usize>)> {
    let a = parse_npy(bytes, file)?;
    Ok((a.values, a.shape))
}

/// Loads a bare `.npy` array that may hold `NaN` or infinities (a map's "no value", as in depth maps: the
/// published Z-NLOS maps mark "no surface" with Inf), both returned as `NaN`; as [`read_npy_array`] otherwise.
///
/// # Errors
/// As [`read_npy_array`].
pub fn read_npy_map(path: impl AsRef<Path>) -> Result<(Vec<f32>, Vec<usize>)> {
    let path = path.as_ref();
    decode_npy_map(&super::read_file(path)?, path)
}

/// [`read_npy_map`] on the bytes of a file (`file` names it in errors).
///
/// # Errors
/// As [`decode_npy_array`], but NaN and infinities are kept as NaN.
pub fn decode_npy_map(bytes: &[u8], file: &Path) -> Result<(Vec<f32>, Vec<usize>)> {
    let a = parse_npy_with(bytes, file, true)?;
    Ok((a.values, a.shape))
}

/// Encodes `data` as a NumPy v1.0 `.npy` array of little-endian `float32` in C order with `shape`.
///
/// # Errors
/// [`TransientError::InvalidArgument`] when the product of `shape` is not `data.len()`.
pub fn encode_npy_f32(data: &[f32], shape: &[usize]) -> Result<Vec<u8>> {
    let count = shape.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    if count != Some(data.len()) {
        return Err(TransientError::InvalidArgument {
            name: "shape",
            reason: format!("{} holds a different number of values than the {} given", fmt_shape(shape), data.len()),
        });
    }
    let dims: Vec<String> = shape.iter().map(ToString::to_string).collect();
    let tuple = if shape.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {tuple}, }}");
    // Pad with spaces and end with '\n' so that the data start on a 64-byte boundary, as NumPy does.
    let (prefix, version) = if dict.len() + 11 <= 65535 { (10, 1u8) } else { (12, 2u8) };
    let total = (prefix + dict.len() + 1).div_ceil(64) * 64;
    dict.extend(std::iter::repeat_n(' ', total - prefix - dict.len() - 1));
    dict.push('\n');
    let mut out = Vec::with_capacity(total + 4 * data.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[version, 0]);
    let hlen = dict.len();
    if version == 1 {
        out.extend_from_slice(&u16::try_from(hlen).unwrap_or(u16::MAX).to_le_bytes());
    } else {
        let too_long = || TransientError::InvalidArgument { name: "shape", reason: "header too long".into() };
        out.extend_from_slice(&u32::try_from(hlen).map_err(|_| too_long())?.to_le_bytes());
    }
    out.extend_from_slice(dict.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------------------
// Parsing

/// A decoded array.
struct Array {
    values: Vec<f32>,
    shape: Vec<usize>,
    /// The dtype string as written in the header.
    descr: String,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Float,
    Int,
    Uint,
    Bool,
}

#[derive(Debug, Clone, Copy)]
struct Dtype {
    kind: Kind,
    size: usize,
    little: bool,
}

fn fmt_shape(shape: &[usize]) -> String {
    let dims: Vec<String> = shape.iter().map(ToString::to_string).collect();
    format!("({})", dims.join(", "))
}

fn malformed(file: &Path, detail: String) -> TransientError {
    TransientError::Malformed { file: file.into(), detail }
}

fn header_err(file: &Path, key: &str, reason: String) -> TransientError {
    TransientError::InvalidValue { file: file.into(), field: format!("npy header.{key}"), reason }
}

fn parse_npy(bytes: &[u8], file: &Path) -> Result<Array> {
    parse_npy_with(bytes, file, false)
}

/// [`parse_npy`]; with `map`, NaN and infinities are a map's "no value" and come back as NaN.
fn parse_npy_with(bytes: &[u8], file: &Path, map: bool) -> Result<Array> {
    let truncated = |detail: &str| TransientError::Truncated { file: file.into(), detail: detail.into() };
    if bytes.len() < 8 {
        if MAGIC.starts_with(&bytes[..bytes.len().min(6)]) {
            return Err(truncated("npy magic and version"));
        }
        return Err(malformed(file, "not a .npy file (no \\x93NUMPY magic)".into()));
    }
    if &bytes[..6] != MAGIC {
        return Err(malformed(file, "not a .npy file (no \\x93NUMPY magic)".into()));
    }
    let (major, minor) = (bytes[6], bytes[7]);
    let (len_size, utf8) = match major {
        1 => (2, false),
        2 => (4, false),
        3 => (4, true),
        _ => {
            return Err(TransientError::Unsupported {
                file: file.into(),
                what: format!("NumPy format version {major}.{minor} (1.0, 2.0 and 3.0 are read)"),
            });
        }
    };
    let len_bytes = bytes.get(8..8 + len_size).ok_or_else(|| truncated("npy header length"))?;
    let hlen = len_bytes.iter().rev().fold(0usize, |acc, &b| (acc << 8) | usize::from(b));
    let start = 8 + len_size;
    let offset = start.checked_add(hlen).ok_or_else(|| truncated("npy header"))?;
    let text = bytes.get(start..offset).ok_or_else(|| truncated("npy header"))?;
    if utf8 && std::str::from_utf8(text).is_err() {
        return Err(malformed(file, "npy header (format 3.0) is not valid UTF-8".into()));
    }
    let (dtype, descr, fortran, shape) = parse_header(text, file)?;
    let count = shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| header_err(file, "shape", format!("{} overflows", fmt_shape(&shape))))?;
    if count == 0 {
        return Err(header_err(file, "shape", format!("{} holds no values (zero-sized array)", fmt_shape(&shape))));
    }
    let nbytes = count
        .checked_mul(dtype.size)
        .ok_or_else(|| header_err(file, "shape", format!("{} overflows", fmt_shape(&shape))))?;
    let data = &bytes[offset..];
    if data.len() < nbytes {
        return Err(TransientError::Truncated {
            file: file.into(),
            detail: format!(
                "npy data: shape {} of {descr} needs {nbytes} bytes, the file has {}",
                fmt_shape(&shape),
                data.len()
            ),
        });
    }
    if data.len() > nbytes {
        return Err(malformed(
            file,
            format!("npy data: {} bytes after the {nbytes} bytes of the array", data.len() - nbytes),
        ));
    }
    let flat: Vec<f32> = data.chunks_exact(dtype.size).map(|c| convert(c, dtype)).collect();
    let mut values = if fortran && shape.len() > 1 { fortran_to_c(&flat, &shape) } else { flat };
    if map {
        values.iter_mut().filter(|v| v.is_infinite()).for_each(|v| *v = f32::NAN);
    }
    if let Some(i) = values.iter().position(|v| !(v.is_finite() || map && v.is_nan())) {
        return Err(TransientError::NonFinite { file: file.into(), field: "npy data".into(), index: i });
    }
    Ok(Array { values, shape, descr })
}

/// One element to `f32` (rounding to nearest).
fn convert(c: &[u8], d: Dtype) -> f32 {
    let mut b = [0u8; 8];
    if d.little {
        b[..c.len()].copy_from_slice(c);
    } else {
        for (dst, src) in b.iter_mut().zip(c.iter().rev()) {
            *dst = *src;
        }
    }
    let raw = u64::from_le_bytes(b);
    let sign_extend = |bits: u32| ((raw << (64 - bits)) as i64) >> (64 - bits);
    match (d.kind, d.size) {
        (Kind::Float, 2) => f16_to_f32(raw as u16),
        (Kind::Float, 4) => f32::from_bits(raw as u32),
        (Kind::Float, _) => f64::from_bits(raw) as f32,
        (Kind::Int, n) => sign_extend(8 * n as u32) as f32,
        (Kind::Uint, _) => raw as f32,
        (Kind::Bool, _) => f32::from(u8::from(raw != 0)),
    }
}

/// IEEE binary16 to binary32 (exact).
fn f16_to_f32(h: u16) -> f32 {
    let sign = u32::from(h >> 15) << 31;
    let exp = u32::from((h >> 10) & 0x1f);
    let man = u32::from(h & 0x3ff);
    let bits = match (exp, man) {
        (0, 0) => sign,
        (0, m) => {
            // Subnormal: value = m · 2⁻²⁴, exact in f32.
            let v = m as f32 * f32::from_bits(0x3380_0000);
            return if sign != 0 { -v } else { v };
        }
        (0x1f, 0) => sign | 0x7f80_0000,
        (0x1f, m) => sign | 0x7fc0_0000 | (m << 13),
        (e, m) => sign | ((e + 112) << 23) | (m << 13),
    };
    f32::from_bits(bits)
}

/// Reorders a Fortran-order (first index fastest) array into C order (last index fastest).
pub(super) fn fortran_to_c(src: &[f32], shape: &[usize]) -> Vec<f32> {
    let n = shape.len();
    let mut c_stride = vec![1usize; n];
    for j in (0..n.saturating_sub(1)).rev() {
        c_stride[j] = c_stride[j + 1] * shape[j + 1];
    }
    let mut out = vec![0.0f32; src.len()];
    let mut idx = vec![0usize; n];
    let mut c_off = 0usize;
    for &v in src {
        out[c_off] = v;
        for j in 0..n {
            idx[j] += 1;
            c_off += c_stride[j];
            if idx[j] < shape[j] {
                break;
            }
            c_off -= c_stride[j] * shape[j];
            idx[j] = 0;
        }
    }
    out
}

/// Parses the header dict: `(dtype, descr string, fortran_order, shape)`.
fn parse_header(text: &[u8], file: &Path) -> Result<(Dtype, String, bool, Vec<usize>)> {
    let mut p = Parser { s: text, i: 0, file };
    let value = p.value(0)?;
    p.skip_ws();
    if p.i != text.len() {
        return Err(p.err("unexpected text after the header dict"));
    }
    let Py::Dict(entries) = value else { return Err(malformed(file, "npy header is not a dict".into())) };
    let mut descr = None;
    let mut fortran = None;
    let mut shape = None;
    for (k, v) in entries {
        let Py::Str(k) = k else { return Err(malformed(file, "npy header has a non-string key".into())) };
        let slot = match k.as_str() {
            "descr" => &mut descr,
            "fortran_order" => &mut fortran,
            "shape" => &mut shape,
            other => {
                return Err(header_err(file, other, "unknown key (a header has descr, fortran_order, shape)".into()));
            }
        };
        if slot.replace(v).is_some() {
            return Err(header_err(file, &k, "given twice".into()));
        }
    }
    let need = |k: &str| TransientError::MissingField {
        file: file.into(),
        field: format!("npy header.{k}"),
        hint: "a .npy header has the keys descr, fortran_order and shape; rewrite the file with numpy.save".into(),
    };
    let descr = match descr.ok_or_else(|| need("descr"))? {
        Py::Str(s) => s,
        other => {
            return Err(TransientError::WrongType {
                file: file.into(),
                field: "npy header.descr".into(),
                expected: "a plain numeric dtype such as '<f4'".into(),
                found: format!("{} (a structured dtype)", other.kind()),
            });
        }
    };
    let dtype = parse_descr(&descr, file)?;
    let fortran = match fortran.ok_or_else(|| need("fortran_order"))? {
        Py::Bool(b) => b,
        other => return Err(header_err(file, "fortran_order", format!("{} is not True or False", other.kind()))),
    };
    let shape = match shape.ok_or_else(|| need("shape"))? {
        Py::Tuple(items) | Py::List(items) => items
            .into_iter()
            .map(|d| match d {
                Py::Int(n) => usize::try_from(n).ok(),
                _ => None,
            })
            .collect::<Option<Vec<usize>>>()
            .ok_or_else(|| header_err(file, "shape", "must be a tuple of non-negative integers".into()))?,
        other => return Err(header_err(file, "shape", format!("{} is not a tuple", other.kind()))),
    };
    Ok((dtype, descr, fortran, shape))
}

fn parse_descr(descr: &str, file: &Path) -> Result<Dtype> {
    let unsupported = || TransientError::WrongType {
        file: file.into(),
        field: "npy header.descr".into(),
        expected: "float (f2, f4, f8), signed or unsigned integer (i1–i8, u1–u8) or bool (b1)".into(),
        found: format!("{descr:?}"),
    };
    let b = descr.as_bytes();
    let (order, rest) = match b.first() {
        Some(c @ (b'<' | b'>' | b'|' | b'=')) => (*c, &b[1..]),
        _ => (b'=', b),
    };
    let (&kind, digits) = rest.split_first().ok_or_else(unsupported)?;
    let size: usize = std::str::from_utf8(digits).ok().and_then(|d| d.parse().ok()).ok_or_else(unsupported)?;
    let kind = match (kind, size) {
        (b'f', 2 | 4 | 8) => Kind::Float,
        (b'i', 1 | 2 | 4 | 8) => Kind::Int,
        (b'u', 1 | 2 | 4 | 8) => Kind::Uint,
        (b'b', 1) => Kind::Bool,
        _ => return Err(unsupported()),
    };
    let little = match order {
        b'>' => false,
        b'<' => true,
        _ => cfg!(target_endian = "little") || size == 1,
    };
    Ok(Dtype { kind, size, little })
}

/// A Python literal as found in `.npy` headers.
#[derive(Debug)]
enum Py {
    Str(String),
    Int(i128),
    Bool(bool),
    None,
    Tuple(Vec<Py>),
    List(Vec<Py>),
    Dict(Vec<(Py, Py)>),
}

impl Py {
    fn kind(&self) -> &'static str {
        match self {
            Py::Str(_) => "a string",
            Py::Int(_) => "an integer",
            Py::Bool(_) => "a boolean",
            Py::None => "None",
            Py::Tuple(_) => "a tuple",
            Py::List(_) => "a list",
            Py::Dict(_) => "a dict",
        }
    }
}

/// A recursive-descent parser for the Python-literal subset used in `.npy` headers: dicts, tuples, lists,
/// quoted strings, integers, `True`, `False`, `None`.
struct Parser<'a> {
    s: &'a [u8],
    i: usize,
    file: &'a Path,
}

impl Parser<'_> {
    fn err(&self, what: &str) -> TransientError {
        malformed(self.file, format!("npy header dict, byte {}: {what}", self.i))
    }

    fn skip_ws(&mut self) {
        while self.s.get(self.i).is_some_and(u8::is_ascii_whitespace) {
            self.i += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.skip_ws();
        self.s.get(self.i).copied()
    }

    fn value(&mut self, depth: usize) -> Result<Py> {
        if depth > MAX_DEPTH {
            return Err(self.err("nested too deeply"));
        }
        match self.peek() {
            None => Err(self.err("unexpected end")),
            Some(b'{') => {
                self.i += 1;
                let mut entries = Vec::new();
                loop {
                    if self.peek() == Some(b'}') {
                        self.i += 1;
                        return Ok(Py::Dict(entries));
                    }
                    let k = self.value(depth + 1)?;
                    if self.peek() != Some(b':') {
                        return Err(self.err("expected ':'"));
                    }
                    self.i += 1;
                    let v = self.value(depth + 1)?;
                    entries.push((k, v));
                    match self.peek() {
                        Some(b',') => self.i += 1,
                        Some(b'}') => {}
                        _ => return Err(self.err("expected ',' or '}'")),
                    }
                }
            }
            Some(open @ (b'(' | b'[')) => {
                let close = if open == b'(' { b')' } else { b']' };
                self.i += 1;
                let mut items = Vec::new();
                let mut trailing_comma = false;
                loop {
                    if self.peek() == Some(close) {
                        self.i += 1;
                        // `(3)` is the integer 3 in Python; `(3,)` is a tuple.
                        if open == b'(' && items.len() == 1 && !trailing_comma {
                            return Ok(items.pop().unwrap_or(Py::None));
                        }
                        return Ok(if open == b'(' { Py::Tuple(items) } else { Py::List(items) });
                    }
                    items.push(self.value(depth + 1)?);
                    trailing_comma = false;
                    match self.peek() {
                        Some(b',') => {
                            self.i += 1;
                            trailing_comma = true;
                        }
                        Some(c) if c == close => {}
                        _ => return Err(self.err("expected ',' or a closing bracket")),
                    }
                }
            }
            Some(q @ (b'\'' | b'"')) => {
                self.i += 1;
                let mut out = Vec::new();
                loop {
                    let c = *self.s.get(self.i).ok_or_else(|| self.err("unterminated string"))?;
                    self.i += 1;
                    match c {
                        _ if c == q => break,
                        b'\\' => {
                            let e = *self.s.get(self.i).ok_or_else(|| self.err("unterminated string"))?;
                            self.i += 1;
                            out.push(match e {
                                b'n' => b'\n',
                                b't' => b'\t',
                                b'r' => b'\r',
                                b'0' => 0,
                                other => other,
                            });
                        }
                        b'\n' => return Err(self.err("newline in string")),
                        _ => out.push(c),
                    }
                }
                Ok(Py::Str(String::from_utf8_lossy(&out).into_owned()))
            }
            Some(c) if c.is_ascii_digit() || c == b'-' || c == b'+' => {
                let start = self.i;
                self.i += 1;
                while self.s.get(self.i).is_some_and(u8::is_ascii_digit) {
                    self.i += 1;
                }
                let text = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
                let n: i128 = text.parse().map_err(|_| self.err("bad integer"))?;
                // Python 2 wrote long integers with an `L` suffix.
                if matches!(self.s.get(self.i), Some(b'L' | b'l')) {
                    self.i += 1;
                }
                Ok(Py::Int(n))
            }
            Some(c) if c.is_ascii_alphabetic() => {
                let start = self.i;
                while self.s.get(self.i).is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_') {
                    self.i += 1;
                }
                match &self.s[start..self.i] {
                    b"True" => Ok(Py::Bool(true)),
                    b"False" => Ok(Py::Bool(false)),
                    b"None" => Ok(Py::None),
                    _ => {
                        self.i = start;
                        Err(self.err("unknown name (only True, False and None are allowed)"))
                    }
                }
            }
            Some(_) => Err(self.err("unexpected character")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy_with(header: &str, data: &[u8]) -> Vec<u8> {
        let mut h = header.to_owned();
        while !(10 + h.len() + 1).is_multiple_of(64) {
            h.push(' ');
        }
        h.push('\n');
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(h.len() as u16).to_le_bytes());
        out.extend_from_slice(h.as_bytes());
        out.extend_from_slice(data);
        out
    }

    fn f() -> &'static Path {
        Path::new("a.npy")
    }

    #[test]
    fn header_parser_handles_python_literals() -> Result<()> {
        let (d, descr, fo, shape) =
            parse_header(b"{'descr': '>i2', \"fortran_order\": True, 'shape': (3, 4L,), }  \n", f())?;
        assert_eq!(
            (d.kind, d.size, d.little, descr.as_str(), fo, shape),
            (Kind::Int, 2, false, ">i2", true, vec![3, 4])
        );
        let (_, _, _, shape) = parse_header(b"{'descr':'<f4','fortran_order':False,'shape':()}", f())?;
        assert!(shape.is_empty());
        // `(7)` is the integer 7, not a tuple.
        assert!(parse_header(b"{'descr':'<f4','fortran_order':False,'shape':(7)}", f()).is_err());
        Ok(())
    }

    #[test]
    fn header_errors() {
        let bad: [&[u8]; 8] = [
            b"{'descr': '<c8', 'fortran_order': False, 'shape': (2,), }",
            b"{'descr': '|O', 'fortran_order': False, 'shape': (2,), }",
            b"{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (2,), }",
            b"{'descr': '<f4', 'fortran_order': False, 'shape': (-2,), }",
            b"{'descr': '<f4', 'fortran_order': 0, 'shape': (2,), }",
            b"{'descr': '<f4', 'shape': (2,), }",
            b"{'descr': '<f4', 'fortran_order': False, 'shape': (2,), 'x': 1}",
            b"{'descr': '<f4', 'fortran_order': False, 'shape': (2,) ",
        ];
        for h in bad {
            let e = parse_header(h, f()).expect_err(&String::from_utf8_lossy(h)).to_string();
            assert!(e.contains("a.npy") && e.contains("npy header"), "{e}");
        }
        let deep = format!("{}{}", "[".repeat(100), "]".repeat(100));
        assert!(parse_header(deep.as_bytes(), f()).is_err());
    }

    #[test]
    fn dtypes_convert() -> Result<()> {
        let cases: Vec<(&str, Vec<u8>, Vec<f32>)> = vec![
            ("<f8", [1.5f64, -2.0].iter().flat_map(|v| v.to_le_bytes()).collect(), vec![1.5, -2.0]),
            (">f4", [1.5f32, -0.0].iter().flat_map(|v| v.to_be_bytes()).collect(), vec![1.5, -0.0]),
            ("<u2", [7u16, 65535].iter().flat_map(|v| v.to_le_bytes()).collect(), vec![7.0, 65535.0]),
            ("<i4", [-7i32, 1 << 20].iter().flat_map(|v| v.to_le_bytes()).collect(), vec![-7.0, 1048576.0]),
            (">i8", [-3i64, 5].iter().flat_map(|v| v.to_be_bytes()).collect(), vec![-3.0, 5.0]),
            ("|i1", vec![0xff, 0x7f], vec![-1.0, 127.0]),
            ("|u1", vec![0xff, 0], vec![255.0, 0.0]),
            ("|b1", vec![1, 0], vec![1.0, 0.0]),
            ("<f2", vec![0x00, 0x3c, 0x01, 0x80], vec![1.0, -f32::from_bits(0x3380_0000)]),
        ];
        for (descr, data, want) in cases {
            let bytes = npy_with(&format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': (2,), }}"), &data);
            let (v, s) = decode_npy_array(&bytes, f())?;
            assert_eq!(s, vec![2]);
            let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&v), bits(&want), "{descr}");
        }
        Ok(())
    }

    #[test]
    fn f16_conversion_is_exact() {
        assert_eq!(f16_to_f32(0x7bff), 65504.0);
        assert_eq!(f16_to_f32(0x0400), 6.103_515_6e-5);
        assert!(f16_to_f32(0x7c00).is_infinite() && f16_to_f32(0x7e00).is_nan());
        assert_eq!(f16_to_f32(0x8000).to_bits(), (-0.0f32).to_bits());
    }

    #[test]
    fn fortran_order_is_reordered() -> Result<()> {
        // C-order array a[i, j, k] = 100 i + 10 j + k with shape (2, 3, 4), stored in Fortran order.
        let shape = [2usize, 3, 4];
        let mut f_data = Vec::new();
        for k in 0..4 {
            for j in 0..3 {
                for i in 0..2 {
                    f_data.extend_from_slice(&((100 * i + 10 * j + k) as f32).to_le_bytes());
                }
            }
        }
        let bytes = npy_with("{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3, 4), }", &f_data);
        let (v, s) = decode_npy_array(&bytes, f())?;
        assert_eq!(s, shape);
        let want: Vec<f32> =
            (0..2).flat_map(|i| (0..3).flat_map(move |j| (0..4).map(move |k| (100 * i + 10 * j + k) as f32))).collect();
        assert_eq!(v, want);
        Ok(())
    }

    #[test]
    fn encode_matches_numpy_layout() -> Result<()> {
        let bytes = encode_npy_f32(&[1.0, 2.0, 3.0], &[3])?;
        assert_eq!(bytes.len(), 128 + 12);
        let text = String::from_utf8_lossy(&bytes[10..128]);
        assert!(text.starts_with("{'descr': '<f4', 'fortran_order': False, 'shape': (3,), }"), "{text}");
        assert!(text.ends_with('\n'));
        assert_eq!(decode_npy_array(&bytes, f())?, (vec![1.0, 2.0, 3.0], vec![3]));
        assert!(encode_npy_f32(&[1.0], &[2]).is_err());
        Ok(())
    }

    #[test]
    fn data_errors() {
        let h = "{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }";
        let e = decode_npy_array(&npy_with(h, &[0; 7]), f()).expect_err("short");
        assert!(matches!(e, TransientError::Truncated { .. }), "{e}");
        let e = decode_npy_array(&npy_with(h, &[0; 9]), f()).expect_err("long");
        assert!(matches!(e, TransientError::Malformed { .. }), "{e}");
        let nan: Vec<u8> = [0.0f32, f32::NAN].iter().flat_map(|v| v.to_le_bytes()).collect();
        let e = decode_npy_array(&npy_with(h, &nan), f()).expect_err("nan");
        assert!(matches!(e, TransientError::NonFinite { index: 1, ref field, .. } if field == "npy data"), "{e}");
        let big: Vec<u8> = [1e300f64, 0.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        let h8 = "{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }";
        assert!(matches!(decode_npy_array(&npy_with(h8, &big), f()), Err(TransientError::NonFinite { index: 0, .. })));
        let z = "{'descr': '<f4', 'fortran_order': False, 'shape': (0, 5), }";
        assert!(matches!(decode_npy_array(&npy_with(z, &[]), f()), Err(TransientError::InvalidValue { .. })));
        let v9 = [MAGIC.as_slice(), &[9, 0, 0, 0]].concat();
        assert!(matches!(decode_npy_array(&v9, f()), Err(TransientError::Unsupported { .. })));
    }
}
