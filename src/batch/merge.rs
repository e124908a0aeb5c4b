//! Merging shard outputs (`--shard I/N` runs) into the files one unsharded run would write.

use std::collections::BTreeMap;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::{
    BatchError, BatchReport, MANIFEST_FILE, Perception, REPORT_FILE, ReportMeta, ResumeError,
    Shard, TRIALS_FILE, TrialRecord, copy_trial_images, parse_trial_lines, read_manifest,
    trial_seed, write_reports,
};

/// Why shard outputs could not be merged.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// No shard directories were given.
    #[error("no shard directories to merge")]
    NoInputs,
    /// A shard file could not be read.
    #[error("cannot read: {source}: {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: io::Error,
    },
    /// A shard's `report.json` is not JSON or lacks a field merging needs.
    #[error("malformed shard report: {source}: {}", path.display())]
    MalformedReport {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: serde_json::Error,
    },
    /// A line of a shard's `trials.jsonl` is not a trial record.
    #[error("malformed trial record on line {line}: {source}: {}", path.display())]
    MalformedLine {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The cause.
        source: serde_json::Error,
    },
    /// A shard was run with other settings than the first one.
    #[error("shard does not match {}: field `{field}` is {found}, expected {expected}: {}", first.display(), path.display())]
    Mismatch {
        /// The shard's `report.json`.
        path: PathBuf,
        /// The first shard's `report.json`, which the others must match.
        first: PathBuf,
        /// The field that differs.
        field: &'static str,
        /// Its value in the first shard.
        expected: String,
        /// Its value here.
        found: String,
    },
    /// A record does not belong in its shard: wrong seed, index out of range or of the shard.
    #[error("trial {trial} on line {line}: field `{field}` {reason}: {}", path.display())]
    ForeignRecord {
        /// The shard's `trials.jsonl`.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The record's trial index.
        trial: u32,
        /// The offending field.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// Two shards both hold the same trial.
    #[error("trial {trial} on line {line} is already in {}: {}", first.display(), path.display())]
    Overlap {
        /// The `trials.jsonl` that repeats the trial.
        path: PathBuf,
        /// 1-based line number there.
        line: usize,
        /// The trial index.
        trial: u32,
        /// The `trials.jsonl` that had it first.
        first: PathBuf,
    },
    /// A shard has neither `report.json` nor `batch.json`.
    #[error("no report.json or batch.json: not a shard's output directory: {}", dir.display())]
    NotAShard {
        /// The directory.
        dir: PathBuf,
    },
    /// A shard's `batch.json` (read when it left no report) is malformed.
    #[error(transparent)]
    Manifest(ResumeError),
    /// The merged files could not be written.
    #[error(transparent)]
    Output(#[from] BatchError),
}

impl MergeError {
    /// Whether the fault lies in the inputs (exit code 2) rather than in writing the output.
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, Self::Output(_))
    }
}

/// The part of a shard's `report.json` that says which batch it belongs to.
#[derive(Debug, Clone, PartialEq, Deserialize)]
struct ShardHeader {
    scenario: String,
    seed: u64,
    perception: Perception,
    scenario_trials: u32,
    shard: Option<Shard>,
    interrupted: bool,
}

/// What a merge produced.
#[derive(Debug, Clone)]
pub struct MergeSummary {
    /// The merged statistics written to `report.json`.
    pub report: BatchReport,
    /// Trials of the scenario that no shard holds (a shard missing or interrupted).
    pub missing_trials: u32,
    /// `DIR/trials.jsonl`.
    pub trials_path: PathBuf,
    /// `DIR/report.json`.
    pub report_path: PathBuf,
    /// `DIR/junit.xml`.
    pub junit_path: PathBuf,
}

fn check_same(
    path: &Path,
    first: &Path,
    field: &'static str,
    expected: String,
    found: String,
) -> Result<(), MergeError> {
    if expected == found {
        return Ok(());
    }
    Err(MergeError::Mismatch {
        path: path.to_path_buf(),
        first: first.to_path_buf(),
        field,
        expected,
        found,
    })
}

