//! `twincell fk` and `twincell ik`.

use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::Serialize;
use twincell::kinematics::{AnalyticIk, ArmModel, IkSolver, flange_pose};

use super::BadInput;

/// Arguments of `twincell fk`.
#[derive(Debug, Args)]
pub struct FkArgs {
    /// Joint angles q1..q6 in radians (controller / URDF convention).
    #[arg(num_args = 6, value_names = ["Q1", "Q2", "Q3", "Q4", "Q5", "Q6"], allow_negative_numbers = true, required = true)]
    q: Vec<f64>,
    /// Print JSON to stdout.
    #[arg(long)]
    json: bool,
}

/// Arguments of `twincell ik`.
#[derive(Debug, Args)]
pub struct IkArgs {
    /// Flange pose in the base_link frame: x y z (m), roll pitch yaw (rad, R = Rz Ry Rx).
    #[arg(num_args = 6, value_names = ["X", "Y", "Z", "ROLL", "PITCH", "YAW"], allow_negative_numbers = true, required = true)]
    pose: Vec<f64>,
    /// Print JSON to stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct FkReport {
    xyz: [f64; 3],
    rpy: [f64; 3],
    matrix: [[f64; 4]; 4],
}

#[derive(Serialize)]
struct IkReport {
    solutions: Vec<[f64; 6]>,
}

fn six(values: &[f64], what: &str) -> Result<[f64; 6]> {
    let Ok(array) = <[f64; 6]>::try_from(values) else {
        return Err(BadInput(format!("{what}: expected 6 numbers, got {}", values.len())).into());
    };
    if let Some(i) = array.iter().position(|v| !v.is_finite()) {
        return Err(BadInput(format!("{what}: value {} is not finite", i + 1)).into());
    }
    Ok(array)
}

/// Runs `twincell fk`.
pub fn run_fk(args: &FkArgs) -> Result<ExitCode> {
    let q = six(&args.q, "joint angles")?;
    let arm = ArmModel::aubo_i5();
    let pose = flange_pose(&arm, &q);
    let (roll, pitch, yaw) = pose.rotation.euler_angles();
    let m = pose.to_homogeneous();
    let report = FkReport {
        xyz: pose.translation.vector.into(),
        rpy: [roll, pitch, yaw],
        matrix: std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)])),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!(
            "flange xyz [m]:    {:.6} {:.6} {:.6}",
            report.xyz[0], report.xyz[1], report.xyz[2]
        );
        println!(
            "flange rpy [rad]:  {:.6} {:.6} {:.6}",
            report.rpy[0], report.rpy[1], report.rpy[2]
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Runs `twincell ik`.
pub fn run_ik(args: &IkArgs) -> Result<ExitCode> {
    let [x, y, z, roll, pitch, yaw] = six(&args.pose, "pose")?;
    let target = Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    );
    let solver = AnalyticIk::new(ArmModel::aubo_i5())?;
    let report = IkReport {
        solutions: solver.solve(&target).into_iter().collect(),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else if report.solutions.is_empty() {
        println!("unreachable within joint limits");
    } else {
        for (i, q) in report.solutions.iter().enumerate() {
            let joints: Vec<String> = q.iter().map(|v| format!("{v:+.6}")).collect();
            println!("solution {}: {}", i + 1, joints.join(" "));
        }
    }
    Ok(ExitCode::SUCCESS)
}
