//! A small, defensive reader for MATLAB level-5 MAT-files (the v5, v6 and v7 formats; v7.3 is HDF5).
//!
//! Reference: MathWorks, *MAT-File Format* (matfile_format.pdf, "Level 5 MAT-File Format"): a 128-byte
//! header (descriptive text, subsystem offset, version `0x0100`, endian indicator `"MI"`), then data
//! elements, each an 8-byte tag (type, byte count) — or a 4-byte *small data element* tag when the data
//! fit in 4 bytes — followed by the data padded to 8 bytes. Variables are `miMATRIX` elements holding
//! sub-elements: array flags (class, complex/global/logical bits), dimensions, name, real part and
//! optional imaginary part. MATLAB v7 wraps each variable in an `miCOMPRESSED` element: a zlib stream
//! that inflates to one `miMATRIX` element.
//!
//! Why not the `matfile` crate: version 0.5 keeps the *storage* type of numeric data and drops the array
//! class (MATLAB stores class-double arrays as uint16 when the values fit, as in the Stanford LCT files),
//! multiplies dimensions in `i32` (overflow panics in debug builds), `unwrap`s the numeric type of the
//! class (panics on a malformed class), and inflates compressed elements without a size bound. This
//! reader never panics, checks every length and offset, honours the class, and never allocates more than
//! the input can actually hold.
//!
//! Design:
//! - [`MatFile::parse`] reads the header and the *headers* of every variable (name, class, dimensions)
//!   without decoding their data; a compressed variable is inflated only up to its header (at most
//!   [`HEADER_PREFIX`] bytes, usually [`SMALL_PREFIX`]). Format detection uses only this.
//! - [`MatFile::numeric`] decodes one variable fully. Its data must match its dimensions exactly, so the
//!   element count is bounded by the bytes present before anything is allocated; a zlib stream is
//!   inflated up to the size its inner tag declares, which must itself be possible for the compressed
//!   size (zlib cannot expand more than [`MAX_INFLATE_RATIO`]:1).
//! - Big-endian files (endian indicator `"MI"` read as bytes) are supported: every integer and float is
//!   read in the file's byte order.
//!
//! **Why one file of ~850 lines.** It is one container format, parsed bottom-up (tags, numeric and char
//! arrays, cells and structs, compressed elements) with one set of size caps and one error path; it is
//! fuzzed as a unit (`fuzz/fuzz_targets/mat_v5.rs`), and every reader of a MAT v5 capture goes through it.

use std::borrow::Cow;
use std::io::Read;
use std::path::Path;

use crate::error::{Result, TransientError};

/// Bytes of a compressed variable inflated first to read its header (flags, dimensions, name).
pub(crate) const SMALL_PREFIX: usize = 1024;

/// Most bytes of a compressed variable inflated to read its header (a header with very many dimensions
/// or a long name); a header longer than this is reported as malformed.
pub(crate) const HEADER_PREFIX: usize = 64 * 1024;

/// Upper bound of the expansion ratio of a zlib/deflate stream (the format's theoretical maximum is
/// about 1032:1), used to reject inner sizes no stream of the given length could produce.
pub(crate) const MAX_INFLATE_RATIO: usize = 1100;

/// `miINT8` … `miUTF32`: the data types of MAT v5 data elements.
const MI_INT8: u32 = 1;
const MI_UINT8: u32 = 2;
const MI_INT16: u32 = 3;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_SINGLE: u32 = 7;
const MI_DOUBLE: u32 = 9;
const MI_INT64: u32 = 12;
const MI_UINT64: u32 = 13;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const MI_UTF8: u32 = 16;

/// Byte order of a MAT-file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Endian {
    /// Endian indicator bytes `"IM"` (written by a little-endian machine).
    Little,
    /// Endian indicator bytes `"MI"` (written by a big-endian machine).
    Big,
}

impl Endian {
    fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Endian::Little => u16::from_le_bytes(b),
            Endian::Big => u16::from_be_bytes(b),
        }
    }

    fn u32(self, b: [u8; 4]) -> u32 {
        match self {
            Endian::Little => u32::from_le_bytes(b),
            Endian::Big => u32::from_be_bytes(b),
        }
    }
}

