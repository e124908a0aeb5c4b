//! Continuing a batch in an output directory that a killed run left: reading its records back,
//! dropping a torn last line, checking they belong to the batch asked for.

use std::fs::{self, File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};

use super::{BatchError, BatchManifest, MANIFEST_FILE, TRIALS_FILE, TrialRecord, trial_seed};

/// Why a directory cannot be resumed: its files are not of the batch asked for, or are damaged.
#[derive(Debug, thiserror::Error)]
pub enum ResumeError {
    /// A file could not be read.
    #[error("cannot read: {source}: {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: io::Error,
    },
    /// `batch.json` is not a manifest.
    #[error("malformed batch manifest: {source}: {}", path.display())]
    MalformedManifest {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: serde_json::Error,
    },
    /// The directory holds trials but no `batch.json` saying which batch they belong to.
    #[error("cannot resume: trials.jsonl holds records but there is no batch.json naming their batch: {}", dir.display())]
    NoManifest {
        /// The directory.
        dir: PathBuf,
    },
    /// The directory holds another batch.
    #[error("cannot resume another batch: field `{field}` is {found} there, {expected} in this run: {}", path.display())]
    Mismatch {
        /// The directory's `batch.json`.
        path: PathBuf,
        /// The field that differs.
        field: &'static str,
        /// Its value for this run.
        expected: String,
        /// Its value in the directory.
        found: String,
    },
    /// A complete line of `trials.jsonl` is not a trial record.
    #[error("malformed trial record on line {line}: {source}: {}", path.display())]
    MalformedLine {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The cause.
        source: serde_json::Error,
    },
    /// A record is not the trial the batch writes at its place.
    #[error("trial {trial} on line {line}: {reason}: {}", path.display())]
    OutOfPlace {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The record's trial index.
        trial: u32,
        /// What was expected instead.
        reason: String,
    },
}

/// One complete line of a `trials.jsonl` and its record.
#[derive(Debug, Clone)]
pub struct TrialLine {
    /// The line as written, without its newline.
    pub text: String,
    /// The record it holds.
    pub record: TrialRecord,
}

/// The complete records of a `trials.jsonl`, in file order.
#[derive(Debug, Clone, Default)]
pub struct TrialLines {
    /// Every line that ends in a newline.
    pub lines: Vec<TrialLine>,
    /// Bytes up to and including the last newline: the part of the file to keep.
    pub complete_len: u64,
    /// Whether bytes after the last newline were dropped (a line torn by a kill).
    pub torn_tail: bool,
}

/// Parses `bytes` of the file `path` as trial records, one a line. A last line without its
/// newline is torn (the writer ends every line with one) and is dropped; any complete line
/// that is not a record is an error naming the line.
pub fn parse_trial_lines(path: &Path, bytes: &[u8]) -> Result<TrialLines, ResumeError> {
    let complete = bytes
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |last| last + 1);
    let mut lines = Vec::new();
    if complete > 0 {
        let body = bytes.get(..complete - 1).unwrap_or_default();
        for (index, raw) in body.split(|&b| b == b'\n').enumerate() {
            let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
            let malformed = |source| ResumeError::MalformedLine {
                path: path.to_path_buf(),
                line: index + 1,
                source,
            };
            let record: TrialRecord = serde_json::from_slice(raw).map_err(malformed)?;
            // The parse succeeded, so the line is UTF-8.
            let text = String::from_utf8_lossy(raw).into_owned();
            lines.push(TrialLine { text, record });
        }
    }
    Ok(TrialLines {
        lines,
        complete_len: complete as u64,
        torn_tail: complete < bytes.len(),
    })
}

/// Reads `path` with [`parse_trial_lines`]; a missing file has no lines.
pub fn read_trial_lines(path: &Path) -> Result<TrialLines, ResumeError> {
    match fs::read(path) {
        Ok(bytes) => parse_trial_lines(path, &bytes),
        Err(err) if err.kind() == io::ErrorKind::NotFound => Ok(TrialLines::default()),
        Err(source) => Err(ResumeError::Read {
            path: path.to_path_buf(),
            source,
        }),
    }
}

/// Reads `DIR/batch.json`, or `None` when there is none.
pub fn read_manifest(out_dir: &Path) -> Result<Option<BatchManifest>, ResumeError> {
    let path = out_dir.join(MANIFEST_FILE);
    let bytes = match fs::read(&path) {
        Ok(bytes) => bytes,
        Err(err) if err.kind() == io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(ResumeError::Read { path, source }),
    };
    serde_json::from_slice(&bytes)
        .map(Some)
        .map_err(|source| ResumeError::MalformedManifest { path, source })
}

/// Checks that `lines` are the first trials of the batch that runs `indices` (the order the
/// batch writes them in) with scenario seed `scenario_seed`.
pub fn check_prefix(
    path: &Path,
    lines: &TrialLines,
    indices: &[u32],
    scenario_seed: u64,
) -> Result<(), ResumeError> {
    for (position, line) in lines.lines.iter().enumerate() {
        let record = &line.record;
        let out_of_place = |reason: String| ResumeError::OutOfPlace {
            path: path.to_path_buf(),
            line: position + 1,
            trial: record.trial,
            reason,
        };
        let Some(&expected) = indices.get(position) else {
            return Err(out_of_place(format!(
                "the batch has only {} trials",
                indices.len()
            )));
        };
        if record.trial != expected {
            return Err(out_of_place(format!("expected trial {expected} here")));
        }
        let seed = trial_seed(scenario_seed, record.trial);
        if record.seed != seed {
            return Err(out_of_place(format!(
                "seed is {}, expected {seed} from scenario seed {scenario_seed}",
                record.seed
            )));
        }
    }
    Ok(())
}

/// Opens `DIR/trials.jsonl` to continue the batch `manifest` that runs `indices`: checks the
/// directory's manifest (writing it when the directory has none and no records), drops a torn
/// last line, and returns the records already there with the file positioned after them.
pub(crate) fn open_for_resume(
    out_dir: &Path,
    manifest: &BatchManifest,
    indices: &[u32],
) -> Result<(Vec<TrialRecord>, File), BatchError> {
    let trials_path = out_dir.join(TRIALS_FILE);
    let lines = read_trial_lines(&trials_path)?;
    match read_manifest(out_dir)? {
        Some(found) => {
            if let Some((field, expected, found)) = manifest.difference(&found) {
                return Err(ResumeError::Mismatch {
                    path: out_dir.join(MANIFEST_FILE),
                    field,
                    expected,
                    found,
                }
                .into());
            }
        }
        None if lines.lines.is_empty() => {
            manifest.write(out_dir)?;
        }
        None => {
            return Err(ResumeError::NoManifest {
                dir: out_dir.to_path_buf(),
            }
            .into());
        }
    }
    check_prefix(&trials_path, &lines, indices, manifest.seed)?;
    let write_err = |source| BatchError::Write {
        path: trials_path.clone(),
        source,
    };
    let file = OpenOptions::new()
        .create(true)
        .append(true)
        .open(&trials_path)
        .map_err(write_err)?;
    if lines.torn_tail {
        tracing::info!(
            "dropping a torn last line of {}",
            trials_path.to_string_lossy()
        );
    }
    // Appends go to the end, which is now just after the last complete line.
    file.set_len(lines.complete_len).map_err(write_err)?;
    let records = lines.lines.into_iter().map(|line| line.record).collect();
    Ok((records, file))
}
