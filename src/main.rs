//! The `twincell` command line: see `README.md` and the command-line contract in the design notes.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cli;

/// Physics-simulated digital twin of a robot sorting cell.
#[derive(Debug, Parser)]
#[command(name = "twincell", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Flange pose for joint angles (forward kinematics).
    Fk(cli::kinematics::FkArgs),
    /// Every joint solution for a flange pose (inverse kinematics).
    Ik(cli::kinematics::IkArgs),
    /// Run a scenario's sorting trials as a headless batch.
    Run(cli::run::RunArgs),
    /// Run every scenario file in a directory as a batch; one report, a row per scenario.
    Suite(cli::suite::SuiteArgs),
    /// Run a scenario over a grid of overrides (`--set KEY=V1,V2`); a row per grid point.
    Sweep(cli::sweep::SweepArgs),
    /// Drive the simulated arm through random IK targets and report tracking errors.
    Demo(cli::demo::DemoArgs),
    /// Measure every bore (dark bore inside a bright rim) in images.
    Measure(cli::measure::MeasureArgs),
    /// Run a scenario like `run` and report each stage's share of the wall time.
    Bench(cli::bench::BenchArgs),
    /// Merge `twincell run --shard` outputs into one batch's trials, report and JUnit files.
    Merge(cli::merge::MergeArgs),
    /// Render the pick station with the cell's camera: PNG plus JSON ground truth.
    Render(cli::render::RenderArgs),
    /// Write a synthetic Ultralytics/YOLO dataset of pick-station images.
    Dataset(cli::render::DatasetArgs),
    /// Find parts and bottles in images with the shipped detector network.
    Detect(cli::detect::DetectArgs),
    /// Estimate the metrology's bias and expanded uncertainty for a scenario's camera and
    /// write the band `run` uses.
    Calibrate(cli::calibrate::CalibrateArgs),
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("TWINCELL_LOG")
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result: anyhow::Result<ExitCode> = match cli.command {
        Command::Fk(args) => cli::kinematics::run_fk(&args),
        Command::Ik(args) => cli::kinematics::run_ik(&args),
        Command::Demo(args) => cli::demo::run_demo(&args),
        Command::Run(args) => cli::run::run(&args),
        Command::Suite(args) => cli::suite::run(&args),
        Command::Sweep(args) => cli::sweep::run(&args),
        Command::Bench(args) => cli::bench::run(&args),
        Command::Measure(args) => cli::measure::run(&args),
        Command::Merge(args) => cli::merge::run(&args),
        Command::Render(args) => cli::render::run_render(&args),
        Command::Dataset(args) => cli::render::run_dataset(&args),
        Command::Detect(args) => cli::detect::run(&args),
        Command::Calibrate(args) => cli::calibrate::run(&args),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            cli::exit_code_for(&err)
        }
    }
}
