//! OpenEXR: one f32 channel, width = bins, height = measurements, geometry in header attributes.
//!
//! Written files have a single scan-line layer with one `FLOAT` channel named `Y`, ZIP-compressed (lossless,
//! so the round trip is bit-exact). Pixel `(x = k, y = m)` is bin `k` of measurement `m`. The header holds:
//! - `nlos` (text): the same JSON as the `.npy` sidecar without the `data`, `dtype` and `shape` entries
//!   (schema: `docs/formats/npy-json.md`). This attribute is authoritative.
//! - human-readable copies for EXR viewers: `nlos.t0`, `nlos.bin_width` (metres of path, double),
//!   `nlos.bin_width_ps` (picoseconds at the capture formats' c = 3e8 m/s, double), `nlos.pattern` (text), `nlos.measurements` and
//!   `nlos.bins` (int).
//!
//! Reading accepts a single-layer scan-line or tiled image with one channel of any name, or a channel named
//! `Y` or `R` among several; `HALF`, `FLOAT` and `UINT` samples (converted to `f32`); any compression
//! the `exr` crate decodes.

use std::io::Cursor;
use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Blocks, Compression, Encoding, FlatSamples, Image, ImageAttributes, Layer,
    LayerAttributes, LineOrder, MetaData, ReadChannels, ReadLayers, SmallVec, Text, WritableImage,
};

use crate::error::{Result, TransientError};
use crate::formats::sidecar::{self, Ctx};
use crate::transient::Transient;

/// Name of the channel written.
pub const CHANNEL: &str = "Y";
/// Name of the text attribute that holds the geometry JSON.
pub const ATTRIBUTE: &str = "nlos";
/// Largest width or height of an EXR data window (the format's coordinates must stay below `i32::MAX / 2`).
pub const MAX_DIMENSION: usize = (i32::MAX / 2 - 1) as usize;
/// Most bins written: a 16-line ZIP block of `bins` f32 values must fit in a chunk (its size is an `i32`).
pub const MAX_BINS: usize = 1 << 24;
/// Largest decoded-to-file size ratio accepted when reading (deflate cannot exceed about 1032:1): a guard
/// against tiny files that declare huge images.
const MAX_EXPANSION: usize = 2048;

