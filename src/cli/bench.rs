//! `twincell bench`: a scenario's trials run as `twincell run` does, reported as the wall-clock
//! share of each stage (physics, render, detection, metrology, planning) per trial.

use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use serde::Serialize;
use twincell::batch::StageTiming;

use super::run::{RunArgs, run_scenario};

/// Arguments of `twincell bench`: those of `twincell run`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(flatten)]
    run: RunArgs,
}

/// One stage's cost.
#[derive(Debug, Serialize)]
struct StageCost {
    stage: &'static str,
    total_s: f64,
    mean_ms: f64,
    /// Share of the summed trial wall time.
    share: f64,
}

/// What `twincell bench --json` prints.
#[derive(Debug, Serialize)]
struct BenchReport {
    scenario: String,
    perception: &'static str,
    trials: u32,
    successes: u32,
    jobs: Option<usize>,
    /// Elapsed time of the whole batch, s.
    wall_s: Option<f64>,
    /// Simulated time over all trials, s.
    sim_time_s: f64,
    /// Summed trial wall time, s (more than `wall_s` with several jobs).
    trial_total_s: f64,
    stages: Vec<StageCost>,
}

/// Runs `twincell bench`.
pub fn run(args: &BenchArgs) -> Result<ExitCode> {
    let summary = run_scenario(&args.run, !args.run.json)?;
    let report = &summary.report;
    let stages = &report.timing.stages;
    let trial_total_s = stages.trial.total_s;
    let known = [
        ("physics", &stages.physics),
        ("render", &stages.render),
        ("detect", &stages.detect),
        ("metrology", &stages.metrology),
        ("planning", &stages.planning),
    ];
    let accounted: f64 = known.iter().map(|(_, s)| s.total_s).sum();
    let other_s = (trial_total_s - accounted).max(0.0);
    let trials = report.trials.max(1);
    let other = StageTiming {
        total_s: other_s,
        mean_ms: other_s * 1e3 / f64::from(trials),
    };
    let share = |s: f64| {
        if trial_total_s > 0.0 {
            s / trial_total_s
        } else {
            0.0
        }
    };
    let costs: Vec<StageCost> = known
        .iter()
        .copied()
        .chain(std::iter::once(("other", &other)))
        .map(|(stage, t)| StageCost {
            stage,
            total_s: t.total_s,
            mean_ms: t.mean_ms,
            share: share(t.total_s),
        })
        .collect();
    let sim_time_s = std::fs::read_to_string(&summary.trials_path)
        .map(|text| {
            text.lines()
                .filter_map(|line| serde_json::from_str::<serde_json::Value>(line).ok())
                .filter_map(|v| v["sim_time_s"].as_f64())
                .sum()
        })
        .unwrap_or(0.0);
    let bench = BenchReport {
        scenario: report.scenario.clone(),
        perception: report.perception.as_str(),
        trials: report.trials,
        successes: report.successes,
        jobs: report.timing.jobs,
        wall_s: report.timing.batch_wall_s,
        sim_time_s,
        trial_total_s,
        stages: costs,
    };
    if args.run.json {
        println!("{}", serde_json::to_string_pretty(&bench)?);
    } else {
        println!(
            "{} ({}): {}/{} trials, wall {:.1} s with {} jobs, {:.0} s simulated",
            bench.scenario,
            bench.perception,
            bench.successes,
            bench.trials,
            bench.wall_s.unwrap_or(f64::NAN),
            bench.jobs.map_or_else(|| "?".into(), |j| j.to_string()),
            bench.sim_time_s
        );
        println!(
            "{:<12}{:>10}{:>12}{:>8}",
            "stage", "total s", "ms/trial", "share"
        );
        for c in &bench.stages {
            println!(
                "{:<12}{:>10.2}{:>12.1}{:>7.1}%",
                c.stage,
                c.total_s,
                c.mean_ms,
                100.0 * c.share
            );
        }
    }
    Ok(ExitCode::from(summary.exit_code()))
}