/// Trials of a scenario of `trials` trials that lie in `shard`.
fn shard_trial_count(trials: u32, shard: Option<Shard>) -> u32 {
    match shard {
        None => trials,
        Some(s) if s.index < trials => (trials - 1 - s.index) / s.count + 1,
        Some(_) => 0,
    }
}

/// The header of the shard in `dir`: from its `report.json`, or, for a shard killed before
/// it wrote one, from its `batch.json` (and then interrupted unless every trial is there;
/// `complete` is set once the records are counted).
fn shard_header(dir: &Path) -> Result<(PathBuf, ShardHeader, bool), MergeError> {
    let report_path = dir.join(REPORT_FILE);
    match fs::read(&report_path) {
        Ok(bytes) => {
            let header =
                serde_json::from_slice(&bytes).map_err(|source| MergeError::MalformedReport {
                    path: report_path.clone(),
                    source,
                })?;
            Ok((report_path, header, true))
        }
        Err(err) if err.kind() == io::ErrorKind::NotFound => {
            let manifest = read_manifest(dir).map_err(MergeError::Manifest)?;
            let Some(manifest) = manifest else {
                return Err(MergeError::NotAShard {
                    dir: dir.to_path_buf(),
                });
            };
            let header = ShardHeader {
                scenario: manifest.scenario,
                seed: manifest.seed,
                perception: manifest.perception,
                scenario_trials: manifest.scenario_trials,
                shard: manifest.shard,
                interrupted: false,
            };
            Ok((dir.join(MANIFEST_FILE), header, false))
        }
        Err(source) => Err(MergeError::Read {
            path: report_path,
            source,
        }),
    }
}

/// One record of a shard, with the exact line it was read from.
struct ShardLine {
    path: PathBuf,
    line: String,
    record: TrialRecord,
}

