//! `batch.json`: which batch an output directory holds, written before its first trial.

use std::fs;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{BatchError, BatchPlan, Perception, Shard};

/// File name of the batch's identity, written when a batch starts.
pub const MANIFEST_FILE: &str = "batch.json";

/// What makes two runs the same batch: `--resume` continues a directory only for a run whose
/// manifest equals the one there, and `merge` reads it for a shard that left no report.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BatchManifest {
    /// Scenario name.
    pub scenario: String,
    /// SHA-256 (hex) of the scenario file's bytes, when the caller gave one.
    pub scenario_sha256: Option<String>,
    /// Scenario seed.
    pub seed: u64,
    /// Perception mode.
    pub perception: Perception,
    /// Trials of the whole scenario, before sharding.
    pub scenario_trials: u32,
    /// The shard, if any.
    pub shard: Option<Shard>,
}

impl BatchManifest {
    /// The manifest of `plan`, with the scenario file's hash if known.
    pub fn of(plan: &BatchPlan, scenario_sha256: Option<String>) -> Self {
        Self {
            scenario: plan.scenario_name.clone(),
            scenario_sha256,
            seed: plan.scenario_seed,
            perception: plan.perception,
            scenario_trials: plan.trials,
            shard: plan.shard,
        }
    }

    /// The first field in which `found` differs from `self`: `(field, self's, found's)`.
    pub fn difference(&self, found: &Self) -> Option<(&'static str, String, String)> {
        let shard = |s: Option<Shard>| s.map_or_else(|| "none".to_owned(), |s| s.to_string());
        let hash = |h: &Option<String>| h.clone().unwrap_or_else(|| "none".to_owned());
        let fields = [
            (
                "scenario",
                format!("{:?}", self.scenario),
                format!("{:?}", found.scenario),
            ),
            (
                "scenario_sha256",
                hash(&self.scenario_sha256),
                hash(&found.scenario_sha256),
            ),
            ("seed", self.seed.to_string(), found.seed.to_string()),
            (
                "perception",
                self.perception.as_str().to_owned(),
                found.perception.as_str().to_owned(),
            ),
            (
                "scenario_trials",
                self.scenario_trials.to_string(),
                found.scenario_trials.to_string(),
            ),
            ("shard", shard(self.shard), shard(found.shard)),
        ];
        fields.into_iter().find(|(_, a, b)| a != b)
    }

    /// Writes `DIR/batch.json` whole or not at all (a temporary file renamed over it).
    pub fn write(&self, out_dir: &Path) -> Result<PathBuf, BatchError> {
        let path = out_dir.join(MANIFEST_FILE);
        let mut json = serde_json::to_string_pretty(self).map_err(|source| BatchError::Json {
            path: path.clone(),
            source,
        })?;
        json.push('\n');
        write_whole(&path, json.as_bytes())?;
        Ok(path)
    }
}

/// Writes `path` through a temporary file beside it and a rename, so that a process killed
/// meanwhile leaves either the old file or the new one, never a torn one.
pub(crate) fn write_whole(path: &Path, bytes: &[u8]) -> Result<(), BatchError> {
    let mut name = path.file_name().unwrap_or_default().to_owned();
    name.push(".tmp");
    let temporary = path.with_file_name(name);
    let write_err = |source| BatchError::Write {
        path: path.to_path_buf(),
        source,
    };
    fs::write(&temporary, bytes).map_err(write_err)?;
    fs::rename(&temporary, path).map_err(write_err)
}