/// Decodes EXR bytes.
///
/// # Errors
/// [`TransientError::Malformed`] for a file the `exr` crate rejects (or panics on);
/// [`TransientError::Unsupported`] for multi-layer or deep images; [`TransientError::MissingField`] when the
/// `nlos` attribute or a usable channel is absent; [`TransientError::WrongShape`] when the image size does
/// not match the geometry; [`TransientError::NonFinite`] for NaN/Inf samples; the geometry errors of the
/// JSON (field `exr attribute nlos.…`).
pub fn read(bytes: &[u8], file: &Path) -> Result<Transient> {
    let malformed = |e: exr::error::Error| TransientError::Malformed { file: file.into(), detail: format!("EXR: {e}") };
    let meta = guard(file, || MetaData::read_from_buffered(Cursor::new(bytes), false))?.map_err(malformed)?;
    let header = match meta.headers.as_slice() {
        [one] => one,
        more => {
            return Err(TransientError::Unsupported {
                file: file.into(),
                what: format!("EXR with {} layers (a transient is one layer)", more.len()),
            });
        }
    };
    if header.deep {
        return Err(TransientError::Unsupported { file: file.into(), what: "deep EXR data".into() });
    }
    let names: Vec<String> = header.channels.list.iter().map(|c| c.name.to_string()).collect();
    let channel = pick_channel(&names).ok_or_else(|| TransientError::MissingField {
        file: file.into(),
        field: "exr channel".into(),
        hint: format!("found channels {names:?}; a transient EXR has one channel, or one named Y or R"),
    })?;
    let (bins, measurements) = (header.layer_size.0, header.layer_size.1);
    let decoded = header
        .channels
        .list
        .iter()
        .map(|c| c.sample_type.bytes_per_sample())
        .sum::<usize>()
        .checked_mul(bins)
        .and_then(|n| n.checked_mul(measurements));
    if decoded.is_none_or(|n| n > bytes.len().saturating_mul(MAX_EXPANSION).max(1 << 20)) {
        return Err(TransientError::Malformed {
            file: file.into(),
            detail: format!(
                "EXR declares a {bins} × {measurements} image, far more than its {} bytes hold",
                bytes.len()
            ),
        });
    }
    let attrs = [&header.own_attributes.other, &header.shared_attributes.other];
    let key = Text::new_or_none(ATTRIBUTE).unwrap_or_default();
    let json = match attrs.iter().find_map(|a| a.get(&key)) {
        Some(AttributeValue::Text(t)) => t.as_slice().to_vec(),
        Some(other) => {
            return Err(TransientError::WrongType {
                file: file.into(),
                field: "exr attribute nlos".into(),
                expected: "text (the geometry JSON)".into(),
                found: format!("{other:?}").chars().take(60).collect(),
            });
        }
        None => {
            return Err(TransientError::MissingField {
                file: file.into(),
                field: "exr attribute nlos".into(),
                hint: "this EXR has no NLOS geometry; it was not written by nlos (convert the capture with \
                       `nlos convert`, or add a text attribute `nlos` holding the JSON of docs/formats/npy-json.md)"
                    .into(),
            });
        }
    };
    let geometry = sidecar::parse(&json, &Ctx { file, prefix: "exr attribute nlos" })?;
    if (geometry.measurements(), geometry.time.bins) != (measurements, bins) {
        return Err(TransientError::WrongShape {
            file: file.into(),
            field: "exr data window".into(),
            expected: format!(
                "{} bins wide × {} measurements high (from the nlos attribute)",
                geometry.time.bins,
                geometry.measurements()
            ),
            found: format!("{bins} × {measurements}"),
        });
    }
    let data = decode_channels(bytes, file, &[names[channel].as_str()], measurements * bins)?.remove(0);
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(TransientError::NonFinite {
            file: file.into(),
            field: format!("exr channel {}", names[channel]),
            index: i,
        });
    }
    let (scan, time) = geometry.into_parts();
    Transient::new(scan, time, data).map_err(|e| super::with_file(e, file))
}

/// Reads an EXR image that is not a capture — a depth or normal map — as `(values, shape)` in C order: one
/// channel (the only one, `Y` or `Z`… as `pick_channel`) gives shape `(height, width)`, three channels
/// named `R, G, B` or `X, Y, Z` give `(height, width, 3)` with x, y, z from R, G, B (or X, Y, Z). Row 0 is the
/// image's top. NaN and infinities are a map's "no value" and come back as NaN.
///
/// # Errors
/// [`TransientError::Io`], [`TransientError::Malformed`] (including a decoder panic),
/// [`TransientError::Unsupported`] for several layers, deep data or a channel set that is neither one
/// channel nor R, G, B / X, Y, Z.
pub fn read_image(path: &Path) -> Result<(Vec<f32>, Vec<usize>)> {
    decode_image(&super::read_file(path)?, path)
}