/// The class of a MATLAB array (`mxCLASS`), from the array flags.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Class {
    /// Cell array (1).
    Cell,
    /// Structure (2).
    Struct,
    /// Object (3).
    Object,
    /// Character array (4).
    Char,
    /// Sparse array (5).
    Sparse,
    /// Double precision (6).
    Double,
    /// Single precision (7).
    Single,
    /// int8 (8).
    Int8,
    /// uint8 (9); also logical arrays, which carry the logical flag.
    UInt8,
    /// int16 (10).
    Int16,
    /// uint16 (11).
    UInt16,
    /// int32 (12).
    Int32,
    /// uint32 (13).
    UInt32,
    /// int64 (14).
    Int64,
    /// uint64 (15).
    UInt64,
    /// Any other class code (function handles, opaque objects, unknown codes).
    Other(u8),
}

impl Class {
    fn from_code(code: u8) -> Self {
        match code {
            1 => Class::Cell,
            2 => Class::Struct,
            3 => Class::Object,
            4 => Class::Char,
            5 => Class::Sparse,
            6 => Class::Double,
            7 => Class::Single,
            8 => Class::Int8,
            9 => Class::UInt8,
            10 => Class::Int16,
            11 => Class::UInt16,
            12 => Class::Int32,
            13 => Class::UInt32,
            14 => Class::Int64,
            15 => Class::UInt64,
            other => Class::Other(other),
        }
    }

    /// Whether the class is a full numeric array class (double, single or an integer class).
    pub(crate) fn is_numeric(self) -> bool {
        !matches!(self, Class::Cell | Class::Struct | Class::Object | Class::Char | Class::Sparse | Class::Other(_))
    }

    /// MATLAB's name of the class.
    pub(crate) fn name(self) -> Cow<'static, str> {
        Cow::Borrowed(match self {
            Class::Cell => "cell",
            Class::Struct => "struct",
            Class::Object => "object",
            Class::Char => "char",
            Class::Sparse => "sparse",
            Class::Double => "double",
            Class::Single => "single",
            Class::Int8 => "int8",
            Class::UInt8 => "uint8",
            Class::Int16 => "int16",
            Class::UInt16 => "uint16",
            Class::Int32 => "int32",
            Class::UInt32 => "uint32",
            Class::Int64 => "int64",
            Class::UInt64 => "uint64",
            Class::Other(c) => return Cow::Owned(format!("class code {c}")),
        })
    }

    /// Converts a stored value to the value of this class, or `None` when it does not fit (a non-integral
    /// or out-of-range value in an integer class).
    fn cast(self, v: f64) -> Option<f64> {
        let int = |lo: f64, hi: f64| (v.fract() == 0.0 && v >= lo && v <= hi).then_some(v);
        match self {
            Class::Double => Some(v),
            Class::Single => Some(f64::from(v as f32)),
            Class::Int8 => int(-128.0, 127.0),
            Class::UInt8 => int(0.0, 255.0),
            Class::Int16 => int(-32768.0, 32767.0),
            Class::UInt16 => int(0.0, 65535.0),
            Class::Int32 => int(-2_147_483_648.0, 2_147_483_647.0),
            Class::UInt32 => int(0.0, 4_294_967_295.0),
            Class::Int64 => int(-9.223_372_036_854_776e18, 9.223_372_036_854_776e18),
            Class::UInt64 => int(0.0, 1.844_674_407_370_955_2e19),
            _ => None,
        }
    }
}

/// Name of a MAT data type, for messages.
fn type_name(t: u32) -> String {
    match t {
        MI_INT8 => "miINT8".into(),
        MI_UINT8 => "miUINT8".into(),
        MI_INT16 => "miINT16".into(),
        MI_UINT16 => "miUINT16".into(),
        MI_INT32 => "miINT32".into(),
        MI_UINT32 => "miUINT32".into(),
        MI_SINGLE => "miSINGLE".into(),
        MI_DOUBLE => "miDOUBLE".into(),
        MI_INT64 => "miINT64".into(),
        MI_UINT64 => "miUINT64".into(),
        MI_MATRIX => "miMATRIX".into(),
        MI_COMPRESSED => "miCOMPRESSED".into(),
        MI_UTF8 => "miUTF8".into(),
        other => format!("data type {other}"),
    }
}

