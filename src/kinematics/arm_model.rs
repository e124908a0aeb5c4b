//! The arm's kinematic description: modified DH table, joint convention, limits and tool.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{DOF, JointVector, KinematicsError};

/// One row of a modified (Craig) DH table: `T = RotX(alpha) TransX(a) RotZ(theta) TransZ(d)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRow {
    /// Twist about the previous x axis, `alpha_{i-1}`.
    pub alpha_rad: f64,
    /// Length along the previous x axis, `a_{i-1}`.
    pub a_m: f64,
    /// Offset along this z axis, `d_i`.
    pub d_m: f64,
    cos_alpha: f64,
    sin_alpha: f64,
    twist: UnitQuaternion<f64>,
}

impl DhRow {
    /// A row from its parameters.
    pub fn new(alpha_rad: f64, a_m: f64, d_m: f64) -> Self {
        let (sin_alpha, cos_alpha) = alpha_rad.sin_cos();
        Self {
            alpha_rad,
            a_m,
            d_m,
            cos_alpha,
            sin_alpha,
            twist: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), alpha_rad),
        }
    }

    /// `cos(alpha)`.
    pub fn cos_alpha(&self) -> f64 {
        self.cos_alpha
    }

    /// The transform from the previous DH frame to this one at DH angle `theta_rad`.
    pub fn transform(&self, theta_rad: f64) -> Isometry3<f64> {
        let translation = Vector3::new(
            self.a_m,
            -self.sin_alpha * self.d_m,
            self.cos_alpha * self.d_m,
        );
        Isometry3::from_parts(
            Translation3::from(translation),
            self.twist * z_rotation(theta_rad),
        )
    }

    /// The joint-independent part of the row, `RotX(alpha) TransX(a)`.
    pub fn fixed_part(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::new(self.a_m, 0.0, 0.0), self.twist)
    }

    /// The joint-dependent part of the row, `RotZ(theta) TransZ(d)`.
    pub fn joint_part(&self, theta_rad: f64) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::new(0.0, 0.0, self.d_m), z_rotation(theta_rad))
    }
}

/// Rotation about z by `angle_rad`.
pub(crate) fn z_rotation(angle_rad: f64) -> UnitQuaternion<f64> {
    let (s, c) = (0.5 * angle_rad).sin_cos();
    UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(c, 0.0, 0.0, s))
}

/// Position, velocity and acceleration limits of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimit {
    /// Lowest allowed angle.
    pub min_rad: f64,
    /// Highest allowed angle.
    pub max_rad: f64,
    /// Largest speed.
    pub max_velocity_rad_s: f64,
    /// Largest acceleration.
    pub max_accel_rad_s2: f64,
}

impl JointLimit {
    /// Whether `q_rad` lies within the position limits (inclusive, with a hair of tolerance).
    pub fn contains(&self, q_rad: f64) -> bool {
        q_rad >= self.min_rad - 1e-12 && q_rad <= self.max_rad + 1e-12
    }
}

/// Kinematic model of a six-axis arm in the AUBO i5 layout.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmModel {
    /// Modified DH rows, joint 1 to 6.
    pub dh: [DhRow; DOF],
    /// `theta_dh = joint_signs * q + theta_offsets_rad`.
    pub theta_offsets_rad: JointVector,
    /// +1 where a joint turns about its DH z axis, -1 where the URDF's axis points the other
    /// way.
    pub joint_signs: JointVector,
    /// Joint limits in the controller convention.
    pub limits: [JointLimit; DOF],
    /// Pose of DH frame 0 in the URDF `base_link` frame.
    pub base_from_dh0: Isometry3<f64>,
    /// Pose of the flange in DH frame 6, where they differ (`None`: the flange is DH frame 6).
    pub dh6_from_flange: Option<Isometry3<f64>>,
    /// Pose of the tool centre point in the flange frame.
    pub flange_from_tcp: Isometry3<f64>,
}

