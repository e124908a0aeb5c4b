//! `twincell demo`: the arm visits random IK targets in the physics world.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use twincell::demo::{DemoParams, run};

/// Arguments of `twincell demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Number of random reachable targets.
    #[arg(long, default_value_t = 100)]
    targets: usize,
    /// Seed of the target sequence.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Fraction of the joint speed and acceleration limits.
    #[arg(long, default_value_t = 0.8)]
    speed: f64,
    /// An arm URDF to use instead of the built-in one.
    #[arg(long)]
    urdf: Option<PathBuf>,
    /// Largest TCP error at rest that passes, mm (exit code 1 above it).
    #[arg(long, default_value_t = 1.0)]
    max_error_mm: f64,
    /// Print JSON to stdout.
    #[arg(long)]
    json: bool,
}

/// Runs `twincell demo`.
pub fn run_demo(args: &DemoArgs) -> Result<ExitCode> {
    if !(args.speed > 0.0 && args.speed <= 1.0) {
        return Err(super::BadInput(format!("--speed: {} is not in (0, 1]", args.speed)).into());
    }
    let params = DemoParams {
        targets: args.targets,
        seed: args.seed,
        speed_fraction: args.speed,
        ..DemoParams::default()
    };
    let report = run(args.urdf.as_deref(), &params)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "target      x [m]    y [m]    z [m]   move [s]  tracking [mm]  at rest [mm]  [mrad]"
        );
        for (i, t) in report.targets.iter().enumerate() {
            println!(
                "{:>6} {:>8.3} {:>8.3} {:>8.3} {:>10.3} {:>14.3} {:>13.4} {:>7.3}",
                i + 1,
                t.xyz[0],
                t.xyz[1],
                t.xyz[2],
                t.move_s,
                t.peak_tracking_mm,
                t.tcp_error_mm,
                t.tcp_angle_error_mrad
            );
        }
        println!(
            "\n{} targets, seed {}: TCP error at rest max {:.4} mm / {:.4} mrad; peak tracking error {:.3} mm; joint-limit excursion {:.1e} rad; {:.1} s simulated",
            report.targets.len(),
            report.seed,
            report.max_tcp_error_mm,
            report.max_tcp_angle_error_mrad,
            report.peak_tracking_mm,
            report.max_limit_violation_rad,
            report.sim_time_s
        );
    }
    let passed =
        report.max_tcp_error_mm <= args.max_error_mm && report.max_limit_violation_rad == 0.0;
    Ok(if passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
