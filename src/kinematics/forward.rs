//! Forward kinematics.

use nalgebra::Isometry3;

use super::{ArmModel, DOF, JointVector};

/// Poses in the `base_link` frame of DH frames 0 to 6 (index 6 is the flange) at joint angles `q`.
pub fn link_frames(arm: &ArmModel, q: &JointVector) -> [Isometry3<f64>; DOF + 1] {
    let mut frames = [arm.base_from_dh0; DOF + 1];
    for i in 0..DOF {
        frames[i + 1] = frames[i] * arm.dh[i].transform(q[i] + arm.theta_offsets_rad[i]);
    }
    frames
}

/// Pose of the flange (URDF `wrist3_Link`) in the `base_link` frame.
pub fn flange_pose(arm: &ArmModel, q: &JointVector) -> Isometry3<f64> {
    let mut pose = arm.base_from_dh0;
    for (row, (&qi, &offset)) in arm.dh.iter().zip(q.iter().zip(&arm.theta_offsets_rad)) {
        pose *= row.transform(qi + offset);
    }
    pose
}

/// Pose of the tool centre point in the `base_link` frame.
pub fn tcp_pose(arm: &ArmModel, q: &JointVector) -> Isometry3<f64> {
    flange_pose(arm, q) * arm.flange_from_tcp
}
