//! `twincell bench`: a scenario's trials run as `twincell run` does, reported as the wall-clock
//! share of each stage (physics, render, detection, metrology, planning) per trial, beside the
//! simulated seconds of each phase of the cell's cycle and how the arm moved.

use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use serde::Serialize;
use twincell::batch::StageTiming;
use twincell::outcome::TrialRecord;

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

/// One phase's simulated time.
#[derive(Debug, Serialize)]
struct PhaseCost {
    phase: &'static str,
    /// Mean simulated seconds per trial.
    mean_s: f64,
}

/// The arm's motion over the batch, as the physics measured it.
#[derive(Debug, Default, Serialize)]
struct MotionSummary {
    /// Mean simulated cycle, s.
    mean_cycle_s: f64,
    /// Largest measured joint speed over its limit.
    max_joint_speed_ratio: f64,
    /// Smallest measured distance of a joint from its position limits, rad.
    min_joint_limit_margin_rad: f64,
    /// Largest commanded-to-measured joint difference, rad.
    max_tracking_error_rad: f64,
    /// Largest drift of a held part in the jaws, mm.
    max_grip_drift_mm: f64,
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
    /// Summed trial wall time per simulated second: what a simulated second costs on one core,
    /// comparable between scenarios of different lengths (a tracked stream and a stopping one).
    wall_per_sim_s: f64,
    stages: Vec<StageCost>,
    /// Simulated seconds per phase of the cell's cycle, mean per trial.
    phases: Vec<PhaseCost>,
    motion: MotionSummary,
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
    let records: Vec<TrialRecord> = std::fs::read_to_string(&summary.trials_path)
        .map(|text| {
            text.lines()
                .filter_map(|line| serde_json::from_str(line).ok())
                .collect()
        })
        .unwrap_or_default();
    let sim_time_s = records.iter().map(|r| r.sim_time_s).sum();
    let (phases, motion) = motion_summary(&records);
    let bench = BenchReport {
        scenario: report.scenario.clone(),
        perception: report.perception.as_str(),
        trials: report.trials,
        successes: report.successes,
        jobs: report.timing.jobs,
        wall_s: report.timing.batch_wall_s,
        sim_time_s,
        trial_total_s,
        wall_per_sim_s: if sim_time_s > 0.0 {
            trial_total_s / sim_time_s
        } else {
            0.0
        },
        stages: costs,
        phases,
        motion,
    };
    if args.run.json {
        println!("{}", serde_json::to_string_pretty(&bench)?);
    } else {
        println!(
            "{} ({}): {}/{} trials, wall {:.1} s with {} jobs, {:.0} s simulated, \
             {:.3} s of trial wall a simulated second",
            bench.scenario,
            bench.perception,
            bench.successes,
            bench.trials,
            bench.wall_s.unwrap_or(f64::NAN),
            bench.jobs.map_or_else(|| "?".into(), |j| j.to_string()),
            bench.sim_time_s,
            bench.wall_per_sim_s
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
        println!("{:<12}{:>10}", "phase", "sim s");
        for p in &bench.phases {
            println!("{:<12}{:>10.3}", p.phase, p.mean_s);
        }
        let m = &bench.motion;
        println!(
            "cycle {:.2} s; joint speed {:.2} of its limit; limit margin {:.3} rad; \
             tracking {:.4} rad; grip drift {:.2} mm",
            m.mean_cycle_s,
            m.max_joint_speed_ratio,
            m.min_joint_limit_margin_rad,
            m.max_tracking_error_rad,
            m.max_grip_drift_mm
        );
    }
    Ok(ExitCode::from(summary.exit_code()))
}

/// Mean simulated seconds per phase and the extremes of the measured motion over `records`.
fn motion_summary(records: &[TrialRecord]) -> (Vec<PhaseCost>, MotionSummary) {
    let count = records.len().max(1) as f64;
    let mut phases: Vec<PhaseCost> = twincell::outcome::Phase::ALL
        .into_iter()
        .map(|phase| PhaseCost {
            phase: phase.as_str(),
            mean_s: 0.0,
        })
        .collect();
    let mut motion = MotionSummary {
        min_joint_limit_margin_rad: if records.is_empty() { 0.0 } else { f64::MAX },
        ..MotionSummary::default()
    };
    for record in records {
        for (cost, (_, s)) in phases.iter_mut().zip(record.motion.phase_s.iter()) {
            cost.mean_s += s / count;
        }
        let m = &record.motion;
        motion.mean_cycle_s += record.cycle_time_s / count;
        motion.max_joint_speed_ratio = motion.max_joint_speed_ratio.max(m.joint_speed_ratio);
        motion.min_joint_limit_margin_rad = motion
            .min_joint_limit_margin_rad
            .min(m.joint_limit_margin_rad);
        motion.max_tracking_error_rad = motion.max_tracking_error_rad.max(m.tracking_error_rad);
        motion.max_grip_drift_mm = motion.max_grip_drift_mm.max(m.grip_drift_mm);
    }
    (phases, motion)
}
