//! The JSON description of a transient's scan geometry and time axis, shared by the `.npy` sidecar and
//! the EXR `nlos` header attribute. Schema: `docs/formats/npy-json.md`.
//!
//! Floats are written by serde_json's shortest round-trip printer (`f32` fields as `f32`, `f64` as
//! `f64`), and read back through a correctly rounded `f64` parse (serde_json's `float_roundtrip`
//! feature) followed by a cast for `f32` fields; for every finite `f32` this gives back the same bits
//! (checked exhaustively over all 2³² patterns when the format was designed).
//!
//! Reading is two-step so that a small, hostile JSON cannot make us allocate a huge point set: [`parse`]
//! checks the structure and returns a [`Header`] whose point sets are still compact ([`Points::Axes`]),
//! the caller compares [`Header::measurements`] with the size of the data it holds, and only then calls
//! [`Header::into_parts`].

use std::path::Path;

use glam::Vec3;
use serde::Serialize;
use serde_json::{Map, Value};

use crate::error::{Result, TransientError};
use crate::scan::{Layout, PatternKind, PointSet, Scan, ScanPattern};
use crate::time_axis::TimeAxis;

/// The value of the `format` key.
pub(crate) const FORMAT_NAME: &str = "nlos-transient";
/// The schema version this crate writes and reads.
pub(crate) const VERSION: u64 = 1;

// ---------------------------------------------------------------------------------------------------------
// Writing

/// Extra top-level entries of the npy sidecar (absent in the EXR attribute).
#[derive(Debug, Serialize)]
pub(crate) struct DataEntries<'a> {
    /// File name of the `.npy` beside the sidecar.
    pub data: &'a str,
    /// NumPy dtype string of the data, e.g. `<f4`.
    pub dtype: &'a str,
    /// Shape of the `.npy` array.
    pub shape: &'a [usize],
}

#[derive(Serialize)]
struct HeaderOut<'a> {
    format: &'static str,
    version: u64,
    #[serde(flatten)]
    data: Option<&'a DataEntries<'a>>,
    time: TimeOut,
    scan: ScanOut,
}

#[derive(Serialize)]
struct TimeOut {
    t0: f64,
    bin_width: f64,
    bins: usize,
    includes_device_legs: bool,
}

#[derive(Serialize)]
struct ScanOut {
    pattern: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    points: Option<PointSetOut>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lasers: Option<PointSetOut>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sensors: Option<PointSetOut>,
    laser_device: Option<[f32; 3]>,
    sensor_device: Option<[f32; 3]>,
}

#[derive(Serialize)]
struct PointSetOut {
    #[serde(skip_serializing_if = "Option::is_none")]
    grid: Option<[usize; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    x: Option<Vec<f32>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    y: Option<Vec<f32>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    z: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    points: Option<Vec<[f32; 3]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    normal: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    normals: Option<Vec<[f32; 3]>>,
}

fn arr(v: Vec3) -> [f32; 3] {
    [v.x, v.y, v.z]
}

/// Bitwise equality (so that `-0.0` and `0.0` are told apart and the encoding stays bit-exact).
fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits()
}

/// The separable form `(xs, ys, z)` of a grid whose point `ix + nx·iy` is exactly `(xs[ix], ys[iy], z)`.
fn separable(set: &PointSet) -> Option<(Vec<f32>, Vec<f32>, f32)> {
    let (nx, ny) = set.grid_dims()?;
    if nx.checked_mul(ny) != Some(set.points.len()) || set.points.is_empty() {
        return None;
    }
    let xs: Vec<f32> = set.points[..nx].iter().map(|p| p.x).collect();
    let ys: Vec<f32> = set.points.iter().step_by(nx).map(|p| p.y).collect();
    let z = set.points[0].z;
    let ok = set.points.iter().enumerate().all(|(i, p)| same(p.x, xs[i % nx]) && same(p.y, ys[i / nx]) && same(p.z, z));
    ok.then_some((xs, ys, z))
}