/// [`read_image`] on the bytes of a file (`file` names it in errors).
///
/// # Errors
/// As [`read_image`].
pub fn decode_image(bytes: &[u8], file: &Path) -> Result<(Vec<f32>, Vec<usize>)> {
    let malformed = |e: exr::error::Error| TransientError::Malformed { file: file.into(), detail: format!("EXR: {e}") };
    let meta = guard(file, || MetaData::read_from_buffered(Cursor::new(&bytes), false))?.map_err(malformed)?;
    let [header] = meta.headers.as_slice() else {
        return Err(TransientError::Unsupported {
            file: file.into(),
            what: "EXR with several layers (a map is one)".into(),
        });
    };
    if header.deep {
        return Err(TransientError::Unsupported { file: file.into(), what: "deep EXR data".into() });
    }
    let (width, height) = (header.layer_size.0, header.layer_size.1);
    if width.saturating_mul(height).saturating_mul(12) > bytes.len().saturating_mul(MAX_EXPANSION).max(1 << 20) {
        return Err(TransientError::Malformed {
            file: file.into(),
            detail: format!("EXR declares a {width} × {height} image, far more than its {} bytes hold", bytes.len()),
        });
    }
    let names: Vec<String> = header.channels.list.iter().map(|c| c.name.to_string()).collect();
    let wanted: Vec<usize> = if names.len() == 1 {
        vec![0]
    } else if let Some(rgb) = [["R", "G", "B"], ["X", "Y", "Z"]]
        .iter()
        .find_map(|set| set.iter().map(|n| names.iter().position(|m| m == n)).collect::<Option<Vec<_>>>())
    {
        rgb
    } else {
        return Err(TransientError::Unsupported {
            file: file.into(),
            what: format!("EXR map with channels {names:?}: a depth map has one channel, a normal map R, G, B"),
        });
    };
    let wanted: Vec<&str> = wanted.iter().map(|&i| names[i].as_str()).collect();
    let planes = decode_channels(bytes, file, &wanted, width * height)?;
    let k = planes.len();
    let values: Vec<f32> = (0..width * height)
        .flat_map(|i| planes.iter().map(move |p| if p[i].is_finite() { p[i] } else { f32::NAN }))
        .collect();
    let shape = if k == 1 { vec![height, width] } else { vec![height, width, k] };
    Ok((values, shape))
}

/// Decodes the named channels of the first layer of an EXR image as `f32` planes of `pixels` samples each,
/// turning a decoder panic into [`TransientError::Malformed`].
fn decode_channels(bytes: &[u8], file: &Path, names: &[&str], pixels: usize) -> Result<Vec<Vec<f32>>> {
    let malformed = |e: exr::error::Error| TransientError::Malformed { file: file.into(), detail: format!("EXR: {e}") };
    let image = guard(file, || {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .non_parallel()
            .from_buffered(Cursor::new(bytes))
    })?
    .map_err(malformed)?;
    let layer = image
        .layer_data
        .first()
        .ok_or_else(|| TransientError::Malformed { file: file.into(), detail: "EXR: no layer decoded".into() })?;
    names
        .iter()
        .map(|name| {
            let samples = layer
                .channel_data
                .list
                .iter()
                .find(|c| c.name.to_string() == *name)
                .map(|c| &c.sample_data)
                .ok_or_else(|| TransientError::Malformed {
                    file: file.into(),
                    detail: "EXR: channel not decoded".into(),
                })?;
            let v: Vec<f32> = match samples {
                FlatSamples::F16(v) => v.iter().map(|h| h.to_f32()).collect(),
                FlatSamples::F32(v) => v.clone(),
                FlatSamples::U32(v) => v.iter().map(|&u| u as f32).collect(),
            };
            if v.len() != pixels {
                return Err(TransientError::Malformed {
                    file: file.into(),
                    detail: format!("EXR: decoded {} samples for an image of {pixels}", v.len()),
                });
            }
            Ok(v)
        })
        .collect()
}

/// The channel to read: the only one, else `Y`, else `R`.
fn pick_channel(names: &[String]) -> Option<usize> {
    if names.len() == 1 {
        return Some(0);
    }
    ["Y", "R"].iter().find_map(|want| names.iter().position(|n| n == want))
}

/// Runs a call into the `exr` crate, turning a panic into [`TransientError::Malformed`]. This guards
/// against a dependency's panic on malformed input: our readers must return errors, never panic.
fn guard<T>(file: &Path, f: impl FnOnce() -> T + std::panic::UnwindSafe) -> Result<T> {
    std::panic::catch_unwind(f).map_err(|panic| {
        let msg = panic
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        TransientError::Malformed { file: file.into(), detail: format!("EXR decoder failed: {msg}") }
    })
}

