//! What a controller commands for one control period, and its checks.

use nalgebra::Isometry3;

use crate::kinematics::{ArmModel, JointVector};

/// Widest jaw opening a controller may command (distance between the pads), m: the shipped
/// gripper's finger joints stop at 0.05 m from the centre line.
pub const MAX_JAW_WIDTH_M: f64 = 0.1;
/// Largest force per jaw a controller may command, N: the finger joints' effort limit.
pub const MAX_JAW_FORCE_N: f64 = 100.0;

/// Where the arm should go.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ArmTarget {
    /// Joint position targets, rad (the controller's convention, as `twincell ik` prints).
    Joints(JointVector),
    /// A pose of the tool centre point in the world, solved through the twin's closed-form IK;
    /// of its solutions the one nearest the joints commanded now is taken.
    ToolPose(Isometry3<f64>),
}

/// One control period's command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Action {
    /// The arm's target; the joint servos' set-points move towards it at the joints' velocity
    /// limits.
    pub arm: ArmTarget,
    /// Commanded distance between the jaws' pads, m; the drive moves them at its own speed.
    pub jaw_width_m: f64,
    /// Force limit per jaw, N.
    pub jaw_force_n: f64,
    /// Whether the belt runs (at the scenario's speed) or stops.
    pub belt_run: bool,
    /// Whether the observation after this period carries a new camera frame.
    pub take_frame: bool,
}

/// Why an action was refused; each names the action's key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ActionError {
    /// A number that is NaN or infinite.
    #[error("{key}: element {index} is {value} (not a finite number)")]
    NotFinite {
        /// The action's key.
        key: &'static str,
        /// Which element.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A joint target past its position limits.
    #[error(
        "joints: joint {joint} target {value_rad:.4} rad is outside its limits [{min_rad}, {max_rad}]"
    )]
    JointOutOfLimit {
        /// Joint number, from 1.
        joint: usize,
        /// The target, rad.
        value_rad: f64,
        /// Lower limit, rad.
        min_rad: f64,
        /// Upper limit, rad.
        max_rad: f64,
    },
    /// A jaw command outside what the gripper can do.
    #[error("{key}: {value} is outside [{min}, {max}]")]
    OutOfRange {
        /// The action's key.
        key: &'static str,
        /// The value.
        value: f64,
        /// Least allowed.
        min: f64,
        /// Most allowed.
        max: f64,
    },
}

/// `values` under `key` when all are finite.
fn finite(key: &'static str, values: &[f64]) -> Result<(), ActionError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(ActionError::NotFinite {
            key,
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

fn in_range(key: &'static str, value: f64, max: f64) -> Result<(), ActionError> {
    finite(key, &[value])?;
    if (0.0..=max).contains(&value) {
        return Ok(());
    }
    Err(ActionError::OutOfRange {
        key,
        value,
        min: 0.0,
        max,
    })
}

impl Action {
    /// Holding the arm at `q` with the jaws as they are commanded, the belt stopped.
    pub fn hold(q: JointVector, jaw_width_m: f64, jaw_force_n: f64) -> Self {
        Self {
            arm: ArmTarget::Joints(q),
            jaw_width_m,
            jaw_force_n,
            belt_run: false,
            take_frame: false,
        }
    }

    /// Checks every number of the action against `arm`'s limits and the gripper's.
    pub fn validate(&self, arm: &ArmModel) -> Result<(), ActionError> {
        match &self.arm {
            ArmTarget::Joints(q) => {
                finite("joints", q)?;
                for (j, (value, limit)) in q.iter().zip(&arm.limits).enumerate() {
                    if *value < limit.min_rad || *value > limit.max_rad {
                        return Err(ActionError::JointOutOfLimit {
                            joint: j + 1,
                            value_rad: *value,
                            min_rad: limit.min_rad,
                            max_rad: limit.max_rad,
                        });
                    }
                }
            }
            ArmTarget::ToolPose(pose) => {
                let t = pose.translation.vector;
                let r = pose.rotation.coords;
                finite("tool_pose", &[t.x, t.y, t.z, r.x, r.y, r.z, r.w])?;
            }
        }
        in_range("jaw_width", self.jaw_width_m, MAX_JAW_WIDTH_M)?;
        in_range("jaw_force", self.jaw_force_n, MAX_JAW_FORCE_N)
    }
}
