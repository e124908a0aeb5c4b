//! `twincell suite DIR`: every scenario file in a directory, one batch each, one report.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use clap::Args;
use twincell::batch::{
    BatchRow, HtmlPage, PageBatch, RoundnessLimits, SuiteReport, cancel_on_signals,
    write_json_report,
};
use twincell::scenario::{Override, Scenario};

use super::BadInput;
use super::batch_options::BatchOptions;

/// Arguments of `twincell suite`.
#[derive(Debug, Args)]
pub struct SuiteArgs {
    /// Directory of scenario files (every `*.toml` in it, in file-name order).
    dir: PathBuf,
    /// Override a key of every scenario before validation (repeatable; see docs/suite.md).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<Override>,
    #[command(flatten)]
    options: BatchOptions,
}

/// Runs `twincell suite`.
pub fn run(args: &SuiteArgs) -> Result<ExitCode> {
    let opts = &args.options;
    let entries = std::fs::read_dir(&args.dir).map_err(|e| {
        BadInput(format!(
            "cannot read the suite directory: {e}: {}",
            args.dir.display()
        ))
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    if files.is_empty() {
        let reason = "holds no scenario (*.toml) file";
        return Err(BadInput(format!("{reason}: {}", args.dir.display())).into());
    }
    // Every file is checked before the first trial runs, so a typo does not cost a long suite.
    let mut scenarios = Vec::with_capacity(files.len());
    for file in &files {
        let scenario = Scenario::load_with(file, &args.set).map_err(|e| BadInput(e.to_string()))?;
        scenarios.push(opts.adjust(scenario)?);
    }
    let limits = RoundnessLimits::shared(&scenarios);
    let cancel = Arc::new(AtomicBool::new(false));
    cancel_on_signals(&cancel)?;
    let mut rows = Vec::with_capacity(files.len());
    let mut batches = Vec::with_capacity(files.len());
    for (file, scenario) in files.iter().zip(scenarios) {
        if cancel.load(Ordering::SeqCst) {
            break;
        }
        let stem = file.file_stem().map_or_else(
            || scenario.name.clone(),
            |s| s.to_string_lossy().into_owned(),
        );
        if !opts.json {
            eprintln!("suite: {} ({})", scenario.name, file.display());
        }
        let dir = opts.out.join(&stem);
        let summary = opts.run_batch(scenario, file, &dir, &cancel)?;
        rows.push(BatchRow::from_report(&summary.report, &stem));
        batches.push(PageBatch {
            label: summary.report.scenario.clone(),
            dir,
            report: summary.report,
        });
    }
    let mut report = SuiteReport::new(
        &args.dir.display().to_string(),
        opts.perception,
        opts.min_success,
        rows,
    );
    if report.scenarios.len() < files.len() {
        // An interrupted suite must not read as a pass.
        report.passed = false;
    }
    write_json_report(&opts.out, &report)?;
    let title = format!("twincell suite {}", report.suite);
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
