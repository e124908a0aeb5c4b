//! `twincell sweep SCENARIO --set KEY=V1,V2 ...`: a scenario over a grid of overrides.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use clap::Args;
use twincell::batch::{
    BatchRow, HtmlPage, PageBatch, RoundnessLimits, SweepPoint, SweepReport, cancel_on_signals,
    write_json_report,
};
use twincell::scenario::{Scenario, SweepAxis, sweep_grid};

use super::BadInput;
use super::batch_options::BatchOptions;

/// Arguments of `twincell sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// The scenario file (TOML).
    scenario: PathBuf,
    /// An axis of the grid: a scenario key and its values, e.g. `conveyor.speed_m_s=0.2,0.3`
    /// or `bottle.distance_range_m=[0.07,0.08],[0.08,0.09]` (repeatable; every combination
    /// runs, the last axis varying fastest).
    #[arg(long = "set", value_name = "KEY=V1,V2,...", required = true)]
    set: Vec<SweepAxis>,
    #[command(flatten)]
    options: BatchOptions,
}

/// Runs `twincell sweep`.
pub fn run(args: &SweepArgs) -> Result<ExitCode> {
    let opts = &args.options;
    let base = opts.adjust(Scenario::load(&args.scenario).map_err(|e| BadInput(e.to_string()))?)?;
    let grid = sweep_grid(&args.set);
    // Every point is checked before the first trial runs.
    let mut scenarios = Vec::with_capacity(grid.len());
    for point in &grid {
        let scenario =
            Scenario::load_with(&args.scenario, point).map_err(|e| BadInput(e.to_string()))?;
        scenarios.push(opts.adjust(scenario)?);
    }
    let limits = RoundnessLimits::shared(&scenarios);
    let cancel = Arc::new(AtomicBool::new(false));
    cancel_on_signals(&cancel)?;
    let mut points = Vec::with_capacity(grid.len());
    let mut batches = Vec::with_capacity(grid.len());
    for (i, (overrides, scenario)) in grid.iter().zip(scenarios).enumerate() {
        if cancel.load(Ordering::SeqCst) {
            break;
        }
        let dir = format!("point-{i:03}");
        if !opts.json {
            let label: Vec<String> = overrides.iter().map(ToString::to_string).collect();
            eprintln!("sweep: point {}/{}: {}", i + 1, grid.len(), label.join(" "));
        }
        let path = opts.out.join(&dir);
        let summary = opts.run_batch(scenario, &args.scenario, &path, &cancel)?;
        let row = BatchRow::from_report(&summary.report, &dir);
        let point = SweepPoint::new(i, overrides, row);
        let label: Vec<String> = point
            .overrides
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        batches.push(PageBatch {
            label: label.join(" "),
            dir: path,
            report: summary.report,
        });
        points.push(point);
    }
    let mut report = SweepReport::new(
        &base.name,
        base.seed,
        opts.perception,
        opts.shard,
        &args.set,
        points,
    );
    if report.points.len() < grid.len() {
        // An interrupted sweep must not read as a pass.
        report.passed = false;
    }
    write_json_report(&opts.out, &report)?;
    let title = format!(
        "twincell sweep of {} (seed {})",
        report.scenario, report.seed
    );
    HtmlPage::for_batches(&title, report.perception, batches)?
        .with_roundness_limits(limits)
        .write(&opts.out)?;
    if opts.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.summary_table());
        println!("results in {}", opts.out.display());
    }
    Ok(ExitCode::from(report.exit_code()))
}
