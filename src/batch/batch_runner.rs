//! Runs a batch of trials on worker threads and streams their records to disk in trial order.

use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use super::batch_manifest::write_whole;
use super::progress_bar::ProgressBar;
use super::resume::open_for_resume;
use super::{
    BatchError, BatchManifest, BatchPlan, BatchReport, FailureReason, Outcome, ReportMeta,
    TrialRecord, TrialRunner, junit_xml, remove_trial_images, trial_seed,
};

/// File name of the trial records, one JSON object a line.
pub const TRIALS_FILE: &str = "trials.jsonl";
/// File name of the batch statistics.
pub const REPORT_FILE: &str = "report.json";
/// File name of the JUnit report.
pub const JUNIT_FILE: &str = "junit.xml";

/// What a finished (or interrupted) batch produced.
#[derive(Debug, Clone)]
pub struct BatchSummary {
    /// The statistics written to `report.json`.
    pub report: BatchReport,
    /// `DIR/trials.jsonl`.
    pub trials_path: PathBuf,
    /// `DIR/report.json`.
    pub report_path: PathBuf,
    /// `DIR/junit.xml`.
    pub junit_path: PathBuf,
}

impl BatchSummary {
    /// The process exit code of the contract: 0 passed, 1 gate failed or interrupted.
    pub fn exit_code(&self) -> u8 {
        super::exit_code(&self.report)
    }
}

/// How [`run_batch_with`] treats the output directory.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BatchOptions {
    /// SHA-256 (hex) of the scenario file, written into `batch.json` so that a resume can
    /// check it runs the same scenario.
    pub scenario_sha256: Option<String>,
    /// Continue the batch already in the directory (`--resume`) instead of starting over.
    pub resume: bool,
}

/// Runs the trials of `plan` with `runner` and writes `trials.jsonl`, `report.json` and
/// `junit.xml` into `out_dir` (created if missing, files replaced), as [`run_batch_with`] does
/// without a scenario hash and without resuming.
pub fn run_batch(
    runner: &dyn TrialRunner,
    plan: &BatchPlan,
    out_dir: &Path,
    cancel: &AtomicBool,
    progress: bool,
) -> Result<BatchSummary, BatchError> {
    run_batch_with(
        runner,
        plan,
        &BatchOptions::default(),
        out_dir,
        cancel,
        progress,
    )
}

/// Runs the trials of `plan` with `runner` and writes `batch.json`, `trials.jsonl`,
/// `report.json` and `junit.xml` into `out_dir` (created if missing).
///
/// - First `batch.json` says which batch the directory holds, and reports (and, unless
///   resuming, camera frames in `images/`) of an earlier run are removed, so a directory
///   never pairs old reports or frames with new records.
/// - Trial `i` gets seed [`trial_seed`]`(plan.scenario_seed, i)`; with a shard, only the
///   trials with `i % N == I` run.
/// - Up to [`BatchPlan::worker_count`] trials run at once. A trial that panics becomes a
///   failed record with reason `panic` and the panic message as detail; the batch goes on.
/// - Records are appended to `trials.jsonl` in trial order, each as soon as every earlier one
///   is written, one `write` per line, so the file is the same for any number of jobs (the
///   `timing` fields aside) and a killed batch leaves every finished prefix on disk.
/// - With `options.resume`, the directory's `batch.json` must equal this run's (else
///   [`ResumeError::Mismatch`](super::ResumeError)); its complete records are kept, a torn
///   last line is dropped, and only the missing trials run. The files end as an uninterrupted
///   run's would (timing aside). A directory without records is started afresh.
/// - `timing.wall_ms` of each record is set here to the trial's measured wall time.
/// - Once `cancel` is set no further trial starts; the running ones finish and are written,
///   and the reports cover them with `"interrupted": true`.
/// - `progress` asks for a progress bar on stderr; it is drawn only when stderr is a terminal.
pub fn run_batch_with(
    runner: &dyn TrialRunner,
    plan: &BatchPlan,
    options: &BatchOptions,
    out_dir: &Path,
    cancel: &AtomicBool,
    progress: bool,
) -> Result<BatchSummary, BatchError> {
    if let Some(value) = plan.min_success
        && !(0.0..=1.0).contains(&value)
    {
        return Err(BatchError::MinSuccess { value });
    }
    let started = Instant::now();
    fs::create_dir_all(out_dir).map_err(|source| BatchError::CreateDir {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let trials_path = out_dir.join(TRIALS_FILE);
    let manifest = BatchManifest::of(plan, options.scenario_sha256.clone());
    let indices = plan.trial_indices();
    let (mut records, mut trials_file) = if options.resume {
        open_for_resume(out_dir, &manifest, &indices)?
    } else {
        manifest.write(out_dir)?;
        // The camera frames of an earlier batch in this directory belong to its records.
        remove_trial_images(out_dir)?;
        let file = File::create(&trials_path).map_err(|source| BatchError::Write {
            path: trials_path.clone(),
            source,
        })?;
        (Vec::new(), file)
    };
    remove_reports(out_dir)?;

    let pending = indices.get(records.len()..).unwrap_or_default();
    let jobs = plan.worker_count(pending.len());
    let mut bar = ProgressBar::new(pending.len(), progress);
    let new_records = run_in_order(
        runner,
        plan.scenario_seed,
        pending,
        jobs,
        cancel,
        |record| {
            let mut line = serde_json::to_string(record).map_err(|source| BatchError::Json {
                path: trials_path.clone(),
                source,
            })?;
            line.push('\n');
            trials_file
                .write_all(line.as_bytes())
                .map_err(|source| BatchError::Write {
                    path: trials_path.clone(),
                    source,
                })
        },
        &mut bar,
    )?;
    bar.finish();
    records.extend(new_records);

    let meta = ReportMeta {
        scenario: plan.scenario_name.clone(),
        seed: plan.scenario_seed,
        perception: plan.perception,
        scenario_trials: plan.trials,
        shard: plan.shard,
        interrupted: records.len() < indices.len(),
        min_success: plan.min_success,
    };
    let mut report = BatchReport::from_records(&meta, &records);
    report.timing.batch_wall_s = Some(started.elapsed().as_secs_f64());
    report.timing.jobs = Some(jobs);
    let (report_path, junit_path) = write_reports(out_dir, &report)?;
    Ok(BatchSummary {
        report,
        trials_path,
        report_path,
        junit_path,
    })
}

/// Removes `report.json` and `junit.xml` of an earlier run, if any.
fn remove_reports(out_dir: &Path) -> Result<(), BatchError> {
    for name in [REPORT_FILE, JUNIT_FILE] {
        let path = out_dir.join(name);
        match fs::remove_file(&path) {
            Ok(()) => {}
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
            Err(source) => return Err(BatchError::Write { path, source }),
        }
    }
    Ok(())
}

/// Writes `report.json` and `junit.xml` of `report` into `out_dir`; returns their paths.
pub fn write_reports(
    out_dir: &Path,
    report: &BatchReport,
) -> Result<(PathBuf, PathBuf), BatchError> {
    let report_path = out_dir.join(REPORT_FILE);
    let mut json = serde_json::to_string_pretty(report).map_err(|source| BatchError::Json {
        path: report_path.clone(),
        source,
    })?;
    json.push('\n');
    write_whole(&report_path, json.as_bytes())?;
    let junit_path = out_dir.join(JUNIT_FILE);
    write_whole(&junit_path, junit_xml(report).as_bytes())?;
    Ok((report_path, junit_path))
}

/// The text of a panic payload (`&str` or `String`; anything else is named as such).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(text) = payload.downcast_ref::<&str>() {
        (*text).to_owned()
    } else if let Some(text) = payload.downcast_ref::<String>() {
        text.clone()
    } else {
        "panic with a non-string payload".to_owned()
    }
}

