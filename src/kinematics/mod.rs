//! Arm kinematics: the model read from the robot's URDF, modified-DH forward kinematics, the
//! closed-form inverse and the Jacobian.
//!
//! Frames: `base` is the URDF's root link; DH frame 0 lies on joint 1's axis (23.5 mm above
//! `base_link` on the AUBO i5); the flange is the link the last arm joint turns (the AUBO i5's
//! `wrist3_Link`, which is its DH frame 6); the tool centre point (TCP) hangs off the flange by
//! a fixed transform. Joint angles `q` are the controller's (and the URDF's):
//! `theta_dh = joint_signs * q + ArmModel::theta_offsets_rad`.

mod arm_model;
mod error;
mod forward;
mod inverse;
mod jacobian;
mod urdf_arm;

pub use arm_model::{ArmModel, DhRow, JointLimit, gripper_tcp};
pub use error::KinematicsError;
pub use forward::{flange_pose, link_frames, tcp_pose};
pub use inverse::{AnalyticIk, IkSolutions, IkSolver};
pub use jacobian::geometric_jacobian;
pub use urdf_arm::{BUILTIN_URDF, BUILTIN_URDF_PATH, GRIPPER_MOUNT_LINK, TCP_LINK, UrdfArm};

/// Number of arm joints.
pub const DOF: usize = 6;

/// A joint vector in radians, controller convention.
pub type JointVector = [f64; DOF];
