//! Readers and writers for the standard NLOS capture formats, with format detection from content.
//!
//! | format | read | write | module |
//! |---|---|---|---|
//! | Stanford LCT `.mat` (O'Toole 2018) | ✓ | – | [`mat`] |
//! | Tsai 2019 `.mat` | ✓ | – | [`mat`] |
//! | Stanford f-k `.mat` (Lindell 2019), MAT v5 and v7.3 | ✓ | – | [`mat`], [`hdf5`] |
//! | general-NLOS `data.mat` + `setup.mat` (paired spots, curved wall; bin width given) | ✓ | – | [`mat`] |
//! | Zaragoza Z-NLOS HDF5 | ✓ | – | [`hdf5`] |
//! | y-tal HDF5_TAL | ✓ | ✓ | [`hdf5`] |
//! | `.npy` + `.json` sidecar | ✓ | ✓ | [`npy`] |
//! | OpenEXR | ✓ | ✓ | [`exr`] |

use std::path::{Path, PathBuf};

use crate::error::{Result, TransientError};
use crate::transient::Transient;

pub mod exr;
pub mod hdf5;
mod jitter_file;
pub mod mat;
pub mod npy;
mod sidecar;

/// A transient file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Format {
    /// Stanford LCT `.mat` (O'Toole et al. 2018): `rect_data` (N,N,T), `width`; 4 ps bins.
    LctMat,
    /// Tsai et al. 2019 `.mat`: `transient` (M,T), `lighting` (M,3).
    TsaiMat,
    /// Stanford f-k `.mat` (Lindell et al. 2019): `meas` (N,N,T), `tofgrid` (N,N); 32 ps bins. MAT v5 or v7.3.
    FkMat,
    /// Zaragoza Z-NLOS HDF5 (`data`, `deltaT`, `t0`, `cameraGridPositions`, `laserGridPositions`, …).
    ZNlos,
    /// Z-NLOS as NeTF preprocessed it, MAT v5: `data` (T,A,B), `cameraGridPositions` (3,N), `deltaT`, …
    ZNlosMat,
    /// general-NLOS (irregular relay surfaces), MAT v5: `data.mat` (`data`, A×B×T) with `setup.mat`
    /// (`laserpoints`, `detectpoints`, A×B×3) beside it: a paired scan; the bin width comes from
    /// [`ReadOptions::bin_width`].
    GeneralNlosMat,
    /// y-tal HDF5_TAL (`H`, `H_format`, `sensor_grid_xyz`, `laser_grid_xyz`, `delta_t`, `t_start`, …).
    Tal,
    /// NumPy `.npy` (data) with a `.json` sidecar (geometry and time axis): this project's exchange format.
    NpyJson,
    /// OpenEXR: one f32 channel, width = bins, height = measurements, geometry in header attributes.
    Exr,
}

impl Format {
    /// Every format, in detection order.
    pub const ALL: [Format; 9] = [
        Format::LctMat,
        Format::TsaiMat,
        Format::FkMat,
        Format::ZNlosMat,
        Format::GeneralNlosMat,
        Format::ZNlos,
        Format::Tal,
        Format::NpyJson,
        Format::Exr,
    ];

    /// Short name, as accepted by [`Format::from_name`] and the CLI.
    pub fn name(self) -> &'static str {
        match self {
            Format::LctMat => "lct-mat",
            Format::TsaiMat => "tsai-mat",
            Format::FkMat => "fk-mat",
            Format::ZNlos => "znlos",
            Format::ZNlosMat => "znlos-mat",
            Format::GeneralNlosMat => "general-nlos",
            Format::Tal => "tal",
            Format::NpyJson => "npy",
            Format::Exr => "exr",
        }
    }

    /// Parses a short name (see [`Format::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name().eq_ignore_ascii_case(name))
    }

    /// Whether this project can write the format.
    pub fn can_write(self) -> bool {
        matches!(self, Format::Tal | Format::NpyJson | Format::Exr)
    }

    /// The writable format conventionally used for a file extension (`.hdf5`/`.h5` → HDF5_TAL, `.npy` →
    /// npy + JSON, `.exr` → EXR).
    pub fn for_writing_extension(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "hdf5" | "h5" | "tal" => Some(Format::Tal),
            "npy" | "json" => Some(Format::NpyJson),
            "exr" => Some(Format::Exr),
            _ => None,
        }
    }
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The container a file's first bytes announce.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Container {
    /// MATLAB level-5 MAT-file (v5/v6/v7).
    MatV5,
    /// MATLAB v7.3: a 512-byte MATLAB header followed by HDF5.
    MatV73,
    /// Plain HDF5.
    Hdf5,
    /// NumPy `.npy`.
    Npy,
    /// OpenEXR.
    Exr,
}

