//! The run record ([`RunRecord`], `checkpoint.json`): everything needed to continue a run, read and written
//! through this type only — the loop, `resume`, the report and the Python package read a run directory's
//! record with [`RunRecord::read`] and its accessors, never by JSON key — with the settings record `resume`
//! compares and atomic writes.
//!
//! **Versions.** [`RunRecord::VERSION`] changes whenever the record's fields change (4: the surface with its
//! named fields, [`crate::surface::Surface`], replaced bare positions, triangles and Adam moments; 5: the
//! albedo per vertex, a field of the surface, replaced the albedo map over the wall plane). A record
//! of another version is refused with its version and this build's, before the rest is parsed, so that a
//! checkpoint of an older build says why it cannot be resumed rather than which JSON field it lacks.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{CHECKPOINT_FILE, RUN_LOG_FILE, RunLog, StopReason, checkpoint_unreadable};
use crate::adam::{VectorAdam, VertexAdam};
use crate::albedo::ALBEDO;
use crate::error::{OptimError, Result};
use crate::params::ReconstructParams;
use crate::prune::PruneRecord;
use crate::reflectance::Reflectance;
use crate::regions::RegionRecord;
use crate::residual::ResidualRecord;
use crate::support::SUPPORT;
use crate::surface::Surface;
use nlos_transient::Transient;

/// Everything needed to continue a run: the checkpoint of its directory ([`CHECKPOINT_FILE`], module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    pub(crate) version: u32,
    pub(crate) fingerprint: u64,
    /// The settings the run was started with ([`SettingsRecord`]).
    pub(crate) settings: SettingsRecord,
    /// The surface with its fields (the shape's Adam moments among them).
    pub(crate) surface: Surface,
    pub(crate) reflectance: Reflectance,
    /// The shape's Adam step count (its moments are [`crate::reconstruct::SHAPE_MOMENTS`] of the surface).
    pub(crate) shape_adam: VertexAdam,
    pub(crate) reflectance_adam: VectorAdam,
    pub(crate) stage: u32,
    pub(crate) block_in_stage: u32,
    pub(crate) blocks_done: u64,
    pub(crate) iteration: u64,
    pub(crate) rng: u64,
    pub(crate) lr_scale: f64,
    pub(crate) scale: f64,
    pub(crate) reg_weight: f64,
    pub(crate) elapsed_s: f64,
    pub(crate) finished: Option<StopReason>,
    pub(crate) log: RunLog,
    /// Stages planned (for progress reports only).
    pub(crate) max_stages_hint: u32,
    /// Boundary pruning per block.
    pub(crate) prune_log: Vec<PruneRecord>,
    /// Residual back-projection per stage.
    pub(crate) residual_log: Vec<ResidualRecord>,
    /// Region tests per block ([`crate::regions`]).
    pub(crate) region_log: Vec<RegionRecord>,
    /// Adam steps the per-vertex albedo has taken (its value and moments are fields of the surface,
    /// [`crate::albedo::ALBEDO`], [`crate::albedo::ALBEDO_MOMENTS`]).
    pub(crate) albedo_steps: u64,
}

/// The part of a record read first: its version.
#[derive(Deserialize)]
struct Header {
    version: u32,
}

impl RunRecord {
    /// The version of the record this build writes and reads (module docs).
    pub const VERSION: u32 = 5;

    /// The record of run directory `dir` ([`CHECKPOINT_FILE`]), checked: its version first, then its
    /// surface.
    ///
    /// # Errors
    /// [`OptimError::Checkpoint`] for a missing or unreadable file, a record of another version (saying
    /// both), malformed JSON or an inconsistent surface.
    pub fn read(dir: &Path) -> Result<Self> {
        let path = dir.join(CHECKPOINT_FILE);
        let ck = |message: String| OptimError::Checkpoint { path: path.clone(), message };
        let bytes = std::fs::read(&path).map_err(|e| ck(checkpoint_unreadable(&e)))?;
        let header: Header = serde_json::from_slice(&bytes).map_err(|e| ck(format!("not a run record: {e}")))?;
        if header.version != Self::VERSION {
            return Err(ck(format!(
                "written by another version of nlos (record version {}, this build reads {}); start the run afresh",
                header.version,
                Self::VERSION
            )));
        }
        let record: Self = serde_json::from_slice(&bytes).map_err(|e| ck(e.to_string()))?;
        if let Err(why) = record.surface.validate() {
            return Err(ck(format!("its surface is inconsistent: {why}")));
        }
        Ok(record)
    }

    /// The surface as the last finished block left it.
    pub fn surface(&self) -> &Surface {
        &self.surface
    }

    /// The reflectance as fitted so far.
    pub fn reflectance(&self) -> &Reflectance {
        &self.reflectance
    }