/// Size in bytes of one element of a numeric data type, `None` for non-numeric types.
fn numeric_size(t: u32) -> Option<usize> {
    match t {
        MI_INT8 | MI_UINT8 => Some(1),
        MI_INT16 | MI_UINT16 => Some(2),
        MI_INT32 | MI_UINT32 | MI_SINGLE => Some(4),
        MI_DOUBLE | MI_INT64 | MI_UINT64 => Some(8),
        _ => None,
    }
}

/// The header of a variable: everything but its data.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct VarHeader {
    /// Variable name.
    pub name: String,
    /// Array class.
    pub class: Class,
    /// Whether the array has an imaginary part.
    pub complex: bool,
    /// Dimensions (MATLAB order: rows, columns, pages, …).
    pub dims: Vec<usize>,
}

impl VarHeader {
    /// The dimensions as MATLAB prints them, e.g. `64×64×2048 double`.
    pub(crate) fn describe(&self) -> String {
        let dims: Vec<String> = self.dims.iter().map(usize::to_string).collect();
        format!("{} {}{}", dims.join("×"), if self.complex { "complex " } else { "" }, self.class.name())
    }
}

/// Where a top-level element lies in the file.
#[derive(Debug, Clone)]
struct Entry {
    /// Offset of the element's data (after its tag).
    offset: usize,
    /// Byte count of the element's data.
    len: usize,
    /// Whether the element is `miCOMPRESSED`.
    compressed: bool,
    /// For compressed elements, the byte count the inner `miMATRIX` tag declares.
    inner_len: usize,
    header: VarHeader,
}

/// A parsed MAT v5 file: its byte order and the headers of its variables; data decoded on demand.
#[derive(Debug)]
pub(crate) struct MatFile<'a> {
    bytes: &'a [u8],
    file: &'a Path,
    endian: Endian,
    entries: Vec<Entry>,
}

/// A decoded numeric variable: its header and its real part, still in the storage type.
#[derive(Debug)]
pub(crate) struct NumericArray<'a> {
    /// The variable's header (name, class, dimensions).
    pub header: VarHeader,
    storage: u32,
    data: Cow<'a, [u8]>,
    endian: Endian,
}

impl<'a> MatFile<'a> {
    /// Parses the 128-byte header and every variable's header.
    ///
    /// # Errors
    /// [`TransientError::Truncated`], [`TransientError::Malformed`] or [`TransientError::Unsupported`],
    /// naming `file`.
    pub(crate) fn parse(bytes: &'a [u8], file: &'a Path) -> Result<Self> {
        let err = Errs { file };
        if bytes.len() < 128 {
            return Err(err.truncated(format!("{} bytes, shorter than the 128-byte MAT-file header", bytes.len())));
        }
        if !bytes.starts_with(b"MATLAB") {
            return Err(err.malformed("the header text does not start with `MATLAB`".into()));
        }
        let endian = match (bytes[126], bytes[127]) {
            (b'I', b'M') => Endian::Little,
            (b'M', b'I') => Endian::Big,
            (a, b) => {
                return Err(err.malformed(format!("endian indicator {:?} is neither \"IM\" nor \"MI\"", [a, b])));
            }
        };
        let version = endian.u16([bytes[124], bytes[125]]);
        if version != 0x0100 {
            return Err(TransientError::Unsupported {
                file: file.into(),
                what: format!("MAT-file version 0x{version:04x} (only level 5, version 0x0100, is read here)"),
            });
        }
        let mut entries = Vec::new();
        let mut pos = 128usize;
        let mut index = 0usize;
        while pos < bytes.len() {
            index += 1;
            let what = || format!("data element #{index} at byte {pos}");
            let tag = bytes.get(pos..pos + 8).ok_or_else(|| {
                err.truncated(format!("{}: {} bytes left, an element tag needs 8", what(), bytes.len() - pos))
            })?;
            let dtype = endian.u32([tag[0], tag[1], tag[2], tag[3]]);
            let len = endian.u32([tag[4], tag[5], tag[6], tag[7]]) as usize;
            let offset = pos + 8;
            let end = offset.checked_add(len).filter(|&e| e <= bytes.len()).ok_or_else(|| {
                err.truncated(format!("{} declares {len} bytes but only {} remain", what(), bytes.len() - offset))
            })?;
            let data = &bytes[offset..end];
            match dtype {
                MI_MATRIX => {
                    let header = parse_header(data, endian, &err, &what())?;
                    entries.push(Entry { offset, len, compressed: false, inner_len: len, header });
                    // miMATRIX data are padded to 8 bytes (the byte count normally includes the padding).
                    pos = end.saturating_add(pad8(len)).min(bytes.len());
                }
                MI_COMPRESSED => {
                    let (inner_len, header) = compressed_header(data, endian, &err, &what())?;
                    entries.push(Entry { offset, len, compressed: true, inner_len, header });
                    pos = end;
                }
                // Other element types do not occur at the top level of files MATLAB writes; skip them.
                _ => pos = end.saturating_add(pad8(len)).min(bytes.len()),
            }
        }
        Ok(Self { bytes, file, endian, entries })
    }

