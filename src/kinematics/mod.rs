//! AUBO i5 kinematics: modified-DH forward kinematics, the closed-form inverse and the Jacobian.
//!
//! Frames: `base` is the URDF `base_link`; DH frame 0 sits 23.5 mm above it; DH frame 6 is the
//! flange (URDF `wrist3_Link`); the tool centre point (TCP) hangs off the flange by a fixed
//! transform. Joint angles `q` are the controller's (and the URDF's):
//! `theta_dh = q + ArmModel::theta_offsets_rad`.

mod arm_model;
mod error;
mod forward;
mod inverse;
mod jacobian;

pub use arm_model::{ArmModel, DhRow, JointLimit, gripper_tcp};
pub use error::KinematicsError;
pub use forward::{flange_pose, link_frames, tcp_pose};
pub use inverse::{AnalyticIk, IkSolutions, IkSolver};
pub use jacobian::geometric_jacobian;

/// Number of arm joints.
pub const DOF: usize = 6;

/// A joint vector in radians, controller convention.
pub type JointVector = [f64; DOF];