    /// The relative albedo of each vertex of [`RunRecord::surface`] as fitted so far (None: the run fits
    /// none, [`crate::ReconstructParams::albedo`]).
    pub fn albedo(&self) -> Option<&[f64]> {
        self.surface.vertex(ALBEDO).ok()
    }

    /// How much of their light the data confirm, per vertex of [`RunRecord::surface`] ([`crate::support`]:
    /// the area-weighted mean of the faces around); None until the run has finished.
    pub fn vertex_support(&self) -> Option<Vec<f32>> {
        let support = self.surface.face(SUPPORT).ok()?;
        Some(crate::support::vertex_support(self.surface.positions(), self.surface.triangles(), support))
    }

    /// The region tests of every block ([`crate::regions`]).
    pub fn regions(&self) -> &[RegionRecord] {
        &self.region_log
    }

    /// The run log (also written as [`RUN_LOG_FILE`]).
    pub fn log(&self) -> &RunLog {
        &self.log
    }

    /// The intensity scale s of the last step (measured ≈ s · rendered).
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The stage (0-based) the next block runs in.
    pub fn stage(&self) -> u32 {
        self.stage
    }

    /// Blocks finished.
    pub fn blocks_done(&self) -> u64 {
        self.blocks_done
    }

    /// Why the run ended, or None while it has blocks to run.
    pub fn finished(&self) -> Option<StopReason> {
        self.finished
    }

    /// Boundary pruning, per block.
    pub fn prune_log(&self) -> &[PruneRecord] {
        &self.prune_log
    }

    /// Residual back-projection, per round.
    pub fn residual_log(&self) -> &[ResidualRecord] {
        &self.residual_log
    }

    /// Writes the record and the run log into `dir`, each atomically.
    ///
    /// # Errors
    /// [`OptimError::Io`], [`OptimError::Checkpoint`].
    pub(crate) fn write(&self, dir: &Path) -> Result<()> {
        let ck = dir.join(CHECKPOINT_FILE);
        write_atomic(&ck, &json_bytes(self, &ck)?)?;
        let lg = dir.join(RUN_LOG_FILE);
        write_atomic(&lg, &json_bytes(&self.log, &lg)?)
    }
}

/// The run's random stream ([`nlos_transient::rng::SplitMix64`]), its one `u64` of state kept in the
/// checkpoint: the next 64 bits.
pub(crate) fn next_u64(state: &mut u64) -> u64 {
    let mut g = nlos_transient::rng::SplitMix64::new(*state);
    let bits = g.next_u64();
    *state = g.state();
    bits
}

/// FNV-1a over the measurement's shape and bits: ties a checkpoint to its measurement.
pub(crate) fn fingerprint(measured: &Transient) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |x: u64| {
        for b in x.to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(measured.measurements() as u64);
    eat(measured.bins() as u64);
    for v in measured.data() {
        eat(u64::from(v.to_bits()));
    }
    h
}

/// The settings a run was started with, in its checkpoint: every field of [`ReconstructParams`] but
/// `out_dir`, as serde writes them. `resume` compares it field by field with the parameters it is given and
/// names the first that differs ([`OptimError::SettingsChanged`]). `version` changes when a field changes
/// meaning; a record of another version is refused rather than compared.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct SettingsRecord {
    pub(crate) version: u32,
    pub(crate) params: serde_json::Value,
}

/// The version of [`SettingsRecord`] this build writes.
pub(crate) const SETTINGS_VERSION: u32 = 1;

impl SettingsRecord {
    pub(crate) fn of(params: &ReconstructParams) -> Result<Self> {
        // Serialising plain data into a `Value` fails only for maps with non-string keys, which the
        // parameters do not hold.
        let params = serde_json::to_value(params).map_err(|_| OptimError::InvalidParameter {
            name: "params",
            value: 0.0,
            reason: "the parameters cannot be recorded in the checkpoint",
        })?;
        Ok(Self { version: SETTINGS_VERSION, params })
    }
}

/// The first difference between two settings records' values, depth first in field order: its dotted path
/// and the two values (compact JSON).
pub(crate) fn first_difference(
    was: &serde_json::Value,
    now: &serde_json::Value,
    path: &str,
) -> Option<(String, String, String)> {
    use serde_json::Value;
    let join = |key: &str| if path.is_empty() { key.to_owned() } else { format!("{path}.{key}") };
    match (was, now) {
        (Value::Object(a), Value::Object(b)) => {
            for (key, va) in a {
                let vb = b.get(key).unwrap_or(&Value::Null);
                if let Some(d) = first_difference(va, vb, &join(key)) {
                    return Some(d);
                }
            }
            b.iter()
                .find(|(key, vb)| !a.contains_key(*key) && !vb.is_null())
                .map(|(key, vb)| (join(key), "(absent)".to_owned(), vb.to_string()))
        }
        (Value::Array(a), Value::Array(b)) if a.len() == b.len() => {
            a.iter().zip(b).enumerate().find_map(|(i, (va, vb))| first_difference(va, vb, &format!("{path}[{i}]")))
        }
        _ if was == now => None,
        _ => {
            // Long values (a sensor's response) are cut: the path names the setting.
            let short = |v: &Value| {
                let s = v.to_string();
                if s.chars().count() > 60 { format!("{}…", s.chars().take(57).collect::<String>()) } else { s }
            };
            Some((path.to_owned(), short(was), short(now)))
        }
    }
}

