//! `twincell merge`: shard outputs into one batch's files.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use twincell::batch::{HtmlPage, exit_code, merge_shards};

use super::BadInput;

/// Arguments of `twincell merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Shard output directories, each holding `trials.jsonl` and `report.json`.
    #[arg(required = true, value_name = "DIR")]
    dirs: Vec<PathBuf>,
    /// Directory for the merged `trials.jsonl`, `report.json`, `junit.xml`, `report.html` and
    /// the shards' camera frames (`images/`).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Least success rate that passes, in [0, 1] (exit code 1 below it).
    #[arg(long, value_name = "RATE", value_parser = super::parse_rate)]
    min_success: Option<f64>,
    /// Print the merged report.json to stdout instead of the summary table.
    #[arg(long)]
    json: bool,
}

/// Runs `twincell merge`.
pub fn run(args: &MergeArgs) -> Result<ExitCode> {
    let summary = match merge_shards(&args.dirs, &args.out, args.min_success) {
        Ok(summary) => summary,
        Err(err) if err.is_bad_input() => return Err(BadInput(err.to_string()).into()),
        Err(err) => return Err(err.into()),
    };
    HtmlPage::for_batch(&summary.report, &args.out)?.write(&args.out)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary.report)?);
    } else {
        print!("{}", summary.report.summary_table());
    }
    if summary.missing_trials > 0 {
        // Partial coverage is reported, not refused: the merged files are written.
        eprintln!(
            "warning: {} of the scenario's {} trials are in no shard (a shard missing or interrupted)",
            summary.missing_trials, summary.report.scenario_trials
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::from(exit_code(&summary.report)))
}