fn point_set_out(set: &PointSet) -> PointSetOut {
    let grid = set.grid_dims().map(|(nx, ny)| [nx, ny]);
    let (x, y, z, points) = match separable(set) {
        Some((xs, ys, z)) => (Some(xs), Some(ys), Some(z), None),
        None => (None, None, None, Some(set.points.iter().copied().map(arr).collect())),
    };
    let shared = set
        .normals
        .first()
        .filter(|n0| set.normals.iter().all(|n| same(n.x, n0.x) && same(n.y, n0.y) && same(n.z, n0.z)));
    let (normal, normals) = match shared {
        Some(n) => (Some(arr(*n)), None),
        None => (None, Some(set.normals.iter().copied().map(arr).collect())),
    };
    PointSetOut { grid, x, y, z, points, normal, normals }
}

/// Serialises the header. `pretty` for the npy sidecar (humans read it), compact for the EXR attribute.
pub(crate) fn to_json(
    scan: &Scan,
    time: &TimeAxis,
    data: Option<&DataEntries<'_>>,
    pretty: bool,
    file: &Path,
    format: &str,
) -> Result<Vec<u8>> {
    let (points, lasers, sensors, pattern) = match &scan.pattern {
        ScanPattern::Confocal(p) => (Some(point_set_out(p)), None, None, "confocal"),
        ScanPattern::Exhaustive { lasers, sensors } | ScanPattern::Paired { lasers, sensors } => {
            (None, Some(point_set_out(lasers)), Some(point_set_out(sensors)), scan.pattern_name())
        }
    };
    let header = HeaderOut {
        format: FORMAT_NAME,
        version: VERSION,
        data,
        time: TimeOut {
            t0: time.t0,
            bin_width: time.bin_width,
            bins: time.bins,
            includes_device_legs: time.includes_device_legs,
        },
        scan: ScanOut {
            pattern,
            points,
            lasers,
            sensors,
            laser_device: scan.laser_device.map(arr),
            sensor_device: scan.sensor_device.map(arr),
        },
    };
    let out = if pretty {
        let mut buf = Vec::new();
        let mut ser = serde_json::Serializer::with_formatter(&mut buf, ObjectsPretty::default());
        header.serialize(&mut ser).map(|()| buf)
    } else {
        serde_json::to_vec(&header)
    };
    out.map_err(|e| TransientError::CannotWrite {
        file: file.into(),
        format: format.into(),
        reason: format!("the geometry cannot be encoded as JSON: {e}"),
    })
}

/// A JSON formatter that indents objects (one key per line) but prints arrays on one line, so that a
/// sidecar stays readable: `"x": [-0.25,0.0,0.25]` rather than one number per line.
#[derive(Default)]
struct ObjectsPretty {
    indent: usize,
    has_value: bool,
}

impl ObjectsPretty {
    fn newline<W: ?Sized + std::io::Write>(&self, w: &mut W) -> std::io::Result<()> {
        w.write_all(b"\n")?;
        (0..self.indent).try_for_each(|_| w.write_all(b"  "))
    }
}

