//! The options `suite` and `sweep` share with `run`, and one batch run through them.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Result;
use clap::Args;
use twincell::batch::{BatchPlan, BatchSummary, Perception, Shard, TrialImages, run_batch};
use twincell::scenario::Scenario;
use twincell::task::CellTrialRunner;

use super::BadInput;

/// Options of `run` that `suite` and `sweep` take too.
#[derive(Debug, Args)]
pub struct BatchOptions {
    /// Scenario seed for every batch (overrides the files').
    #[arg(long)]
    pub seed: Option<u64>,
    /// Trials per batch (overrides the files').
    #[arg(long)]
    pub trials: Option<u32>,
    /// Output directory: report.json here, each batch's files in a directory below.
    #[arg(long, value_name = "DIR", default_value = "out")]
    pub out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Run only shard I of N of every batch (trials with index % N == I).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,
    /// Where perception's answers come from.
    #[arg(long, value_enum, default_value_t = Perception::Camera)]
    pub perception: Perception,
    /// The detector model for camera perception (default: the shipped one).
    #[arg(long, value_name = "FILE.onnx")]
    pub model: Option<PathBuf>,
    /// Least success rate each batch must reach, in [0, 1] (exit code 1 when one does not);
    /// replaces each scenario file's own `min_success`.
    #[arg(long, value_name = "RATE", value_parser = super::parse_rate)]
    pub min_success: Option<f64>,
    /// Print report.json to stdout instead of the summary table.
    #[arg(long)]
    pub json: bool,
}

impl BatchOptions {
    /// `scenario` with `--seed` and `--trials` applied.
    pub fn adjust(&self, mut scenario: Scenario) -> Result<Scenario> {
        if let Some(seed) = self.seed {
            scenario.seed = seed;
        }
        if let Some(trials) = self.trials {
            if trials == 0 {
                return Err(BadInput("--trials: must be at least 1".into()).into());
            }
            scenario.trials = trials;
        }
        Ok(scenario)
    }

    /// Runs `scenario` (read from `path`) as one batch into `out`, as `run` does.
    pub fn run_batch(
        &self,
        scenario: Scenario,
        path: &Path,
        out: &Path,
        cancel: &AtomicBool,
    ) -> Result<BatchSummary> {
        let plan = BatchPlan {
            scenario_name: scenario.name.clone(),
            scenario_seed: scenario.seed,
            perception: self.perception,
            trials: scenario.trials,
            jobs: self.jobs,
            shard: self.shard,
            min_success: self.min_success.or(scenario.min_success),
        };
        let mut runner = match &self.model {
            Some(model) => CellTrialRunner::with_model(scenario, path, self.perception, model),
            None => CellTrialRunner::new(scenario, path, self.perception),
        }
        .map_err(|e| BadInput(format!("{}: {e}", path.display())))?;
        if self.perception == Perception::Camera {
            runner.observe_with(Arc::new(TrialImages::new(out)));
        }
        Ok(run_batch(&runner, &plan, out, cancel, !self.json)?)
    }
}