/// Runs one trial, turning a panic into a failed record and stamping its wall time.
fn run_one(runner: &dyn TrialRunner, index: u32, seed: u64) -> TrialRecord {
    let started = Instant::now();
    let result = catch_unwind(AssertUnwindSafe(|| runner.run_trial(index, seed)));
    let wall_ms = started.elapsed().as_secs_f64() * 1000.0;
    let mut record = match result {
        Ok(record) => record,
        Err(payload) => {
            TrialRecord::failed(index, seed, FailureReason::Panic, panic_message(&*payload))
        }
    };
    if record.trial != index || record.seed != seed {
        // The batch's bookkeeping relies on these; a runner that gets them wrong is fixed up
        // here rather than allowed to reorder or mislabel the file.
        tracing::warn!(
            "trial runner returned trial {} seed {} for trial {index} seed {seed}",
            record.trial,
            record.seed
        );
        record.trial = index;
        record.seed = seed;
    }
    record.timing.wall_ms = wall_ms;
    record
}

/// Runs the trials `indices` on `jobs` threads, hands each record to `sink` in `indices`
/// order, and returns the records handed over. Stops launching when `cancel` is set or `sink`
/// fails; the first sink error is returned after the running trials finish.
fn run_in_order(
    runner: &dyn TrialRunner,
    scenario_seed: u64,
    indices: &[u32],
    jobs: usize,
    cancel: &AtomicBool,
    mut sink: impl FnMut(&TrialRecord) -> Result<(), BatchError>,
    bar: &mut ProgressBar,
) -> Result<Vec<TrialRecord>, BatchError> {
    let next = AtomicUsize::new(0);
    let sink_failed = AtomicBool::new(false);
    let mut written = Vec::with_capacity(indices.len());
    let mut failed = 0;
    let mut first_error = None;
    std::thread::scope(|scope| {
        let (sender, receiver) = mpsc::channel::<(usize, TrialRecord)>();
        for worker in 0..jobs {
            let sender = sender.clone();
            let (next, sink_failed) = (&next, &sink_failed);
            let spawned = std::thread::Builder::new()
                .name(format!("trial-worker-{worker}"))
                .spawn_scoped(scope, move || {
                    loop {
                        if cancel.load(Ordering::SeqCst) || sink_failed.load(Ordering::SeqCst) {
                            break;
                        }
                        let position = next.fetch_add(1, Ordering::SeqCst);
                        let Some(&index) = indices.get(position) else {
                            break;
                        };
                        let seed = trial_seed(scenario_seed, index);
                        let record = run_one(runner, index, seed);
                        if sender.send((position, record)).is_err() {
                            break;
                        }
                    }
                });
            if let Err(source) = spawned {
                // Workers already started keep going; with none, nothing will ever arrive.
                if worker == 0 {
                    first_error = Some(BatchError::Spawn { source });
                }
                break;
            }
        }
        drop(sender);

        // Completions arrive in any order; hold them until all earlier ones are written.
        let mut pending: BTreeMap<usize, TrialRecord> = BTreeMap::new();
        for (position, record) in receiver {
            pending.insert(position, record);
            while let Some(record) = pending.remove(&written.len()) {
                if first_error.is_some() {
                    continue;
                }
                if let Err(err) = sink(&record) {
                    sink_failed.store(true, Ordering::SeqCst);
                    first_error = Some(err);
                    continue;
                }
                if record.outcome == Outcome::Failure {
                    failed += 1;
                }
                written.push(record);
                bar.update(written.len(), failed);
            }
        }
    });
    match first_error {
        Some(err) => Err(err),
        None => Ok(written),
    }
}