impl serde_json::ser::Formatter for ObjectsPretty {
    fn begin_array_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W, first: bool) -> std::io::Result<()> {
        if first { Ok(()) } else { w.write_all(b",") }
    }

    fn begin_object<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        self.indent += 1;
        self.has_value = false;
        w.write_all(b"{")
    }

    fn end_object<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        self.indent = self.indent.saturating_sub(1);
        if self.has_value {
            self.newline(w)?;
        }
        self.has_value = true;
        w.write_all(b"}")
    }

    fn begin_object_key<W: ?Sized + std::io::Write>(&mut self, w: &mut W, first: bool) -> std::io::Result<()> {
        if !first {
            w.write_all(b",")?;
        }
        self.newline(w)
    }

    fn begin_object_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        w.write_all(b": ")
    }

    fn end_object_value<W: ?Sized + std::io::Write>(&mut self, _w: &mut W) -> std::io::Result<()> {
        self.has_value = true;
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------------------
// Reading

/// Points of a set as read: compact until the caller has checked the sizes.
#[derive(Debug)]
pub(crate) enum Points {
    /// A separable grid: point `ix + nx·iy` is `(xs[ix], ys[iy], z)`.
    Axes {
        /// x coordinates, `nx` of them.
        xs: Vec<f32>,
        /// y coordinates, `ny` of them.
        ys: Vec<f32>,
        /// The common z.
        z: f32,
    },
    /// An explicit list.
    List(Vec<Vec3>),
}

/// A point set as read from JSON.
#[derive(Debug)]
pub(crate) struct PointSetIn {
    points: Points,
    /// One shared normal, or one per point.
    normals: Result<Vec3, Vec<Vec3>>,
    layout: Layout,
    len: usize,
}

impl PointSetIn {
    fn into_point_set(self) -> PointSet {
        let points = match self.points {
            Points::Axes { xs, ys, z } => {
                ys.iter().flat_map(|&y| xs.iter().map(move |&x| Vec3::new(x, y, z))).collect()
            }
            Points::List(p) => p,
        };
        let normals = match self.normals {
            Ok(n) => vec![n; points.len()],
            Err(list) => list,
        };
        PointSet { points, normals, layout: self.layout }
    }
}

/// A decoded header whose point sets are not yet materialised.
#[derive(Debug)]
pub(crate) struct Header {
    /// The time axis (validated).
    pub time: TimeAxis,
    /// Confocal: one set; exhaustive and paired: lasers and sensors.
    sets: Vec<PointSetIn>,
    /// Whether two sets pair up one to one rather than every laser with every sensor.
    paired: bool,
    laser_device: Option<Vec3>,
    sensor_device: Option<Vec3>,
    /// The whole top-level object, for format-specific keys (`data`, `dtype`, `shape`).
    pub top: Map<String, Value>,
}

impl Header {
    /// Number of measurements the scan describes (checked: no overflow).
    pub fn measurements(&self) -> usize {
        match self.sets.as_slice() {
            [one] => one.len,
            [l, s] if self.paired => l.len,
            [l, s] => l.len.saturating_mul(s.len),
            _ => 0,
        }
    }

    /// Whether the scan is confocal.
    pub fn is_confocal(&self) -> bool {
        self.sets.len() == 1
    }

    /// Whether the scan is paired (measurement `m` = laser `m` with sensor `m`).
    pub fn is_paired(&self) -> bool {
        self.paired
    }

    /// `(ny, nx)` of a confocal grid (or of a paired scan's laser grid), `(lasers, sensors)` of an exhaustive
    /// scan; `None` for a list.
    pub fn image_dims(&self) -> Option<(usize, usize)> {
        match (self.sets.as_slice(), self.paired) {
            ([one], _) | ([one, _], true) => match one.layout {
                Layout::Grid { nx, ny } => Some((ny, nx)),
                Layout::List => None,
            },
            ([l, s], false) => Some((l.len, s.len)),
            _ => None,
        }
    }

    /// Builds the scan (allocates the point lists). Call only after checking [`Header::measurements`]
    /// against the data.
    pub fn into_parts(self) -> (Scan, TimeAxis) {
        let mut sets = self.sets.into_iter().map(PointSetIn::into_point_set);
        let first = sets.next().unwrap_or_else(|| PointSet::list(Vec::new()));
        let pattern = match sets.next() {
            Some(sensors) if self.paired => ScanPattern::Paired { lasers: first, sensors },
            Some(sensors) => ScanPattern::Exhaustive { lasers: first, sensors },
            None => ScanPattern::Confocal(first),
        };
        (Scan { pattern, laser_device: self.laser_device, sensor_device: self.sensor_device }, self.time)
    }
}

/// Error helpers that name the file and the field path.
pub(crate) struct Ctx<'a> {
    /// The file the JSON came from.
    pub file: &'a Path,
    /// Prefix of every field path, e.g. `sidecar` or `exr attribute nlos`.
    pub prefix: &'a str,
}

impl Ctx<'_> {
    fn field(&self, path: &str) -> String {
        if path.is_empty() { self.prefix.to_owned() } else { format!("{}.{path}", self.prefix) }
    }

    fn missing(&self, path: &str, hint: &str) -> TransientError {
        TransientError::MissingField { file: self.file.into(), field: self.field(path), hint: hint.into() }
    }

    fn wrong_type(&self, path: &str, expected: &str, found: &Value) -> TransientError {
        TransientError::WrongType {
            file: self.file.into(),
            field: self.field(path),
            expected: expected.into(),
            found: describe(found),
        }
    }

    fn invalid(&self, path: &str, reason: String) -> TransientError {
        TransientError::InvalidValue { file: self.file.into(), field: self.field(path), reason }
    }

    fn wrong_shape(&self, path: &str, expected: String, found: String) -> TransientError {
        TransientError::WrongShape { file: self.file.into(), field: self.field(path), expected, found }
    }

    fn non_finite(&self, path: &str, index: usize) -> TransientError {
        TransientError::NonFinite { file: self.file.into(), field: self.field(path), index }
    }
}