impl ArmModel {
    /// The AUBO i5 as in the paper's DH table, with the controller's joint convention and limits.
    pub fn aubo_i5() -> Self {
        let deg = std::f64::consts::PI / 180.0;
        let dh = [
            DhRow::new(0.0, 0.0, 0.0985),
            DhRow::new(90.0 * deg, 0.0, 0.1405),
            DhRow::new(180.0 * deg, 0.408, 0.0),
            DhRow::new(180.0 * deg, 0.376, -0.019),
            DhRow::new(-90.0 * deg, 0.0, 0.1025),
            DhRow::new(90.0 * deg, 0.0, 0.094),
        ];
        // The vendor's 3.14 rad/s is a rated speed, not pi.
        #[allow(clippy::approx_constant)]
        const SHOULDER_SPEED_RAD_S: f64 = 3.14;
        let big = |max_velocity_rad_s, max_accel_rad_s2| JointLimit {
            min_rad: -3.04,
            max_rad: 3.04,
            max_velocity_rad_s,
            max_accel_rad_s2,
        };
        Self {
            dh,
            theta_offsets_rad: [0.0, 90.0 * deg, 0.0, -90.0 * deg, 0.0, 0.0],
            joint_signs: [1.0; DOF],
            limits: [
                big(SHOULDER_SPEED_RAD_S, 30.0),
                big(SHOULDER_SPEED_RAD_S, 30.0),
                big(SHOULDER_SPEED_RAD_S, 30.0),
                big(2.6, 25.0),
                big(2.6, 25.0),
                big(2.6, 25.0),
            ],
            base_from_dh0: Isometry3::translation(0.0, 0.0, 0.0235),
            dh6_from_flange: None,
            flange_from_tcp: Isometry3::identity(),
        }
    }

    /// The same arm with a tool centre point at `flange_from_tcp`.
    pub fn with_tool(mut self, flange_from_tcp: Isometry3<f64>) -> Self {
        self.flange_from_tcp = flange_from_tcp;
        self
    }

    /// The DH angle of joint `i` at controller angle `q_rad`.
    pub fn theta(&self, i: usize, q_rad: f64) -> f64 {
        if self.joint_signs[i] < 0.0 {
            self.theta_offsets_rad[i] - q_rad
        } else {
            q_rad + self.theta_offsets_rad[i]
        }
    }

    /// DH angles from controller joint angles.
    pub fn theta_from_q(&self, q: &JointVector) -> JointVector {
        std::array::from_fn(|i| self.theta(i, q[i]))
    }

    /// Controller joint angles from DH angles.
    pub fn q_from_theta(&self, theta: &JointVector) -> JointVector {
        std::array::from_fn(|i| {
            if self.joint_signs[i] < 0.0 {
                self.theta_offsets_rad[i] - theta[i]
            } else {
                theta[i] - self.theta_offsets_rad[i]
            }
        })
    }

    /// Whether `other` puts the flange where this model does at every joint angle (checked at
    /// a spread of angles, within `tolerance` metres and radians), with the same position and
    /// speed limits.
    pub fn same_arm_as(&self, other: &ArmModel, tolerance: f64) -> bool {
        let limits_agree = self.limits.iter().zip(&other.limits).all(|(a, b)| {
            a.min_rad == b.min_rad
                && a.max_rad == b.max_rad
                && a.max_velocity_rad_s == b.max_velocity_rad_s
        });
        limits_agree
            && (0..32).all(|k| {
                let q: JointVector =
                    std::array::from_fn(|i| f64::from((k * 5 + i as i32 * 7) % 17) * 0.35 - 2.8);
                let (a, b) = (super::flange_pose(self, &q), super::flange_pose(other, &q));
                (a.translation.vector - b.translation.vector).norm() <= tolerance
                    && a.rotation.angle_to(&b.rotation) <= tolerance
            })
    }

    /// Checks that every joint is finite and within its limits.
    pub fn check_limits(&self, q: &JointVector) -> Result<(), KinematicsError> {
        for (joint, (&value_rad, limit)) in q.iter().zip(&self.limits).enumerate() {
            if !value_rad.is_finite() {
                return Err(KinematicsError::NotFinite {
                    what: "joint angle",
                });
            }
            if !limit.contains(value_rad) {
                return Err(KinematicsError::JointOutOfLimit {
                    joint,
                    value_rad,
                    min_rad: limit.min_rad,
                    max_rad: limit.max_rad,
                });
            }
        }
        Ok(())
    }
}

/// The tool centre point of the project's gripper in the flange frame: midway between the pads.
pub fn gripper_tcp() -> Isometry3<f64> {
    Isometry3::translation(0.0, 0.0, 0.125)
}