    /// The headers of all variables, in file order.
    pub(crate) fn headers(&self) -> impl Iterator<Item = &VarHeader> {
        self.entries.iter().map(|e| &e.header)
    }

    /// The header of variable `name` (the first one of that name).
    pub(crate) fn header(&self, name: &str) -> Option<&VarHeader> {
        self.headers().find(|h| h.name == name)
    }

    /// The names of all variables, comma-separated, for messages.
    pub(crate) fn names(&self) -> String {
        let names: Vec<String> = self.headers().map(|h| format!("`{}` ({})", h.name, h.describe())).collect();
        if names.is_empty() { "no variables".into() } else { names.join(", ") }
    }

    /// Decodes numeric variable `name` (real, full, numeric class).
    ///
    /// # Errors
    /// [`TransientError::MissingField`] when absent (`hint` says what it holds); [`TransientError::WrongType`]
    /// for a non-numeric class or complex data; [`TransientError::Malformed`]/[`TransientError::Truncated`]
    /// for a damaged element.
    pub(crate) fn numeric(&self, name: &str, hint: &str) -> Result<NumericArray<'a>> {
        let err = Errs { file: self.file };
        let entry = self.entries.iter().find(|e| e.header.name == name).ok_or_else(|| {
            TransientError::MissingField { file: self.file.into(), field: name.into(), hint: hint.into() }
        })?;
        let h = &entry.header;
        if !h.class.is_numeric() || h.complex {
            return Err(TransientError::WrongType {
                file: self.file.into(),
                field: name.into(),
                expected: "a real numeric array (double, single or integer class)".into(),
                found: h.describe(),
            });
        }
        let raw = &self.bytes[entry.offset..entry.offset + entry.len];
        let what = format!("variable `{name}`");
        let body: Cow<'a, [u8]> = if entry.compressed {
            let limit = entry.inner_len.saturating_add(8);
            let full = inflate(raw, limit)
                .map_err(|e| err.malformed(format!("{what}: bad zlib stream in miCOMPRESSED element: {e}")))?;
            if full.len() < limit {
                return Err(err.truncated(format!(
                    "{what}: the compressed stream inflates to {} of the {} bytes its tag declares",
                    full.len(),
                    limit
                )));
            }
            let mut full = full;
            full.drain(..8);
            Cow::Owned(full)
        } else {
            Cow::Borrowed(raw)
        };
        let (storage, range) = real_part(&body, self.endian, &err, &what)?;
        let size = numeric_size(storage).ok_or_else(|| TransientError::WrongType {
            file: self.file.into(),
            field: name.into(),
            expected: "numeric data".into(),
            found: format!("{} data in a {} array", type_name(storage), h.class.name()),
        })?;
        let count = h.dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
        if count.and_then(|c| c.checked_mul(size)) != Some(range.len()) {
            return Err(err.malformed(format!(
                "{what}: dimensions {} need {} bytes of {} but the element holds {} bytes",
                h.describe(),
                count.and_then(|c| c.checked_mul(size)).map_or_else(|| "more than 2^64".into(), |b| b.to_string()),
                type_name(storage),
                range.len()
            )));
        }
        let data = match body {
            Cow::Borrowed(b) => Cow::Borrowed(&b[range]),
            Cow::Owned(mut v) => {
                v.truncate(range.end);
                v.drain(..range.start);
                Cow::Owned(v)
            }
        };
        Ok(NumericArray { header: h.clone(), storage, data, endian: self.endian })
    }
}