/// A short description of a JSON value's type for error messages.
fn describe(v: &Value) -> String {
    match v {
        Value::Null => "null".into(),
        Value::Bool(b) => format!("boolean {b}"),
        Value::Number(n) => format!("number {n}"),
        Value::String(s) => format!("string {:?}", s.chars().take(40).collect::<String>()),
        Value::Array(a) => format!("array of {} elements", a.len()),
        Value::Object(_) => "object".into(),
    }
}

fn get<'v>(obj: &'v Map<String, Value>, key: &str) -> Option<&'v Value> {
    obj.get(key).filter(|v| !v.is_null())
}

fn object<'v>(ctx: &Ctx<'_>, v: &'v Value, path: &str) -> Result<&'v Map<String, Value>> {
    v.as_object().ok_or_else(|| ctx.wrong_type(path, "a JSON object", v))
}

fn req<'v>(ctx: &Ctx<'_>, obj: &'v Map<String, Value>, key: &str, path: &str, hint: &str) -> Result<&'v Value> {
    get(obj, key).ok_or_else(|| ctx.missing(path, hint))
}

/// Rejects keys other than `allowed` (catches typos such as `bin_widht`).
fn only_keys(ctx: &Ctx<'_>, obj: &Map<String, Value>, allowed: &[&str], path: &str) -> Result<()> {
    match obj.keys().find(|k| !allowed.contains(&k.as_str())) {
        Some(k) => Err(ctx.invalid(
            &join(path, k),
            format!("unknown key (allowed here: {}); check the spelling", allowed.join(", ")),
        )),
        None => Ok(()),
    }
}

fn join(path: &str, key: &str) -> String {
    if path.is_empty() { key.to_owned() } else { format!("{path}.{key}") }
}

fn f64_of(ctx: &Ctx<'_>, v: &Value, path: &str) -> Result<f64> {
    let x = v.as_f64().ok_or_else(|| ctx.wrong_type(path, "a number", v))?;
    if x.is_finite() { Ok(x) } else { Err(ctx.non_finite(path, 0)) }
}

fn f32_of(ctx: &Ctx<'_>, v: &Value, path: &str, index: usize) -> Result<f32> {
    let x = v.as_f64().ok_or_else(|| ctx.wrong_type(path, "a number", v))?;
    let y = x as f32;
    if y.is_finite() { Ok(y) } else { Err(ctx.non_finite(path, index)) }
}

fn usize_of(ctx: &Ctx<'_>, v: &Value, path: &str) -> Result<usize> {
    v.as_u64().and_then(|n| usize::try_from(n).ok()).ok_or_else(|| ctx.wrong_type(path, "a non-negative integer", v))
}

fn f32_list(ctx: &Ctx<'_>, v: &Value, path: &str) -> Result<Vec<f32>> {
    let a = v.as_array().ok_or_else(|| ctx.wrong_type(path, "an array of numbers", v))?;
    a.iter().enumerate().map(|(i, x)| f32_of(ctx, x, path, i)).collect()
}

fn vec3_of(ctx: &Ctx<'_>, v: &Value, path: &str, index: usize) -> Result<Vec3> {
    match v.as_array().map(Vec::as_slice) {
        Some([x, y, z]) => {
            Ok(Vec3::new(f32_of(ctx, x, path, index)?, f32_of(ctx, y, path, index)?, f32_of(ctx, z, path, index)?))
        }
        _ => Err(ctx.wrong_type(path, "[x, y, z] (three numbers)", v)),
    }
}

fn vec3_list(ctx: &Ctx<'_>, v: &Value, path: &str) -> Result<Vec<Vec3>> {
    let a = v.as_array().ok_or_else(|| ctx.wrong_type(path, "an array of [x, y, z]", v))?;
    a.iter().enumerate().map(|(i, p)| vec3_of(ctx, p, path, i)).collect()
}

const POINT_SET_KEYS: [&str; 7] = ["grid", "x", "y", "z", "points", "normal", "normals"];

