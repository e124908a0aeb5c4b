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
    keep_freed_memory();
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
    let code = match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            cli::exit_code_for(&err)
        }
    };
    leave(code)
}

/// Has the C library's allocator keep the memory a command frees for its next allocations.
///
/// By default glibc maps each allocation over 128 KB (a frame, its area of interest, the
/// renderer's readback, the solver's buffers) fresh from the kernel and unmaps it when it is
/// freed, so every look and many steps fault their pages in again, zeroed: the main job took
/// 124 000 page faults, and 6.4 % of its CPU samples were the kernel's (perf). Served from the
/// heap and kept there, the same batch takes 69 000, and the kernel 2.1 %; the results are the
/// same (allocation never reaches them). The heap keeps the largest working set a command has.
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        unsafe extern "C" {
            /// glibc's `mallopt`: sets one of the allocator's parameters.
            fn mallopt(param: i32, value: i32) -> i32;
        }
        /// glibc's `M_TRIM_THRESHOLD` and `M_MMAP_THRESHOLD` (malloc.h).
        const M_TRIM_THRESHOLD: i32 = -1;
        const M_MMAP_THRESHOLD: i32 = -3;
        // SAFETY: `mallopt` only sets allocator parameters; it is called before any thread
        // starts, with values glibc accepts (the mmap threshold's limit is 32 MB on 64-bit).
        unsafe {
            mallopt(M_MMAP_THRESHOLD, 32 << 20);
            mallopt(M_TRIM_THRESHOLD, 1 << 30);
        }
    }
}

/// Ends the process with `code` without running the C library's exit handlers.
///
/// A command that rendered leaves Mesa's llvmpipe worker threads and LLVM's global state alive
/// to the end, and the handlers that tear them down at exit (Mesa's `atexit`, libLLVM's static
/// destructors) now and then corrupted the heap after every result was written: glibc aborted
/// the process ("double free or corruption", "corrupted size vs. prev_size"), exit 134, about
/// once in 30 camera batches on this machine, and once in a CI run's test. By the time a
/// command returns, everything it owes is written: its files are closed as it goes and when it
/// returns, and the standard streams are flushed here. So the process leaves by `_exit`.
fn leave(code: ExitCode) -> ! {
    use std::io::Write;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    // The commands exit with 0, 1 or 2; `ExitCode` only says which by comparison.
    let status = (0..=u8::MAX)
        .find(|&c| ExitCode::from(c) == code)
        .map_or(1, i32::from);
    unsafe extern "C" {
        /// POSIX `_exit`: ends the process at once, without exit handlers.
        fn _exit(status: i32) -> !;
    }
    // SAFETY: `_exit` takes any status and does not return; no Rust state is used after it.
    unsafe { _exit(status) }
}
