//! The arm demo: drives the simulated arm through random reachable IK targets and measures how
//! well the servos track and settle.

use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::Serialize;

use crate::control::TrajectoryFollower;
use crate::kinematics::{AnalyticIk, DOF, IkSolver, JointVector, tcp_pose};
use crate::planning::JointTrajectory;
use crate::rng::SimRng;
use crate::sim::{SimArm, SimError, World, WorldParams};

/// Settings of the demo.
#[derive(Debug, Clone)]
pub struct DemoParams {
    /// How many targets to visit.
    pub targets: usize,
    /// Seed of the target sequence.
    pub seed: u64,
    /// Fraction of the joint speed and acceleration limits to move at.
    pub speed_fraction: f64,
    /// Time to settle at each target before measuring.
    pub settle_s: f64,
}

impl Default for DemoParams {
    fn default() -> Self {
        Self {
            targets: 100,
            seed: 1,
            speed_fraction: 0.8,
            settle_s: 0.3,
        }
    }
}

/// The outcome at one target.
#[derive(Debug, Clone, Serialize)]
pub struct DemoTarget {
    /// Target TCP position in the base frame, m.
    pub xyz: [f64; 3],
    /// IK solution driven to.
    pub q_goal: JointVector,
    /// Motion time, s.
    pub move_s: f64,
    /// TCP position error at rest, mm.
    pub tcp_error_mm: f64,
    /// TCP orientation error at rest, mrad.
    pub tcp_angle_error_mrad: f64,
    /// Largest TCP deviation from the planned path during the move, mm.
    pub peak_tracking_mm: f64,
}

/// What the demo measured.
#[derive(Debug, Clone, Serialize)]
pub struct DemoReport {
    /// Seed used.
    pub seed: u64,
    /// One entry per target.
    pub targets: Vec<DemoTarget>,
    /// Worst TCP position error at rest, mm.
    pub max_tcp_error_mm: f64,
    /// Worst TCP orientation error at rest, mrad.
    pub max_tcp_angle_error_mrad: f64,
    /// Worst TCP deviation from the planned path while moving, mm.
    pub peak_tracking_mm: f64,
    /// Largest excursion of any joint past its limit, rad (0 when none).
    pub max_limit_violation_rad: f64,
    /// Simulated seconds.
    pub sim_time_s: f64,
}

/// A random TCP target that a gripper would use over a table: pointing down within 30 degrees,
/// any yaw, 0.3-0.7 m from the base axis, 0.05-0.5 m above the base.
fn random_target(rng: &mut SimRng) -> Isometry3<f64> {
    let radius = rng.range(0.3, 0.7);
    let azimuth = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
    let z = rng.range(0.05, 0.5);
    let tilt = rng.range(0.0, 30f64.to_radians());
    let tilt_axis = rng.range(0.0, std::f64::consts::TAU);
    let yaw = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
    let down = UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, yaw);
    let tilt =
        UnitQuaternion::from_euler_angles(tilt * tilt_axis.cos(), tilt * tilt_axis.sin(), 0.0);
    Isometry3::from_parts(
        Translation3::new(radius * azimuth.cos(), radius * azimuth.sin(), z),
        tilt * down,
    )
}

/// Runs the demo with the arm loaded from `urdf` (the built-in description when `None`).
pub fn run(urdf: Option<&Path>, params: &DemoParams) -> Result<DemoReport, SimError> {
    let mut world = World::new(WorldParams::default());
    let arm = match urdf {
        Some(path) => SimArm::load(&mut world, path, Isometry3::identity())?,
        None => SimArm::load_builtin(&mut world, Isometry3::identity())?,
    };
    let model = arm.kinematics().model.clone();
    let ik = AnalyticIk::new(model.clone())?;
    let home: JointVector = [0.0, -0.26, 1.74, 0.43, 1.57, 0.0];
    arm.reset_to(&mut world, &home, 0.03);
    let mut rng = SimRng::new(params.seed);
    let mut q_current = home;
    let mut targets = Vec::with_capacity(params.targets);
    let mut max_violation: f64 = 0.0;
    while targets.len() < params.targets {
        let target = random_target(&mut rng);
        let Some(q_goal) = ik.solve(&target).nearest(&q_current) else {
            continue;
        };
        let trajectory =
            JointTrajectory::through(&model, &[q_current, q_goal], params.speed_fraction);
        let move_s = trajectory.duration_s();
        let follower = TrajectoryFollower::new(trajectory, world.time_s());
        let mut peak_tracking: f64 = 0.0;
        let end_s = world.time_s() + move_s + params.settle_s;
        while world.time_s() < end_s {
            let Some(sample) = follower.update(&mut world, &arm) else {
                break;
            };
            world.step();
            let q = arm.joint_positions(&world);
            check_finite(&q, world.time_s())?;
            for (j, &value) in q.iter().enumerate() {
                let limit = &model.limits[j];
                let over = (value - limit.max_rad).max(limit.min_rad - value).max(0.0);
                max_violation = max_violation.max(over);
            }
            let planned = tcp_pose(&model, &sample.q).translation.vector;
            let actual = tcp_pose(&model, &q).translation.vector;
            peak_tracking = peak_tracking.max((planned - actual).norm());
        }
        // Measure the TCP from the simulated flange body, not from the joint readings.
        let flange = arm.world_from_base().inverse() * arm.flange_in_world(&world);
        let tcp = flange * model.flange_from_tcp;
        let tcp_error_m = (tcp.translation.vector - target.translation.vector).norm();
        let angle_error_rad = tcp.rotation.angle_to(&target.rotation);
        q_current = q_goal;
        targets.push(DemoTarget {
            xyz: target.translation.vector.into(),
            q_goal,
            move_s,
            tcp_error_mm: tcp_error_m * 1e3,
            tcp_angle_error_mrad: angle_error_rad * 1e3,
            peak_tracking_mm: peak_tracking * 1e3,
        });
    }
    let max_of = |f: fn(&DemoTarget) -> f64| targets.iter().map(f).fold(0.0, f64::max);
    Ok(DemoReport {
        seed: params.seed,
        max_tcp_error_mm: max_of(|t| t.tcp_error_mm),
        max_tcp_angle_error_mrad: max_of(|t| t.tcp_angle_error_mrad),
        peak_tracking_mm: max_of(|t| t.peak_tracking_mm),
        max_limit_violation_rad: max_violation,
        sim_time_s: world.time_s(),
        targets,
    })
}

fn check_finite(q: &[f64; DOF], time_s: f64) -> Result<(), SimError> {
    if q.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(SimError::BlowUp {
            what: "arm joint angle".into(),
            time_s,
        })
    }
}