/// Encodes `transient` as EXR bytes.
///
/// # Errors
/// [`TransientError::CannotWrite`] when the image would exceed the format's limits ([`MAX_DIMENSION`]
/// measurements, [`MAX_BINS`] bins) or the encoder fails.
pub fn write(transient: &Transient, file: &Path) -> Result<Vec<u8>> {
    let cannot = |reason: String| TransientError::CannotWrite { file: file.into(), format: "exr".into(), reason };
    let (m, bins) = (transient.measurements(), transient.bins());
    if m > MAX_DIMENSION {
        return Err(cannot(format!("{m} measurements exceed the EXR height limit of {MAX_DIMENSION}; use npy or tal")));
    }
    if bins > MAX_BINS {
        return Err(cannot(format!("{bins} bins exceed the limit of {MAX_BINS} for EXR; rebin, or use npy or tal")));
    }
    let time = transient.time();
    let json = sidecar::to_json(transient.scan(), time, None, false, file, "exr")?;
    let json = std::str::from_utf8(&json).ok().and_then(Text::new_or_none);
    let json = json.ok_or_else(|| cannot("the geometry JSON is not representable as EXR text".into()))?;
    let text = |s: &str| Text::new_or_none(s).ok_or_else(|| cannot(format!("{s:?} is not EXR text")));
    let mut attributes = LayerAttributes::default();
    let pattern = transient.scan().pattern_name();
    let mut entries = vec![
        (ATTRIBUTE, AttributeValue::Text(json)),
        ("nlos.t0", AttributeValue::F64(time.t0)),
        ("nlos.bin_width", AttributeValue::F64(time.bin_width)),
        ("nlos.bin_width_ps", AttributeValue::F64(time.bin_width_ps())),
        ("nlos.pattern", AttributeValue::Text(text(pattern)?)),
    ];
    for (name, n) in [("nlos.measurements", m), ("nlos.bins", bins)] {
        if let Ok(n) = i32::try_from(n) {
            entries.push((name, AttributeValue::I32(n)));
        }
    }
    for (name, value) in entries {
        attributes.other.insert(text(name)?, value);
    }
    let encoding =
        Encoding { compression: Compression::ZIP16, blocks: Blocks::ScanLines, line_order: LineOrder::Increasing };
    let mut list = SmallVec::new();
    list.push(AnyChannel::new(text(CHANNEL)?, FlatSamples::F32(transient.data().to_vec())));
    let layer = Layer::new((bins, m), attributes, encoding, AnyChannels::sort(list));
    let image = Image::new(ImageAttributes::new(exr::prelude::IntegerBounds::from_dimensions((bins, m))), layer);
    let mut out = Vec::new();
    image.write().non_parallel().to_buffered(Cursor::new(&mut out)).map_err(|e| cannot(format!("EXR encoder: {e}")))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PointSet, Scan, TimeAxis};

    fn sample() -> Result<Transient> {
        let scan = Scan::confocal(PointSet::wall_grid(3, 2, 0.25, 0.25)?);
        let mut t = Transient::zeros(scan, TimeAxis::new(0.5, 0.004, 5)?)?;
        for (i, v) in t.data_mut().iter_mut().enumerate() {
            *v = i as f32 * 0.25 - 1.0;
        }
        Ok(t)
    }

    #[test]
    fn round_trip_and_attributes() -> Result<()> {
        let t = sample()?;
        let bytes = write(&t, Path::new("a.exr"))?;
        let back = read(&bytes, Path::new("a.exr"))?;
        assert_eq!(back, t);
        let meta = MetaData::read_from_buffered(Cursor::new(&bytes), true)
            .map_err(|e| TransientError::Malformed { file: "a.exr".into(), detail: e.to_string() })?;
        let h = &meta.headers[0];
        assert_eq!(h.compression, Compression::ZIP16);
        let other = [&h.own_attributes.other, &h.shared_attributes.other];
        let get = |k: &str| other.iter().find_map(|a| a.get(&Text::from(k)).cloned());
        assert_eq!(get("nlos.t0"), Some(AttributeValue::F64(0.5)));
        assert_eq!(get("nlos.bins"), Some(AttributeValue::I32(5)));
        Ok(())
    }

    #[test]
    fn channel_choice() {
        let s = |v: &[&str]| v.iter().map(|x| (*x).to_owned()).collect::<Vec<_>>();
        assert_eq!(pick_channel(&s(&["transient"])), Some(0));
        assert_eq!(pick_channel(&s(&["B", "G", "R"])), Some(2));
        assert_eq!(pick_channel(&s(&["A", "Y"])), Some(1));
        assert_eq!(pick_channel(&s(&["A", "B"])), None);
    }
}