fn point_set(ctx: &Ctx<'_>, v: &Value, path: &str) -> Result<PointSetIn> {
    let obj = object(ctx, v, path)?;
    only_keys(ctx, obj, &POINT_SET_KEYS, path)?;
    let layout = match get(obj, "grid") {
        None => Layout::List,
        Some(g) => match g.as_array().map(Vec::as_slice) {
            Some([nx, ny]) => {
                let p = join(path, "grid");
                Layout::Grid { nx: usize_of(ctx, nx, &p)?, ny: usize_of(ctx, ny, &p)? }
            }
            _ => return Err(ctx.wrong_type(&join(path, "grid"), "[nx, ny] (two integers)", g)),
        },
    };
    let axes = ["x", "y", "z"].map(|k| get(obj, k));
    let points = match (get(obj, "points"), axes) {
        (Some(p), [None, None, None]) => Points::List(vec3_list(ctx, p, &join(path, "points"))?),
        (None, [Some(x), Some(y), Some(z)]) => {
            let Layout::Grid { nx, ny } = layout else {
                return Err(ctx.missing(&join(path, "grid"), "the x/y/z form needs \"grid\": [nx, ny]"));
            };
            let xs = f32_list(ctx, x, &join(path, "x"))?;
            let ys = f32_list(ctx, y, &join(path, "y"))?;
            if xs.len() != nx {
                return Err(ctx.wrong_shape(&join(path, "x"), format!("{nx} values (grid nx)"), xs.len().to_string()));
            }
            if ys.len() != ny {
                return Err(ctx.wrong_shape(&join(path, "y"), format!("{ny} values (grid ny)"), ys.len().to_string()));
            }
            Points::Axes { xs, ys, z: f32_of(ctx, z, &join(path, "z"), 0)? }
        }
        (None, [None, None, None]) => {
            return Err(ctx.missing(&join(path, "points"), "give \"points\": [[x, y, z], …] or, for a grid, x, y, z"));
        }
        _ => {
            return Err(ctx.invalid(
                path,
                "give either \"points\" or all of \"x\", \"y\", \"z\" (a separable grid), not a mix".into(),
            ));
        }
    };
    let len = match &points {
        Points::Axes { xs, ys, .. } => xs.len().saturating_mul(ys.len()),
        Points::List(p) => p.len(),
    };
    if len == 0 {
        return Err(ctx.invalid(path, "no points (zero-sized scan); a scan needs at least one point".into()));
    }
    if let Layout::Grid { nx, ny } = layout
        && nx.checked_mul(ny) != Some(len)
    {
        return Err(ctx.wrong_shape(&join(path, "points"), format!("{nx} × {ny} grid points"), len.to_string()));
    }
    let normals = match (get(obj, "normal"), get(obj, "normals")) {
        (Some(n), None) => Ok(vec3_of(ctx, n, &join(path, "normal"), 0)?),
        (None, Some(n)) => {
            let list = vec3_list(ctx, n, &join(path, "normals"))?;
            if list.len() != len {
                return Err(ctx.wrong_shape(
                    &join(path, "normals"),
                    format!("{len} normals (one per point)"),
                    list.len().to_string(),
                ));
            }
            Err(list)
        }
        (None, None) => Ok(Vec3::Z),
        (Some(_), Some(_)) => {
            return Err(
                ctx.invalid(path, "give either \"normal\" (shared) or \"normals\" (per point), not both".into())
            );
        }
    };
    if let Ok(n) = &normals
        && (n.length() - 1.0).abs() > 1e-3
    {
        return Err(ctx.invalid(&join(path, "normal"), format!("{n:?} is not a unit vector")));
    }
    Ok(PointSetIn { points, normals, layout, len })
}

fn time_axis(ctx: &Ctx<'_>, v: &Value) -> Result<TimeAxis> {
    let obj = object(ctx, v, "time")?;
    only_keys(ctx, obj, &["t0", "bin_width", "bins", "includes_device_legs"], "time")?;
    let t0 = f64_of(ctx, req(ctx, obj, "t0", "time.t0", "path length at the start of bin 0, metres")?, "time.t0")?;
    let bin_width = f64_of(
        ctx,
        req(ctx, obj, "bin_width", "time.bin_width", "width of one bin, metres of path length")?,
        "time.bin_width",
    )?;
    let bins = usize_of(ctx, req(ctx, obj, "bins", "time.bins", "number of time bins")?, "time.bins")?;
    let includes_device_legs = match get(obj, "includes_device_legs") {
        None => false,
        Some(Value::Bool(b)) => *b,
        Some(other) => return Err(ctx.wrong_type("time.includes_device_legs", "true or false", other)),
    };
    if bin_width <= 0.0 {
        return Err(ctx.invalid("time.bin_width", format!("{bin_width} must be > 0 (metres of path)")));
    }
    if bins == 0 {
        return Err(ctx.invalid("time.bins", "a transient needs at least one time bin".into()));
    }
    Ok(TimeAxis { t0, bin_width, bins, includes_device_legs })
}

