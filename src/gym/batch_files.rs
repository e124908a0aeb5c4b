//! A batch of an outside controller's trials written as `twincell run` writes its own:
//! `trials.jsonl`, `report.json`, `junit.xml` and `report.html`, from one writer.

use std::fmt::Write as _;
use std::path::Path;

use crate::batch::{
    BatchError, BatchReport, HtmlPage, ReportMeta, RoundnessLimits, TRIALS_FILE, write_reports,
};
use crate::outcome::{Perception, TrialRecord};
use crate::scenario::Scenario;

/// Why a batch's files could not be written.
#[derive(Debug, thiserror::Error)]
pub enum BatchFilesError {
    /// The directory or a file could not be written.
    #[error("{path}: {source}")]
    Write {
        /// The path.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The reports could not be written.
    #[error(transparent)]
    Batch(#[from] BatchError),
    /// The page could not be written.
    #[error(transparent)]
    Html(#[from] crate::batch::HtmlError),
    /// A record did not serialise.
    #[error("record of trial {trial}: {source}")]
    Json {
        /// The trial.
        trial: u32,
        /// Why.
        source: serde_json::Error,
    },
}

/// Writes `records` (trials of `scenario` seeded `seed`, in `perception` mode) into `out_dir`
/// with the batch's report files; returns the report.
pub fn write_batch(
    scenario: &Scenario,
    seed: u64,
    perception: Perception,
    records: &[TrialRecord],
    out_dir: &Path,
) -> Result<BatchReport, BatchFilesError> {
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| BatchFilesError::Write { path, source }
    };
    std::fs::create_dir_all(out_dir).map_err(io(out_dir))?;
    let mut sorted: Vec<&TrialRecord> = records.iter().collect();
    sorted.sort_by_key(|r| r.trial);
    let mut lines = String::new();
    for record in &sorted {
        let line = serde_json::to_string(record).map_err(|source| BatchFilesError::Json {
            trial: record.trial,
            source,
        })?;
        let _ = writeln!(lines, "{line}");
    }
    let trials_path = out_dir.join(TRIALS_FILE);
    std::fs::write(&trials_path, lines).map_err(io(&trials_path))?;
    let meta = ReportMeta {
        scenario: scenario.name.clone(),
        seed,
        perception,
        scenario_trials: u32::try_from(records.len()).unwrap_or(u32::MAX),
        shard: None,
        interrupted: false,
        min_success: scenario.min_success,
    };
    let owned: Vec<TrialRecord> = sorted.into_iter().cloned().collect();
    let report = BatchReport::from_records(&meta, &owned);
    write_reports(out_dir, &report)?;
    HtmlPage::for_batch(&report, out_dir)?
        .with_roundness_limits(Some(RoundnessLimits::of(scenario)))
        .write(out_dir)?;
    Ok(report)
}
