//! `twincell run`: a scenario's trials as a headless batch.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Result;
use clap::Args;
use sha2::{Digest, Sha256};
use twincell::batch::{
    BatchOptions, BatchPlan, BatchSummary, HtmlPage, Perception, RoundnessLimits, Shard,
    TrialImages, cancel_on_signals, run_batch_with,
};
#[cfg(feature = "record")]
use twincell::record::{DEFAULT_VIEWER_ADDR, RerunRecorder};
use twincell::scenario::{Override, Scenario};
use twincell::task::CellTrialRunner;

use super::BadInput;

/// Arguments of `twincell run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The scenario file (TOML).
    scenario: PathBuf,
    /// Scenario seed (overrides the file's).
    #[arg(long)]
    seed: Option<u64>,
    /// Number of trials (overrides the file's).
    #[arg(long)]
    trials: Option<u32>,
    /// Override a scenario key before validation, e.g. `sensor.noise_sigma=4` or
    /// `part_types.axle_c44.grip_force_n=80` (repeatable; see docs/suite.md).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<Override>,
    /// Output directory for trials.jsonl, report.json and junit.xml.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Continue the batch a killed run left in DIR (its output directory): keep its finished
    /// trials and run the rest. DIR must hold the same scenario file, seed, perception, trial
    /// count and shard (exit 2 otherwise); an empty or missing DIR starts the batch there.
    #[arg(long, value_name = "DIR", conflicts_with = "out")]
    resume: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    jobs: Option<usize>,
    /// Run only shard I of N (trials with index % N == I).
    #[arg(long, value_name = "I/N")]
    shard: Option<Shard>,
    /// Where perception's answers come from.
    #[arg(long, value_enum, default_value_t = Perception::Camera)]
    perception: Perception,
    /// The detector model for camera perception (default: the shipped one).
    #[arg(long, value_name = "FILE.onnx")]
    model: Option<PathBuf>,
    /// Least success rate that passes, in [0, 1] (exit code 1 below it); replaces the
    /// scenario file's `min_success`.
    #[arg(long, value_name = "RATE", value_parser = super::parse_rate)]
    min_success: Option<f64>,
    /// Print report.json to stdout instead of the summary table.
    #[arg(long)]
    pub json: bool,
    /// Record the trials into a Rerun recording (.rrd) for the viewer of Rerun 0.36.
    #[cfg(feature = "record")]
    #[arg(long, value_name = "FILE.rrd", conflicts_with = "connect")]
    record: Option<PathBuf>,
    /// Stream the trials to a running Rerun 0.36 viewer (HOST:PORT).
    #[cfg(feature = "record")]
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_VIEWER_ADDR)]
    connect: Option<String>,
}

/// Runs `twincell run`.
pub fn run(args: &RunArgs) -> Result<ExitCode> {
    let summary = run_scenario(args, !args.json)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary.report)?);
    } else {
        print!("{}", summary.report.summary_table());
        println!("results in {}", args.out_dir().display());
    }
    Ok(ExitCode::from(summary.exit_code()))
}

impl RunArgs {
    /// Where the batch's files go: the `--resume` directory or `--out`.
    pub fn out_dir(&self) -> &Path {
        self.resume.as_deref().unwrap_or(&self.out)
    }
}

/// SHA-256 (hex) of the scenario file at `path`, the bases it extends and the `--set`
/// overrides.
fn scenario_sha256(path: &Path, overrides: &[Override]) -> Result<String> {
    let sources = Scenario::source_files(path).map_err(|e| BadInput(e.to_string()))?;
    let mut bytes = Vec::new();
    for (i, (_, text)) in sources.iter().enumerate() {
        // A file without bases hashes as its bytes alone, as before `extends` existed.
        if i > 0 {
            bytes.extend_from_slice(b"\n--base\n");
        }
        bytes.extend_from_slice(text.as_bytes());
    }
    // A batch run with `--set` overrides is a different scenario from the file alone.
    for o in overrides {
        bytes.extend_from_slice(format!("\n--set {o}").as_bytes());
    }
    Ok(format!("{:x}", Sha256::digest(&bytes)))
}

/// Loads the scenario, applies the overrides and runs the batch (with a progress bar when
/// `progress`), writing the output directory.
pub fn run_scenario(args: &RunArgs, progress: bool) -> Result<BatchSummary> {
    let mut scenario =
        Scenario::load_with(&args.scenario, &args.set).map_err(|e| BadInput(e.to_string()))?;
    if let Some(seed) = args.seed {
        scenario.seed = seed;
    }
    if let Some(trials) = args.trials {
        if trials == 0 {
            return Err(BadInput("--trials: must be at least 1".into()).into());
        }
        scenario.trials = trials;
    }
    let plan = BatchPlan {
        scenario_name: scenario.name.clone(),
        scenario_seed: scenario.seed,
        perception: args.perception,
        trials: scenario.trials,
        jobs: args.jobs,
        shard: args.shard,
        min_success: args.min_success.or(scenario.min_success),
    };
    let mut runner = match &args.model {
        Some(model) => {
            CellTrialRunner::with_model(scenario, &args.scenario, args.perception, model)
        }
        None => CellTrialRunner::new(scenario, &args.scenario, args.perception),
    }
    .map_err(|e| BadInput(format!("{}: {e}", args.scenario.display())))?;
    if args.perception == Perception::Camera {
        runner.observe_with(Arc::new(TrialImages::new(args.out_dir())));
    }
    #[cfg(feature = "record")]
    let recorder = recorder(args, &plan)?;
    #[cfg(feature = "record")]
    if let Some(recorder) = &recorder {
        runner.observe_with(Arc::new(recorder.clone()));
    }
    let limits = RoundnessLimits::of(runner.scenario());
    let cancel = Arc::new(AtomicBool::new(false));
    cancel_on_signals(&cancel)?;
    let options = BatchOptions {
        scenario_sha256: Some(scenario_sha256(&args.scenario, &args.set)?),
        resume: args.resume.is_some(),
    };
    let summary = run_batch_with(&runner, &plan, &options, args.out_dir(), &cancel, progress)
        .map_err(|e| {
            if e.is_bad_input() {
                anyhow::Error::new(BadInput(e.to_string()))
            } else {
                e.into()
            }
        })?;
    HtmlPage::for_batch(&summary.report, args.out_dir())?
        .with_roundness_limits(Some(limits))
        .write(args.out_dir())?;
    #[cfg(feature = "record")]
    if let Some(recorder) = recorder {
        recorder.finish()?;
    }
    Ok(summary)
}

/// The recorder `--record` or `--connect` asks for; one recording per batch, named after it.
#[cfg(feature = "record")]
fn recorder(args: &RunArgs, plan: &BatchPlan) -> Result<Option<RerunRecorder>> {
    let name = format!(
        "{}-{:?}-seed{}",
        plan.scenario_name, plan.perception, plan.scenario_seed
    )
    .to_lowercase();
    if let Some(path) = &args.record {
        if path.extension().is_none_or(|e| e != "rrd") {
            let reason = "the file name must end in .rrd";
            return Err(BadInput(format!("--record: {reason}: {}", path.display())).into());
        }
        let recorder =
            RerunRecorder::save(path, &name).map_err(|e| BadInput(format!("--record: {e}")))?;
        return Ok(Some(recorder));
    }
    match &args.connect {
        Some(addr) => Ok(Some(
            RerunRecorder::connect(addr, &name).map_err(|e| BadInput(format!("--connect: {e}")))?,
        )),
        None => Ok(None),
    }
}