impl NumericArray<'_> {
    /// Number of elements (the product of the dimensions).
    pub(crate) fn len(&self) -> usize {
        numeric_size(self.storage).map_or(0, |s| self.data.len() / s)
    }

    /// Calls `f(index, value)` for every element in storage (column-major) order, with the stored value
    /// converted to the array's class.
    ///
    /// # Errors
    /// [`TransientError::Malformed`] when a stored value does not fit the class; the errors of `f`.
    fn for_each(&self, file: &Path, mut f: impl FnMut(usize, f64) -> Result<()>) -> Result<()> {
        let class = self.header.class;
        let be = self.endian == Endian::Big;
        let mut put = |i: usize, v: f64| -> Result<()> {
            let c = class.cast(v).ok_or_else(|| TransientError::Malformed {
                file: file.into(),
                detail: format!(
                    "variable `{}`: stored {} value {v} at index {i} does not fit its class {}",
                    self.header.name,
                    type_name(self.storage),
                    class.name()
                ),
            })?;
            f(i, c)
        };
        macro_rules! each {
            ($t:ty, $n:literal, $conv:expr) => {{
                for (i, c) in self.data.chunks_exact($n).enumerate() {
                    let mut a = [0u8; $n];
                    a.copy_from_slice(c);
                    let v: $t = if be { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) };
                    put(i, $conv(v))?;
                }
            }};
        }
        match self.storage {
            MI_INT8 => each!(i8, 1, f64::from),
            MI_UINT8 => each!(u8, 1, f64::from),
            MI_INT16 => each!(i16, 2, f64::from),
            MI_UINT16 => each!(u16, 2, f64::from),
            MI_INT32 => each!(i32, 4, f64::from),
            MI_UINT32 => each!(u32, 4, f64::from),
            MI_SINGLE => each!(f32, 4, f64::from),
            MI_DOUBLE => each!(f64, 8, |v: f64| v),
            MI_INT64 => each!(i64, 8, |v: i64| v as f64),
            MI_UINT64 => each!(u64, 8, |v: u64| v as f64),
            other => {
                return Err(TransientError::Malformed {
                    file: file.into(),
                    detail: format!("variable `{}`: {} is not numeric", self.header.name, type_name(other)),
                });
            }
        }
        Ok(())
    }

    /// All values as `f64` (class values), column-major; NaN/Inf rejected.
    ///
    /// # Errors
    /// [`TransientError::NonFinite`] naming the variable; as `for_each`.
    pub(crate) fn to_f64(&self, file: &Path) -> Result<Vec<f64>> {
        let mut out = Vec::with_capacity(self.len());
        self.for_each(file, |i, v| {
            if !v.is_finite() {
                return Err(self.non_finite(file, i));
            }
            out.push(v);
            Ok(())
        })?;
        Ok(out)
    }

    /// All values as `f32` (class values rounded to f32), column-major; NaN/Inf (also after rounding)
    /// rejected.
    ///
    /// # Errors
    /// [`TransientError::NonFinite`] naming the variable; as `for_each`.
    pub(crate) fn to_f32(&self, file: &Path) -> Result<Vec<f32>> {
        let mut out = Vec::with_capacity(self.len());
        self.for_each(file, |i, v| {
            let x = v as f32;
            if !x.is_finite() {
                return Err(self.non_finite(file, i));
            }
            out.push(x);
            Ok(())
        })?;
        Ok(out)
    }

    /// All values as `f32`, column-major, NaN and infinities (a map's "no value") as NaN.
    ///
    /// # Errors
    /// As `for_each`.
    pub(crate) fn to_f32_map(&self, file: &Path) -> Result<Vec<f32>> {
        let mut out = Vec::with_capacity(self.len());
        self.for_each(file, |_, v| {
            let x = v as f32;
            out.push(if x.is_finite() { x } else { f32::NAN });
            Ok(())
        })?;
        Ok(out)
    }

    /// Calls `f(index, value)` for every element in column-major order with the class value rounded to
    /// `f32`, rejecting NaN/Inf (also after rounding). Lets callers place values without an intermediate copy.
    ///
    /// # Errors
    /// [`TransientError::NonFinite`] naming the variable; as `for_each`.
    pub(crate) fn for_each_f32(&self, file: &Path, mut f: impl FnMut(usize, f32)) -> Result<()> {
        self.for_each(file, |i, v| {
            let x = v as f32;
            if !x.is_finite() {
                return Err(self.non_finite(file, i));
            }
            f(i, x);
            Ok(())
        })
    }

    /// The single value of a 1×1 array.
    ///
    /// # Errors
    /// [`TransientError::WrongShape`] when the array does not hold exactly one element; as `to_f64`.
    pub(crate) fn scalar(&self, file: &Path) -> Result<f64> {
        let v = self.to_f64(file)?;
        match v.as_slice() {
            [x] => Ok(*x),
            _ => Err(TransientError::WrongShape {
                file: file.into(),
                field: self.header.name.clone(),
                expected: "a scalar (1×1)".into(),
                found: self.header.describe(),
            }),
        }
    }

    fn non_finite(&self, file: &Path, index: usize) -> TransientError {
        TransientError::NonFinite { file: file.into(), field: self.header.name.clone(), index }
    }
}

