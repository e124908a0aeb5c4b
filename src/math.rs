//! Conversions between the kinematics layer's `f64` nalgebra types and the physics engine's
//! `f32` glam types. The only place where the two meet.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use rapier3d::math::{Pose, Rotation, Vector};

/// A kinematics pose as a physics pose.
pub fn pose_to_physics(pose: &Isometry3<f64>) -> Pose {
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion();
    Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32).normalize(),
    )
}

/// A physics pose as a kinematics pose.
pub fn pose_from_physics(pose: &Pose) -> Isometry3<f64> {
    let t = pose.translation;
    let r = pose.rotation;
    Isometry3::from_parts(
        Translation3::new(f64::from(t.x), f64::from(t.y), f64::from(t.z)),
        UnitQuaternion::new_normalize(Quaternion::new(
            f64::from(r.w),
            f64::from(r.x),
            f64::from(r.y),
            f64::from(r.z),
        )),
    )
}

/// A kinematics vector as a physics vector.
pub fn vector_to_physics(v: &Vector3<f64>) -> Vector {
    Vector::new(v.x as f32, v.y as f32, v.z as f32)
}

/// A physics vector as a kinematics vector.
pub fn vector_from_physics(v: Vector) -> Vector3<f64> {
    Vector3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_round_trip_keeps_single_precision() {
        let pose = Isometry3::from_parts(
            Translation3::new(0.4, -0.25, 0.8),
            UnitQuaternion::from_euler_angles(0.3, -1.2, 2.5),
        );
        let back = pose_from_physics(&pose_to_physics(&pose));
        assert!((back.translation.vector - pose.translation.vector).norm() < 1e-6);
        assert!(back.rotation.angle_to(&pose.rotation) < 1e-6);
    }
}