fn device(ctx: &Ctx<'_>, obj: &Map<String, Value>, key: &str) -> Result<Option<Vec3>> {
    get(obj, key).map(|v| vec3_of(ctx, v, &join("scan", key), 0)).transpose()
}

/// Parses and checks a header. `allowed_top` lists the top-level keys the container accepts besides
/// `format`, `version`, `time` and `scan` (unknown top-level keys are ignored, for user metadata).
pub(crate) fn parse(json: &[u8], ctx: &Ctx<'_>) -> Result<Header> {
    let value: Value = serde_json::from_slice(json).map_err(|e| TransientError::Malformed {
        file: ctx.file.into(),
        detail: format!("{}: not valid JSON: {e}", ctx.prefix),
    })?;
    let top = object(ctx, &value, "")?;
    match get(top, "format") {
        Some(Value::String(s)) if s == FORMAT_NAME => {}
        Some(other) => return Err(ctx.wrong_type("format", &format!("the string {FORMAT_NAME:?}"), other)),
        None => return Err(ctx.missing("format", &format!("add \"format\": {FORMAT_NAME:?}"))),
    }
    let version = req(ctx, top, "version", "version", &format!("add \"version\": {VERSION}"))?;
    match version.as_u64() {
        Some(VERSION) => {}
        Some(v) => {
            return Err(TransientError::Unsupported {
                file: ctx.file.into(),
                what: format!("{} schema version {v} (this build reads version {VERSION})", ctx.prefix),
            });
        }
        None => return Err(ctx.wrong_type("version", "an integer", version)),
    }
    let time = time_axis(ctx, req(ctx, top, "time", "time", "add the time axis object")?)?;
    let scan = object(ctx, req(ctx, top, "scan", "scan", "add the scan geometry object")?, "scan")?;
    const PATTERNS: &str = "\"confocal\", \"exhaustive\" or \"paired\"";
    let pattern = req(ctx, scan, "pattern", "scan.pattern", PATTERNS)?;
    let kind = pattern.as_str().and_then(|p| p.parse::<PatternKind>().ok());
    let paired = kind == Some(PatternKind::Paired);
    let sets = match kind {
        Some(PatternKind::Confocal) => {
            only_keys(ctx, scan, &["pattern", "points", "laser_device", "sensor_device"], "scan")?;
            let p = req(ctx, scan, "points", "scan.points", "the confocal scan points")?;
            vec![point_set(ctx, p, "scan.points")?]
        }
        Some(PatternKind::Exhaustive | PatternKind::Paired) => {
            only_keys(ctx, scan, &["pattern", "lasers", "sensors", "laser_device", "sensor_device"], "scan")?;
            let l = req(ctx, scan, "lasers", "scan.lasers", "the laser points")?;
            let s = req(ctx, scan, "sensors", "scan.sensors", "the sensor points")?;
            let sets = vec![point_set(ctx, l, "scan.lasers")?, point_set(ctx, s, "scan.sensors")?];
            if paired && sets[0].len != sets[1].len {
                return Err(ctx.wrong_shape(
                    "scan.sensors",
                    format!("{} points (a paired scan has one sensor spot per laser spot)", sets[0].len),
                    sets[1].len.to_string(),
                ));
            }
            sets
        }
        None => return Err(ctx.wrong_type("scan.pattern", PATTERNS, pattern)),
    };
    let laser_device = device(ctx, scan, "laser_device")?;
    let sensor_device = device(ctx, scan, "sensor_device")?;
    let Value::Object(top) = value else { return Err(ctx.wrong_type("", "a JSON object", &Value::Null)) };
    Ok(Header { time, sets, paired, laser_device, sensor_device, top })
}