/// The HDF5 signature.
pub(crate) const HDF5_MAGIC: &[u8; 8] = b"\x89HDF\r\n\x1a\n";

pub(crate) fn sniff(bytes: &[u8]) -> Option<Container> {
    if bytes.starts_with(HDF5_MAGIC) {
        return Some(Container::Hdf5);
    }
    if bytes.starts_with(b"\x93NUMPY") {
        return Some(Container::Npy);
    }
    if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        return Some(Container::Exr);
    }
    if bytes.starts_with(b"MATLAB") && bytes.len() >= 128 {
        if bytes.len() >= 520 && &bytes[512..520] == HDF5_MAGIC {
            return Some(Container::MatV73);
        }
        return Some(Container::MatV5);
    }
    None
}

/// Detects the format of `bytes` (the content of `file`, which is used for messages and, for `.npy`,
/// to find the sidecar).
///
/// # Errors
/// [`TransientError::UnknownFormat`] when no format matches; container errors while peeking inside.
pub fn detect_bytes(bytes: &[u8], file: &Path) -> Result<Format> {
    match sniff(bytes) {
        Some(Container::MatV5) => mat::classify(bytes, file),
        Some(Container::MatV73) => hdf5::classify(&bytes[512..], file),
        Some(Container::Hdf5) => hdf5::classify(bytes, file),
        Some(Container::Npy) => Ok(Format::NpyJson),
        Some(Container::Exr) => Ok(Format::Exr),
        None if bytes.len() < 8 => Err(TransientError::Truncated {
            file: file.into(),
            detail: format!("only {} bytes, too short for any format's header", bytes.len()),
        }),
        None => Err(TransientError::UnknownFormat {
            file: file.into(),
            reason: format!("first bytes {:02x?} match no known signature", &bytes[..8.min(bytes.len())]),
        }),
    }
}

/// Detects the format of a file from its content.
///
/// # Errors
/// [`TransientError::Io`] when the file cannot be read; as [`detect_bytes`].
pub fn detect(path: impl AsRef<Path>) -> Result<Format> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    detect_bytes(&bytes, path)
}

/// What a reader needs to know that some files do not say.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReadOptions {
    /// The bin width, metres of path, for formats whose files do not store it ([`Format::GeneralNlosMat`]:
    /// 32 ps = 0.0096 m for the published capture). Refused for a format that stores or defines its own, so
    /// that a file is never read with two different time axes.
    pub bin_width: Option<f64>,
}

impl ReadOptions {
    /// Options with a bin width given in picoseconds (converted at the speed of light the capture formats
    /// use, `c = 3e8` m/s: 32 ps is 9.6 mm of path).
    pub fn with_bin_width_ps(ps: Option<f64>) -> Self {
        Self { bin_width: ps.map(|ps| ps * 1e-12 * CAPTURE_SPEED_OF_LIGHT) }
    }
}

pub use crate::time_axis::CAPTURE_SPEED_OF_LIGHT;

/// Reads a transient from a file in any supported format, detected from the content.
///
/// For the npy format, pass either the `.npy` or its `.json` sidecar.
///
/// # Errors
/// Any [`TransientError`]; each names the file and the field.
pub fn read(path: impl AsRef<Path>) -> Result<Transient> {
    read_with(path, &ReadOptions::default())
}

/// [`read`] with what the file does not say ([`ReadOptions`]).
///
/// # Errors
/// As [`read`]; [`TransientError::InvalidValue`] for a bin width that is not one, or one given for a format
/// that has its own; [`TransientError::MissingField`] for a general-NLOS file without one.
pub fn read_with(path: impl AsRef<Path>, options: &ReadOptions) -> Result<Transient> {
    let path = path.as_ref();
    if options.bin_width.is_some() {
        // The format is known only after detection; the general-NLOS files are the only ones that need it.
        let bytes = read_file(path)?;
        let format = detect_bytes(&bytes, path)?;
        return read_bytes_with(&bytes, format, path, options);
    }
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) {
        return npy::read_pair(&path.with_extension("npy"), path);
    }
    let bytes = read_file(path)?;
    let format = detect_bytes(&bytes, path)?;
    if format == Format::NpyJson {
        // read_pair's error for a missing sidecar says what the sidecar is and how to write it.
        return npy::read_pair(path, &path.with_extension("json"));
    }
    read_bytes_as(&bytes, format, path)
}

/// Reads a transient from bytes already in memory, in a known format. `file` names them in errors (and,
/// for [`Format::NpyJson`], locates the `.json` sidecar beside it).
///
/// # Errors
/// Any [`TransientError`].
pub fn read_bytes_as(bytes: &[u8], format: Format, file: &Path) -> Result<Transient> {
    read_bytes_with(bytes, format, file, &ReadOptions::default())
}