/// Merges the shard directories `dirs` (each holding `trials.jsonl` and `report.json` from
/// `twincell run --shard`) into `out_dir`: `trials.jsonl` in trial order with each line copied
/// byte for byte, so it equals an unsharded run's (timing aside), plus `report.json` and
/// `junit.xml` built from the merged records, and each merged trial's camera frame from its
/// shard's `images/`.
///
/// All shards must share scenario, seed, perception, trial count and shard count; every record
/// must carry its derived seed, lie in its shard, and appear in only one shard. A shard that
/// was interrupted makes the merged report interrupted; `min_success` sets its gate.
///
/// A shard killed before it wrote `report.json` is read as `--resume` reads it: its header
/// comes from `batch.json`, a torn last line is dropped, and its complete records count.
pub fn merge_shards(
    dirs: &[PathBuf],
    out_dir: &Path,
    min_success: Option<f64>,
) -> Result<MergeSummary, MergeError> {
    if let Some(value) = min_success
        && !(0.0..=1.0).contains(&value)
    {
        return Err(BatchError::MinSuccess { value }.into());
    }
    let mut first: Option<(PathBuf, ShardHeader)> = None;
    let mut interrupted = false;
    let mut by_trial: BTreeMap<u32, ShardLine> = BTreeMap::new();
    for dir in dirs {
        let (report_path, header, has_report) = shard_header(dir)?;
        let (first_path, expected) =
            first.get_or_insert_with(|| (report_path.clone(), header.clone()));
        let same = |field: &'static str, expected: String, found: String| {
            check_same(&report_path, first_path, field, expected, found)
        };
        same(
            "scenario",
            format!("{:?}", expected.scenario),
            format!("{:?}", header.scenario),
        )?;
        same("seed", expected.seed.to_string(), header.seed.to_string())?;
        same(
            "perception",
            expected.perception.as_str().to_owned(),
            header.perception.as_str().to_owned(),
        )?;
        same(
            "scenario_trials",
            expected.scenario_trials.to_string(),
            header.scenario_trials.to_string(),
        )?;
        let shard_count = |h: &ShardHeader| {
            h.shard
                .map_or_else(|| "none".to_owned(), |s| s.count.to_string())
        };
        same("shard.count", shard_count(expected), shard_count(&header))?;
        let trials_path = dir.join(TRIALS_FILE);
        let bytes = match fs::read(&trials_path) {
            Ok(bytes) => bytes,
            // Killed between writing batch.json and its first record.
            Err(err) if !has_report && err.kind() == io::ErrorKind::NotFound => Vec::new(),
            Err(source) => {
                return Err(MergeError::Read {
                    path: trials_path,
                    source,
                });
            }
        };
        let lines = parse_trial_lines(&trials_path, &bytes).map_err(|err| match err {
            ResumeError::MalformedLine { path, line, source } => {
                MergeError::MalformedLine { path, line, source }
            }
            other => MergeError::Manifest(other),
        })?;
        // A shard killed before its report (no report.json, or a torn last line) is
        // interrupted unless every one of its trials made it to disk.
        let all_there = u32::try_from(lines.lines.len())
            .is_ok_and(|n| n >= shard_trial_count(header.scenario_trials, header.shard));
        interrupted |= header.interrupted || (!has_report && !all_there) || lines.torn_tail;
        for (line_index, shard_line) in lines.lines.into_iter().enumerate() {
            let line_no = line_index + 1;
            let record = shard_line.record;
            let foreign = |field, reason: String| MergeError::ForeignRecord {
                path: trials_path.clone(),
                line: line_no,
                trial: record.trial,
                field,
                reason,
            };
            if record.trial >= header.scenario_trials {
                return Err(foreign(
                    "trial",
                    format!(
                        "is not below the scenario's {} trials",
                        header.scenario_trials
                    ),
                ));
            }
            if let Some(shard) = header.shard
                && !shard.contains(record.trial)
            {
                return Err(foreign("trial", format!("is not in shard {shard}")));
            }
            let seed = trial_seed(header.seed, record.trial);
            if record.seed != seed {
                return Err(foreign(
                    "seed",
                    format!(
                        "is {}, expected {seed} from scenario seed {}",
                        record.seed, header.seed
                    ),
                ));
            }
            if let Some(earlier) = by_trial.get(&record.trial) {
                return Err(MergeError::Overlap {
                    path: trials_path.clone(),
                    line: line_no,
                    trial: record.trial,
                    first: earlier.path.clone(),
                });
            }
            by_trial.insert(
                record.trial,
                ShardLine {
                    path: trials_path.clone(),
                    line: shard_line.text,
                    record,
                },
            );
        }
    }
    let Some((_, header)) = first else {
        return Err(MergeError::NoInputs);
    };

    fs::create_dir_all(out_dir).map_err(|source| BatchError::CreateDir {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let trials_path = out_dir.join(TRIALS_FILE);
    let mut text = String::new();
    for shard_line in by_trial.values() {
        text.push_str(&shard_line.line);
        text.push('\n');
    }
    fs::write(&trials_path, text).map_err(|source| BatchError::Write {
        path: trials_path.clone(),
        source,
    })?;
    copy_trial_images(
        by_trial
            .iter()
            .map(|(&trial, l)| (trial, l.path.parent().unwrap_or(Path::new(".")))),
        out_dir,
    )?;
    let records: Vec<TrialRecord> = by_trial.into_values().map(|l| l.record).collect();
    let meta = ReportMeta {
        scenario: header.scenario,
        seed: header.seed,
        perception: header.perception,
        scenario_trials: header.scenario_trials,
        shard: None,
        interrupted,
        min_success,
    };
    let report = BatchReport::from_records(&meta, &records);
    let (report_path, junit_path) = write_reports(out_dir, &report)?;
    Ok(MergeSummary {
        missing_trials: header.scenario_trials.saturating_sub(report.trials),
        report,
        trials_path,
        report_path,
        junit_path,
    })
}
