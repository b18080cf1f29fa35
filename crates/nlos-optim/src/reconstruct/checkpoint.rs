//! The checkpoint (`checkpoint.json`): everything needed to continue a run, the settings record `resume`
//! compares, and atomic writes.

use super::*;

/// Everything needed to continue a run (written as the checkpoint).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct State {
    pub(super) version: u32,
    pub(super) fingerprint: u64,
    /// The settings the run was started with ([`SettingsRecord`]).
    pub(super) settings: SettingsRecord,
    #[serde(with = "exact_vec3")]
    pub(super) positions: Vec<Vec3>,
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) reflectance: Reflectance,
    pub(super) shape_adam: VertexAdam,
    pub(super) reflectance_adam: VectorAdam,
    pub(super) stage: u32,
    pub(super) block_in_stage: u32,
    pub(super) blocks_done: u64,
    pub(super) iteration: u64,
    pub(super) rng: u64,
    pub(super) lr_scale: f64,
    pub(super) scale: f64,
    pub(super) reg_weight: f64,
    pub(super) elapsed_s: f64,
    pub(super) finished: Option<StopReason>,
    pub(super) log: RunLog,
    /// Stages planned (for progress reports only).
    #[serde(default)]
    pub(super) max_stages_hint: u32,
    /// Boundary pruning per block.
    #[serde(default)]
    pub(super) prune_log: Vec<PruneRecord>,
    /// Residual back-projection per stage.
    #[serde(default)]
    pub(super) residual_log: Vec<ResidualRecord>,
    /// The albedo map ([`crate::albedo`]; None without one).
    #[serde(default)]
    pub(super) albedo: Option<AlbedoMap>,
    /// Adam state of the albedo map's θ.
    #[serde(default)]
    pub(super) albedo_adam: VectorAdam,
}

/// f32 vectors stored as f64 triples: an f32 widened to f64 prints and parses back exactly (serde_json's
/// `float_roundtrip`), whereas f32 parsing goes through f64 and could round twice.
mod exact_vec3 {
    use glam::Vec3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub(super) fn serialize<S: Serializer>(v: &[Vec3], s: S) -> Result<S::Ok, S::Error> {
        v.iter().map(|p| p.as_dvec3().to_array()).collect::<Vec<[f64; 3]>>().serialize(s)
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec3>, D::Error> {
        Ok(Vec::<[f64; 3]>::deserialize(d)?
            .into_iter()
            .map(|a| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32))
            .collect())
    }
}

/// The run's random stream ([`nlos_transient::rng::SplitMix64`]), its one `u64` of state kept in the
/// checkpoint: the next 64 bits.
pub(super) fn next_u64(state: &mut u64) -> u64 {
    let mut g = nlos_transient::rng::SplitMix64::new(*state);
    let bits = g.next_u64();
    *state = g.state();
    bits
}

/// FNV-1a over the measurement's shape and bits: ties a checkpoint to its measurement.
pub(super) fn fingerprint(measured: &Transient) -> u64 {
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
pub(super) struct SettingsRecord {
    pub(super) version: u32,
    pub(super) params: serde_json::Value,
}

/// The version of [`SettingsRecord`] this build writes.
pub(super) const SETTINGS_VERSION: u32 = 1;

impl SettingsRecord {
    pub(super) fn of(params: &ReconstructParams) -> Result<Self> {
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
pub(super) fn first_difference(
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

/// Writes `bytes` to `path` atomically (temporary file in the same directory + rename).
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    let io = |source| OptimError::Io { path: path.to_owned(), fix: OptimError::WRITE_FIX, source };
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)
}

pub(super) fn json_bytes<T: Serialize>(v: &T, path: &Path) -> Result<Vec<u8>> {
    serde_json::to_vec(v).map_err(|e| OptimError::Checkpoint { path: path.to_owned(), message: e.to_string() })
}

pub(super) fn write_outputs(dir: &Path, st: &State) -> Result<()> {
    let ck = dir.join(CHECKPOINT_FILE);
    write_atomic(&ck, &json_bytes(st, &ck)?)?;
    let lg = dir.join(RUN_LOG_FILE);
    write_atomic(&lg, &json_bytes(&st.log, &lg)?)
}

#[cfg(test)]
mod tests {
    use super::*;

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
