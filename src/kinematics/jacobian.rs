//! The geometric Jacobian.

use nalgebra::Matrix6;

use super::{ArmModel, DOF, JointVector, link_frames};

/// Geometric Jacobian of the TCP in the `base_link` frame: rows 0-2 map joint rates to linear
/// velocity (m/s), rows 3-5 to angular velocity (rad/s).
pub fn geometric_jacobian(arm: &ArmModel, q: &JointVector) -> Matrix6<f64> {
    let frames = link_frames(arm, q);
    let tcp = frames[DOF] * arm.flange_from_tcp;
    let tcp_position = tcp.translation.vector;
    let mut jacobian = Matrix6::zeros();
    // In modified DH, joint i turns about the z axis of DH frame i (frames[i + 1] here: frames[0]
    // is DH frame 0).
    let dh6 = match &arm.dh6_from_flange {
        Some(dh6_from_flange) => frames[DOF] * dh6_from_flange.inverse(),
        None => frames[DOF],
    };
    for i in 0..DOF {
        let frame = if i + 1 == DOF { &dh6 } else { &frames[i + 1] };
        let axis = frame.rotation * nalgebra::Vector3::z() * arm.joint_signs[i];
        let linear = axis.cross(&(tcp_position - frame.translation.vector));
        jacobian.fixed_view_mut::<3, 1>(0, i).copy_from(&linear);
        jacobian.fixed_view_mut::<3, 1>(3, i).copy_from(&axis);
    }
    jacobian
}