/// Error constructors bound to a file.
#[derive(Debug, Clone, Copy)]
struct Errs<'p> {
    file: &'p Path,
}

impl Errs<'_> {
    fn truncated(self, detail: String) -> TransientError {
        TransientError::Truncated { file: self.file.into(), detail }
    }

    fn malformed(self, detail: String) -> TransientError {
        TransientError::Malformed { file: self.file.into(), detail }
    }
}

/// Bytes of padding after `len` bytes of data to reach a multiple of 8.
fn pad8(len: usize) -> usize {
    (8 - len % 8) % 8
}

/// Inflates the zlib stream `data`, stopping after `limit` bytes of output.
fn inflate(data: &[u8], limit: usize) -> std::io::Result<Vec<u8>> {
    let cap = limit.min(data.len().saturating_mul(MAX_INFLATE_RATIO)).min(1 << 30);
    let mut out = Vec::with_capacity(cap);
    flate2::read::ZlibDecoder::new(data).take(limit as u64).read_to_end(&mut out)?;
    Ok(out)
}

/// Reads the inner tag and the header of an `miCOMPRESSED` element by inflating a prefix of its stream:
/// first [`SMALL_PREFIX`] bytes (enough for nearly every header), then [`HEADER_PREFIX`] when the header
/// did not fit. Returns the inner `miMATRIX` byte count and the header.
fn compressed_header(data: &[u8], endian: Endian, err: &Errs<'_>, what: &str) -> Result<(usize, VarHeader)> {
    let mut limit = SMALL_PREFIX;
    loop {
        let prefix = inflate(data, limit)
            .map_err(|e| err.malformed(format!("{what}: bad zlib stream in miCOMPRESSED element: {e}")))?;
        let inner = prefix
            .get(..8)
            .ok_or_else(|| err.truncated(format!("{what}: the compressed stream ends before its inner tag")))?;
        let inner_type = endian.u32([inner[0], inner[1], inner[2], inner[3]]);
        let inner_len = endian.u32([inner[4], inner[5], inner[6], inner[7]]) as usize;
        if inner_type != MI_MATRIX {
            return Err(err.malformed(format!(
                "{what}: a compressed element holds {}, expected miMATRIX",
                type_name(inner_type)
            )));
        }
        if inner_len > data.len().saturating_mul(MAX_INFLATE_RATIO).saturating_add(64) {
            return Err(err.malformed(format!(
                "{what}: the inner element declares {inner_len} bytes, more than {} compressed bytes can hold",
                data.len()
            )));
        }
        let avail = prefix.len() - 8;
        let body = &prefix[8..8 + inner_len.min(avail)];
        match parse_header(body, endian, err, what) {
            // The header may continue beyond the prefix: inflate more.
            Err(TransientError::Truncated { .. }) if prefix.len() == limit && limit < HEADER_PREFIX => {
                limit = HEADER_PREFIX;
            }
            r => return r.map(|h| (inner_len, h)),
        }
    }
}