/// [`read_bytes_as`] with what the file does not say ([`ReadOptions`]).
///
/// # Errors
/// As [`read_with`].
pub fn read_bytes_with(bytes: &[u8], format: Format, file: &Path, options: &ReadOptions) -> Result<Transient> {
    if let Some(w) = options.bin_width {
        mat::general_nlos::check_bin_width(w, file)?;
        if format != Format::GeneralNlosMat {
            return Err(TransientError::InvalidValue {
                file: file.into(),
                field: "bin width".into(),
                reason: format!(
                    "a bin width was given, but this {format} file has its own time axis; the option is for \
                     files that do not store one (general-NLOS)"
                ),
            });
        }
    }
    let t = match format {
        Format::LctMat | Format::TsaiMat | Format::FkMat if sniff(bytes) == Some(Container::MatV5) => {
            mat::read(bytes, format, file)?
        }
        Format::LctMat | Format::TsaiMat | Format::FkMat if sniff(bytes) == Some(Container::MatV73) => {
            hdf5::read(&bytes[512..], format, file)?
        }
        Format::LctMat | Format::TsaiMat | Format::FkMat => {
            return Err(TransientError::UnknownFormat { file: file.into(), reason: "not a MAT-file".into() });
        }
        Format::ZNlosMat if sniff(bytes) == Some(Container::MatV5) => mat::read(bytes, format, file)?,
        Format::GeneralNlosMat if sniff(bytes) == Some(Container::MatV5) => {
            mat::read_general_nlos(bytes, file, options)?
        }
        Format::GeneralNlosMat => {
            return Err(TransientError::Unsupported {
                file: file.into(),
                what: "a general-NLOS file saved as MAT v7.3 (HDF5); save it with `-v7` (scipy.io.savemat writes v5)"
                    .into(),
            });
        }
        Format::ZNlosMat => {
            return Err(TransientError::Unsupported {
                file: file.into(),
                what: "NeTF's Z-NLOS `.mat` saved as MAT v7.3 (HDF5); save it with `-v7` or read the dataset's \
                       own HDF5"
                    .into(),
            });
        }
        Format::ZNlos | Format::Tal => hdf5::read(bytes, format, file)?,
        Format::NpyJson => {
            let sidecar = read_file(&file.with_extension("json"))?;
            npy::read(bytes, &sidecar, file)?
        }
        Format::Exr => exr::read(bytes, file)?,
    };
    t.validate().map_err(|e| with_file(e, file))?;
    // A point list that forms a regular grid is a grid, whatever the format wrote.
    Ok(t.with_grid_layout())
}

/// Writes `transient` to `path` in `format`, atomically: the bytes go to a temporary file beside `path`
/// which is then renamed over it, so a crash never leaves a half-written file. The npy format also writes
/// the `.json` sidecar beside the `.npy`.
///
/// # Errors
/// [`TransientError::CannotWrite`] for a read-only format or a transient the format cannot hold;
/// [`TransientError::Io`].
pub fn write(transient: &Transient, path: impl AsRef<Path>, format: Format) -> Result<()> {
    let path = path.as_ref();
    match format {
        Format::Tal => write_atomic(path, &hdf5::write_tal(transient, path)?),
        Format::Exr => write_atomic(path, &exr::write(transient, path)?),
        Format::NpyJson => {
            let npy_path = path.with_extension("npy");
            let (npy, json) = npy::write(transient, &npy_path)?;
            write_atomic(&npy_path.with_extension("json"), &json)?;
            write_atomic(&npy_path, &npy)
        }
        other => Err(TransientError::CannotWrite {
            file: path.into(),
            format: other.name().into(),
            reason: "this format is read-only; write tal (.hdf5), npy or exr instead".into(),
        }),
    }
}

/// Reads a whole file.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| TransientError::Io { file: path.into(), source })
}

/// Writes `bytes` to `path` atomically: the whole file or the previous one, never a part
/// (`atomic_write_file`, the one implementation every crate of the workspace writes through: a uniquely
/// named temporary file in the same directory, synced, renamed over `path`).
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write as _;
    let io = |source| TransientError::Io { file: path.into(), source };
    let mut file = atomic_write_file::AtomicWriteFile::open(path).map_err(io)?;
    file.write_all(bytes).map_err(io)?;
    file.commit().map_err(io)
}

/// Replaces the `<memory>` file name of a validation error with the real file.
pub(crate) fn with_file(e: TransientError, file: &Path) -> TransientError {
    use TransientError as E;
    let f: PathBuf = file.into();
    match e {
        E::InvalidValue { field, reason, .. } => E::InvalidValue { file: f, field, reason },
        E::NonFinite { field, index, .. } => E::NonFinite { file: f, field, index },
        E::WrongShape { field, expected, found, .. } => E::WrongShape { file: f, field, expected, found },
        other => other,
    }
}
