//! Forward kinematics.

use nalgebra::Isometry3;

use super::{ArmModel, DOF, JointVector};

/// Poses in the `base_link` frame of DH frames 0 to 5 and of the flange (index 6) at joint
/// angles `q`.
pub fn link_frames(arm: &ArmModel, q: &JointVector) -> [Isometry3<f64>; DOF + 1] {
    let mut frames = [arm.base_from_dh0; DOF + 1];
    for i in 0..DOF {
        frames[i + 1] = frames[i] * arm.dh[i].transform(arm.theta(i, q[i]));
    }
    if let Some(dh6_from_flange) = &arm.dh6_from_flange {
        frames[DOF] *= dh6_from_flange;
    }
    frames
}

/// Pose of the flange (the link the last arm joint turns) in the `base_link` frame.
pub fn flange_pose(arm: &ArmModel, q: &JointVector) -> Isometry3<f64> {
    let mut pose = arm.base_from_dh0;
    for (i, (row, &qi)) in arm.dh.iter().zip(q).enumerate() {
        pose *= row.transform(arm.theta(i, qi));
    }
    if let Some(dh6_from_flange) = &arm.dh6_from_flange {
        pose *= dh6_from_flange;
    }
    pose
}

/// Pose of the tool centre point in the `base_link` frame.
pub fn tcp_pose(arm: &ArmModel, q: &JointVector) -> Isometry3<f64> {
    flange_pose(arm, q) * arm.flange_from_tcp
}