/// One sub-element: its data type, and the byte range of its data within the parent, and where the next
/// sub-element begins.
struct Sub {
    dtype: u32,
    start: usize,
    end: usize,
    next: usize,
}

/// Reads the sub-element tag at `pos` of `p` (normal or small data element format).
fn sub_element(p: &[u8], pos: usize, endian: Endian, err: &Errs<'_>, what: &str, field: &str) -> Result<Sub> {
    let tag = p.get(pos..pos.saturating_add(8)).ok_or_else(|| {
        err.truncated(format!("{what}: the matrix element ends before its {field} (at byte {pos} of {})", p.len()))
    })?;
    let first = endian.u32([tag[0], tag[1], tag[2], tag[3]]);
    let small_len = (first >> 16) as usize;
    if small_len != 0 {
        // Small data element: 2 bytes of count and 2 of type (in file order), then up to 4 bytes of data.
        if small_len > 4 {
            return Err(err.malformed(format!("{what}: small data element of {small_len} bytes in its {field}")));
        }
        return Ok(Sub { dtype: first & 0xFFFF, start: pos + 4, end: pos + 4 + small_len, next: pos + 8 });
    }
    let len = endian.u32([tag[4], tag[5], tag[6], tag[7]]) as usize;
    let start = pos + 8;
    let end = start.checked_add(len).filter(|&e| e <= p.len()).ok_or_else(|| {
        err.truncated(format!("{what}: its {field} declares {len} bytes but only {} remain", p.len() - start))
    })?;
    Ok(Sub { dtype: first, start, end, next: end.saturating_add(pad8(len)) })
}

/// Parses array flags, dimensions and name at the start of an `miMATRIX` element's data.
fn parse_header(p: &[u8], endian: Endian, err: &Errs<'_>, what: &str) -> Result<VarHeader> {
    if p.is_empty() {
        return Err(err.malformed(format!("{what}: empty miMATRIX element")));
    }
    let flags = sub_element(p, 0, endian, err, what, "array flags")?;
    let f = &p[flags.start..flags.end];
    if flags.dtype != MI_UINT32 || f.len() < 4 {
        return Err(err.malformed(format!("{what}: array flags are {} of {} bytes", type_name(flags.dtype), f.len())));
    }
    let word = endian.u32([f[0], f[1], f[2], f[3]]);
    let class = Class::from_code((word & 0xFF) as u8);
    let complex = word & 0x0800 != 0;
    let dsub = sub_element(p, flags.next, endian, err, what, "dimensions")?;
    if dsub.dtype != MI_INT32 || (dsub.end - dsub.start) % 4 != 0 || dsub.end == dsub.start {
        return Err(err.malformed(format!(
            "{what}: dimensions are {} of {} bytes, expected miINT32",
            type_name(dsub.dtype),
            dsub.end - dsub.start
        )));
    }
    let mut dims = Vec::with_capacity((dsub.end - dsub.start) / 4);
    for c in p[dsub.start..dsub.end].chunks_exact(4) {
        let d = endian.u32([c[0], c[1], c[2], c[3]]) as i32;
        let d = usize::try_from(d).map_err(|_| err.malformed(format!("{what}: negative dimension {d}")))?;
        dims.push(d);
    }
    let nsub = sub_element(p, dsub.next, endian, err, what, "name")?;
    if !matches!(nsub.dtype, MI_INT8 | MI_UINT8 | MI_UTF8) {
        return Err(err.malformed(format!("{what}: its name is {}, expected miINT8", type_name(nsub.dtype))));
    }
    let name = String::from_utf8_lossy(&p[nsub.start..nsub.end]).into_owned();
    Ok(VarHeader { name, class, complex, dims })
}

/// Finds the real part of a numeric `miMATRIX` element's data: its storage type and byte range.
fn real_part(p: &[u8], endian: Endian, err: &Errs<'_>, what: &str) -> Result<(u32, std::ops::Range<usize>)> {
    let flags = sub_element(p, 0, endian, err, what, "array flags")?;
    let dims = sub_element(p, flags.next, endian, err, what, "dimensions")?;
    let name = sub_element(p, dims.next, endian, err, what, "name")?;
    let real = sub_element(p, name.next, endian, err, what, "real part")?;
    Ok((real.dtype, real.start..real.end))
}

#[cfg(test)]
mod tests;