/// Reads an optional integer list (e.g. `shape`) from the top level.
pub(crate) fn usize_list(ctx: &Ctx<'_>, top: &Map<String, Value>, key: &str) -> Result<Option<Vec<usize>>> {
    let Some(v) = get(top, key) else { return Ok(None) };
    let a = v.as_array().ok_or_else(|| ctx.wrong_type(key, "an array of integers", v))?;
    a.iter().map(|x| usize_of(ctx, x, key)).collect::<Result<Vec<_>>>().map(Some)
}

/// Reads an optional string from the top level.
pub(crate) fn string<'v>(ctx: &Ctx<'_>, top: &'v Map<String, Value>, key: &str) -> Result<Option<&'v str>> {
    match get(top, key) {
        None => Ok(None),
        Some(Value::String(s)) => Ok(Some(s)),
        Some(other) => Err(ctx.wrong_type(key, "a string", other)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctx() -> Ctx<'static> {
        Ctx { file: Path::new("t.json"), prefix: "sidecar" }
    }

    #[test]
    fn grid_uses_separable_form_and_round_trips() -> Result<()> {
        let scan = Scan::confocal(PointSet::wall_grid(3, 2, 0.25, 0.1)?);
        let time = TimeAxis::new(0.1, 0.003, 7)?;
        let json = to_json(&scan, &time, None, true, Path::new("t.json"), "npy")?;
        let text = String::from_utf8_lossy(&json);
        assert!(text.contains("\"x\"") && text.contains("\"normal\""), "{text}");
        assert_eq!(text.matches("\"points\"").count(), 1, "{text}");
        let h = parse(&json, &ctx())?;
        assert_eq!(h.measurements(), 6);
        assert_eq!(h.image_dims(), Some((2, 3)));
        let (s, t) = h.into_parts();
        assert_eq!((s, t), (scan, time));
        Ok(())
    }

    #[test]
    fn non_separable_grid_uses_point_list() -> Result<()> {
        let mut set = PointSet::wall_grid(2, 2, 0.25, 0.25)?;
        set.points[3].z = 1e-30;
        set.normals[1] = Vec3::new(0.0, 0.6, 0.8);
        let scan = Scan::confocal(set);
        let time = TimeAxis::new(-0.0, 1e-3, 1)?;
        let json = to_json(&scan, &time, None, false, Path::new("t.json"), "exr")?;
        let text = String::from_utf8_lossy(&json);
        assert!(text.contains("\"points\"") && text.contains("\"normals\""), "{text}");
        let (s, t) = parse(&json, &ctx())?.into_parts();
        assert_eq!(s, scan);
        assert_eq!(t.t0.to_bits(), (-0.0f64).to_bits());
        Ok(())
    }

    #[test]
    fn errors_name_the_field() {
        let cases: [(&str, &str); 7] = [
            (r#"{"format":"nlos-transient","version":2}"#, "version 2"),
            (r#"{"format":"nlos-transient","version":1,"time":{"t0":0,"bins":3},"scan":{}}"#, "sidecar.time.bin_width"),
            (
                r#"{"format":"nlos-transient","version":1,"time":{"t0":0,"bin_width":-1,"bins":3},"scan":{}}"#,
                "sidecar.time.bin_width",
            ),
            (
                r#"{"format":"nlos-transient","version":1,"time":{"t0":0,"bin_width":1,"bins":3,"bin_widht":2}}"#,
                "sidecar.time.bin_widht",
            ),
            (
                r#"{"format":"nlos-transient","version":1,"time":{"t0":0,"bin_width":1,"bins":3},
                   "scan":{"pattern":"confocal","points":{"grid":[0,0],"x":[],"y":[],"z":0}}}"#,
                "zero-sized",
            ),
            (
                r#"{"format":"nlos-transient","version":1,"time":{"t0":0,"bin_width":1,"bins":3},
                   "scan":{"pattern":"confocal","points":{"grid":[2,1],"x":[1],"y":[0],"z":0}}}"#,
                "sidecar.scan.points.x",
            ),
            (
                r#"{"format":"nlos-transient","version":1,"time":{"t0":0,"bin_width":1,"bins":3},
                   "scan":{"pattern":"confocal","points":{"points":[[0,0,1e39]]}}}"#,
                "sidecar.scan.points.points",
            ),
        ];
        for (json, needle) in cases {
            let e = parse(json.as_bytes(), &ctx()).expect_err(json).to_string();
            assert!(e.contains(needle), "{e} lacks {needle}");
            assert!(e.contains("t.json"), "{e}");
        }
    }
}