/// Writes `bytes` to `path` atomically: the whole file or the previous one, never a part
/// (`atomic_write_file`: a temporary file in the same directory, synced, renamed over `path`).
///
/// # Errors
/// [`OptimError::Io`] naming the file.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write as _;
    let io = |source| OptimError::Io { path: path.to_owned(), fix: OptimError::WRITE_FIX, source };
    let mut file = atomic_write_file::AtomicWriteFile::open(path).map_err(io)?;
    file.write_all(bytes).map_err(io)?;
    file.commit().map_err(io)
}

fn json_bytes<T: Serialize>(v: &T, path: &Path) -> Result<Vec<u8>> {
    serde_json::to_vec(v).map_err(|e| OptimError::Checkpoint { path: path.to_owned(), message: e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A checkpoint written by the build before the surface type (version 3: bare positions, triangles and
    /// Adam moments) is refused with both versions, not with the JSON field it lacks; one of this version is
    /// read back as written; a directory without one says there is nothing to resume.
    #[test]
    fn a_record_of_another_version_is_refused_saying_both_versions() {
        let dir = std::env::temp_dir().join(format!("nlos-record-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let e = RunRecord::read(&dir).expect_err("no record");
        assert!(e.to_string().contains("nothing to resume"), "{e}");
        let v3 = r#"{"version":3,"fingerprint":1,"positions":[[0,0,0.5]],"triangles":[],"shape_adam":{"m":[],"v":[],"t":0}}"#;
        std::fs::write(dir.join(CHECKPOINT_FILE), v3).expect("write");
        let e = RunRecord::read(&dir).expect_err("version 3");
        let both = format!("record version 3, this build reads {}", RunRecord::VERSION);
        assert!(e.to_string().contains(&both), "{e}");
        let p = [glam::Vec3::new(0.0, 0.0, 0.5), glam::Vec3::new(0.1, 0.0, 0.5), glam::Vec3::new(0.0, 0.1, 0.5)];
        let mut surface = Surface::new(p.to_vec(), vec![[0, 2, 1]]).expect("surface");
        surface.vertex_mut(crate::reconstruct::SHAPE_MOMENTS).expect("field")[1].v = 1e-7;
        let record = RunRecord {
            version: RunRecord::VERSION,
            fingerprint: 7,
            settings: SettingsRecord::of(&ReconstructParams::default()).expect("settings"),
            surface,
            reflectance: Reflectance::default(),
            shape_adam: VertexAdam { t: 3 },
            reflectance_adam: VectorAdam::new(1),
            stage: 1,
            block_in_stage: 2,
            blocks_done: 5,
            iteration: 40,
            rng: 9,
            lr_scale: 0.5,
            scale: 1.25,
            reg_weight: 0.1,
            elapsed_s: 3.0,
            finished: None,
            log: RunLog::default(),
            max_stages_hint: 3,
            prune_log: Vec::new(),
            residual_log: Vec::new(),
            region_log: Vec::new(),
            albedo_steps: 0,
        };
        record.write(&dir).expect("write");
        assert_eq!(RunRecord::read(&dir).expect("read"), record);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The record names the first setting that differs, by its path, with both values.
    #[test]
    fn settings_record_names_the_changed_field() {
        let p = ReconstructParams::default();
        let a = SettingsRecord::of(&p).expect("record");
        assert_eq!(first_difference(&a.params, &a.params, ""), None);
        let q = ReconstructParams { schedule: crate::Schedule { shape_iterations: 30, ..p.schedule }, ..p.clone() };
        let b = SettingsRecord::of(&q).expect("record");
        assert_eq!(
            first_difference(&a.params, &b.params, ""),
            Some(("schedule.shape_iterations".into(), "20".into(), "30".into()))
        );
        let r = ReconstructParams { prune: None, ..p.clone() };
        let d = first_difference(&a.params, &SettingsRecord::of(&r).expect("record").params, "").expect("differs");
        assert_eq!(d.0, "prune");
        assert_eq!(d.2, "null");
        // The output directory is not a setting.
        let o = ReconstructParams { out_dir: Some("elsewhere".into()), ..p };
        assert_eq!(SettingsRecord::of(&o).expect("record"), a);
    }
}
