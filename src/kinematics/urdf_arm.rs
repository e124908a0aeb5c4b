//! The arm in a URDF: the chain of revolute joints from the root link to the gripper's mount,
//! and its kinematic model in the modified DH form that the closed-form inverse solves.
//!
//! The joints' axes at zero angles are read as lines in the root frame, and the DH frames are
//! put on them by Craig's convention: each x axis along the common normal to the next joint's
//! axis. The signs of the axes and normals are chosen so that the table has the closed form's
//! twists; an arm that cannot be written so (axes that are not parallel or perpendicular where
//! the closed form needs it, offsets where it needs none) is refused with the reason. The table
//! is checked against the URDF's own chain at sample angles before it is used.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use urdf_rs::{JointType, Pose, Robot};

use super::inverse::CLOSED_FORM_ALPHA_DEG;
use super::{ArmModel, DOF, DhRow, JointLimit, JointVector, KinematicsError, flange_pose};

/// The link the twin's gripper is fixed to; the arm is the chain from the root down to it.
pub const GRIPPER_MOUNT_LINK: &str = "gripper_Link";
/// The link at the gripper's tool centre point, fixed below the flange.
pub const TCP_LINK: &str = "tcp_Link";
/// Axes this close to parallel or perpendicular (sine or cosine of the angle) count as such.
const ANGLE_TOLERANCE: f64 = 1e-9;
/// Offsets shorter than this count as zero, m.
const LENGTH_TOLERANCE_M: f64 = 1e-9;
/// Lengths are kept to whole steps of this many per metre (nanometres), so that a URDF's
/// decimal lengths come through exactly (dividing by a whole number rounds correctly).
const LENGTH_STEPS_PER_M: f64 = 1e9;
/// Angles are kept to whole steps of this many per degree, so that right angles come through
/// exactly.
const ANGLE_STEPS_PER_DEG: f64 = 1e9;
/// How far the table's flange may lie from the URDF chain's at the check angles, m or rad.
const CHECK_TOLERANCE: f64 = 1e-8;
/// Vendors' published DH tables, in the convention the closed form solves.
const PUBLISHED_TABLES: [fn() -> ArmModel; 1] = [ArmModel::aubo_i5];
/// A joint reaches its top speed in this time when the URDF gives no acceleration limit, s.
const DEFAULT_RAMP_S: f64 = 0.1;

/// The arm a URDF describes: its joints and links by name, and its kinematic model.
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfArm {
    /// The six arm joints, base to flange.
    pub joints: [String; DOF],
    /// The root link: the arm's base frame, where the cell places the robot.
    pub base_link: String,
    /// The link the last arm joint turns: the flange.
    pub flange_link: String,
    /// The model, with the TCP of the gripper's `tcp_Link`.
    pub model: ArmModel,
}

/// One joint of the chain at zero angles, in the root frame.
#[derive(Debug, Clone, Copy)]
struct AxisLine {
    point: Vector3<f64>,
    direction: Vector3<f64>,
}

/// The project's own arm-and-gripper description, built into the binary.
pub const BUILTIN_URDF: &str = include_str!("../../assets/urdf/aubo_i5.urdf");
/// Where the built-in URDF lives in the source tree (named in errors).
pub const BUILTIN_URDF_PATH: &str = "assets/urdf/aubo_i5.urdf";

impl UrdfArm {
    /// The arm of the built-in URDF.
    pub fn builtin() -> Result<Self, KinematicsError> {
        Self::from_urdf_str(BUILTIN_URDF)
    }

    /// The arm of URDF `text`.
    pub fn from_urdf_str(text: &str) -> Result<Self, KinematicsError> {
        let robot = urdf_rs::read_from_string(text).map_err(|e| KinematicsError::Urdf {
            reason: format!("{e:#}"),
        })?;
        Self::from_robot(&robot)
    }

    /// The arm of `robot`; refused with the reason when it is not a six-axis arm of the family
    /// the closed form solves. Where a published DH table describes the same arm, that table
    /// is the model, so that its numbers come through as the vendor wrote them.
    pub fn from_robot(robot: &Robot) -> Result<Self, KinematicsError> {
        let chain = chain_to(robot, GRIPPER_MOUNT_LINK)?;
        let base_link = match chain.first() {
            Some(&j) => robot.joints[j].parent.link.clone(),
            None => GRIPPER_MOUNT_LINK.to_owned(),
        };
        let mut root_from_link = Isometry3::identity();
        let mut lines = Vec::new();
        let mut joints = Vec::new();
        let mut limits = Vec::new();
        let mut flange = None;
        for &j in &chain {
            let joint = &robot.joints[j];
            root_from_link *= isometry(&joint.origin);
            match joint.joint_type {
                JointType::Revolute | JointType::Continuous => {
                    let axis = Vector3::from_row_slice(&joint.axis.xyz.0);
                    lines.push(AxisLine {
                        point: root_from_link.translation.vector,
                        direction: root_from_link.rotation * axis.normalize(),
                    });
                    joints.push(joint.name.clone());
                    limits.push(joint_limit(joint));
                    flange = Some((joint.child.link.clone(), root_from_link));
                }
                JointType::Fixed => {}
                _ => {
                    return Err(unsupported(format!(
                        "joint `{}` between the root and `{GRIPPER_MOUNT_LINK}` is neither revolute nor fixed",
                        joint.name
                    )));
                }
            }
        }
        if lines.len() != DOF {
            return Err(unsupported(format!(
                "the chain from `{base_link}` to `{GRIPPER_MOUNT_LINK}` has {} revolute joints; the closed form solves six",
                lines.len()
            )));
        }
        let Some((flange_link, root_from_flange)) = flange else {
            return Err(unsupported("the chain has no revolute joint".into()));
        };
        let lines: [AxisLine; DOF] = std::array::from_fn(|i| lines[i]);
        let (signs, dh, theta_offsets_rad, base_from_dh0, dh6_from_flange) =
            dh_table(&lines, &root_from_flange)?;
        let limits: [JointLimit; DOF] = std::array::from_fn(|i| limits[i]);
        let flange_from_tcp = match chain_to(robot, TCP_LINK) {
            Ok(tcp_chain) => {
                let root_from_tcp = tcp_chain.iter().fold(Isometry3::identity(), |pose, &j| {
                    pose * isometry(&robot.joints[j].origin)
                });
                root_from_flange.inverse() * root_from_tcp
            }
            Err(_) => Isometry3::identity(),
        };
        let model = ArmModel {
            dh,
            theta_offsets_rad,
            joint_signs: signs,
            limits,
            base_from_dh0,
            dh6_from_flange,
            flange_from_tcp: quantized_pose(&flange_from_tcp),
        };
        check_against_chain(robot, &chain, &model)?;
        let model = PUBLISHED_TABLES
            .iter()
            .map(|table| table().with_tool(model.flange_from_tcp))
            .find(|table| table.same_arm_as(&model, CHECK_TOLERANCE))
            .unwrap_or(model);
        Ok(Self {
            joints: std::array::from_fn(|i| joints[i].clone()),
            base_link,
            flange_link,
            model,
        })
    }
}

fn unsupported(reason: String) -> KinematicsError {
    KinematicsError::UnsupportedGeometry { reason }
}

/// The joints from the root link down to `link`, root first.
fn chain_to(robot: &Robot, link: &str) -> Result<Vec<usize>, KinematicsError> {
    if !robot.links.iter().any(|l| l.name == link) {
        return Err(unsupported(format!(
            "no link `{link}`: the twin's gripper mounts there"
        )));
    }
    let mut chain = Vec::new();
    let mut at = link;
    while let Some(j) = robot.joints.iter().position(|j| j.child.link == at) {
        if chain.contains(&j) || chain.len() > robot.joints.len() {
            return Err(unsupported(format!(
                "the joints above `{link}` form a loop"
            )));
        }
        chain.push(j);
        at = &robot.joints[j].parent.link;
    }
    chain.reverse();
    Ok(chain)
}

fn isometry(pose: &Pose) -> Isometry3<f64> {
    let [x, y, z] = pose.xyz.0;
    let [roll, pitch, yaw] = pose.rpy.0;
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

fn joint_limit(joint: &urdf_rs::Joint) -> JointLimit {
    let (min_rad, max_rad) = if joint.joint_type == JointType::Continuous {
        (-PI, PI)
    } else {
        (joint.limit.lower, joint.limit.upper)
    };
    JointLimit {
        min_rad,
        max_rad,
        max_velocity_rad_s: joint.limit.velocity,
        max_accel_rad_s2: joint.limit.velocity / DEFAULT_RAMP_S,
    }
}

fn quantize_length(value_m: f64) -> f64 {
    let steps = (value_m * LENGTH_STEPS_PER_M).round();
    if steps == 0.0 {
        0.0
    } else {
        steps / LENGTH_STEPS_PER_M
    }
}

/// `angle_rad` to the nearest step, as degrees times pi/180 (how the tables write their angles).
fn quantize_angle(angle_rad: f64) -> f64 {
    let degrees = (angle_rad.to_degrees() * ANGLE_STEPS_PER_DEG).round() / ANGLE_STEPS_PER_DEG;
    if degrees == 0.0 {
        0.0
    } else {
        degrees * (PI / 180.0)
    }
}

fn quantized_pose(pose: &Isometry3<f64>) -> Isometry3<f64> {
    let t = pose.translation.vector.map(quantize_length);
    let rotation = if pose.rotation.angle() < ANGLE_TOLERANCE {
        UnitQuaternion::identity()
    } else {
        pose.rotation
    };
    Isometry3::from_parts(Translation3::from(t), rotation)
}

/// Signed angle from `from` to `to` about `axis` (all unit, `from` and `to` normal to `axis`).
fn angle_about(from: &Vector3<f64>, to: &Vector3<f64>, axis: &Vector3<f64>) -> f64 {
    from.cross(to).dot(axis).atan2(from.dot(to))
}

/// A unit vector normal to `z`: `hint` with its `z` part removed, or any normal when `hint`
/// runs along `z`.
fn normal_to(z: &Vector3<f64>, hint: &Vector3<f64>) -> Vector3<f64> {
    let v = hint - z * hint.dot(z);
    if v.norm() > ANGLE_TOLERANCE {
        return v.normalize();
    }
    let other = if z.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    (other - z * other.dot(z)).normalize()
}

type DhTable = (
    JointVector,
    [DhRow; DOF],
    JointVector,
    Isometry3<f64>,
    Option<Isometry3<f64>>,
);

/// The DH table of the six axis lines, and the flange's pose in DH frame 6.
fn dh_table(
    lines: &[AxisLine; DOF],
    root_from_flange: &Isometry3<f64>,
) -> Result<DhTable, KinematicsError> {
    let mut signs = [1.0; DOF];
    let mut z: [Vector3<f64>; DOF] = std::array::from_fn(|i| lines[i].direction);
    // x axis and origin of DH frames 1..5 (frame 6 is set by the flange below).
    let mut x = [Vector3::zeros(); DOF];
    let mut origin = [Vector3::zeros(); DOF];
    // Where each frame's x axis meets the next joint's axis.
    let mut foot = [Vector3::zeros(); DOF];
    let mut alpha = [0.0; DOF];
    let mut a = [0.0; DOF];
    for i in 0..DOF - 1 {
        let (p, q) = (lines[i].point, lines[i + 1].point);
        let expected_deg = CLOSED_FORM_ALPHA_DEG[i + 1];
        let next = lines[i + 1].direction;
        let cos = z[i].dot(&next);
        let row = i + 2;
        if expected_deg.abs() == 90.0 {
            if cos.abs() > ANGLE_TOLERANCE {
                return Err(unsupported(format!(
                    "joints {} and {} must be perpendicular, their axes are {:.3} deg apart",
                    i + 1,
                    i + 2,
                    cos.clamp(-1.0, 1.0).acos().to_degrees()
                )));
            }
            z[i + 1] = next;
            x[i] = z[i].cross(&z[i + 1]).normalize() * expected_deg.signum();
            // The closest points of the two lines.
            let w = p - q;
            let (b, d, e) = (z[i].dot(&z[i + 1]), z[i].dot(&w), z[i + 1].dot(&w));
            let denominator = 1.0 - b * b;
            let s = (b * e - d) / denominator;
            let t = (e - b * d) / denominator;
            origin[i] = p + z[i] * s;
            foot[i] = q + z[i + 1] * t;
        } else {
            if z[i].cross(&next).norm() > ANGLE_TOLERANCE {
                return Err(unsupported(format!(
                    "joints {} and {} must be parallel, their axes are {:.3} deg apart",
                    i + 1,
                    i + 2,
                    cos.clamp(-1.0, 1.0).acos().to_degrees()
                )));
            }
            let same_way = expected_deg == 0.0;
            signs[i + 1] = if (cos > 0.0) == same_way { 1.0 } else { -1.0 };
            z[i + 1] = next * signs[i + 1];
            // The common normal through the next joint's origin.
            origin[i] = p + z[i] * (q - p).dot(&z[i]);
            foot[i] = q;
            let across = q - origin[i];
            if across.norm() <= LENGTH_TOLERANCE_M {
                return Err(unsupported(format!(
                    "joints {} and {} lie on one line; the closed form needs a link between them",
                    i + 1,
                    i + 2
                )));
            }
            x[i] = across.normalize();
        }
        alpha[i + 1] = quantize_angle(angle_about(&z[i], &z[i + 1], &x[i]));
        a[i + 1] = quantize_length((foot[i] - origin[i]).dot(&x[i]));
        if a[i + 1] != 0.0 && !(row == 3 || row == 4) {
            return Err(unsupported(format!(
                "the axes of joints {} and {} pass {:.1} mm apart; the closed form needs them to meet",
                i + 1,
                i + 2,
                a[i + 1] * 1e3
            )));
        }
    }
    // Frame 6: on the last axis, its x axis the flange's.
    let flange_x = root_from_flange.rotation * Vector3::x();
    x[DOF - 1] = normal_to(&z[DOF - 1], &flange_x);
    let flange_point = root_from_flange.translation.vector;
    let last = lines[DOF - 1].point;
    origin[DOF - 1] = last + z[DOF - 1] * (flange_point - last).dot(&z[DOF - 1]);
    // Frame 0: z along joint 1, origin where the root's origin projects onto that axis.
    let z0 = z[0];
    let origin0 = lines[0].point + z0 * (-lines[0].point).dot(&z0);
    let x0 = normal_to(&z0, &Vector3::x());
    let frame = |x: &Vector3<f64>, z: &Vector3<f64>, o: &Vector3<f64>| {
        let y = z.cross(x);
        let r = nalgebra::Matrix3::from_columns(&[*x, y, *z]);
        Isometry3::from_parts(
            Translation3::from(*o),
            UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r)),
        )
    };
    let root_from_dh0 = frame(&x0, &z0, &origin0);
    // The previous frame's x axis and where it meets each joint's axis.
    let mut previous_x = x0;
    let mut previous_foot = origin0;
    let mut rows = Vec::with_capacity(DOF);
    let mut offsets = [0.0; DOF];
    for i in 0..DOF {
        let d = quantize_length((origin[i] - previous_foot).dot(&z[i]));
        offsets[i] = quantize_angle(angle_about(&previous_x, &x[i], &z[i]));
        rows.push(DhRow::new(alpha[i], a[i], d));
        previous_x = x[i];
        previous_foot = foot[i];
    }
    let dh6_in_root = frame(&x[DOF - 1], &z[DOF - 1], &origin[DOF - 1]);
    let dh6_from_flange = quantized_pose(&(dh6_in_root.inverse() * root_from_flange));
    let dh6_from_flange = (dh6_from_flange != Isometry3::identity()).then_some(dh6_from_flange);
    let base_from_dh0 = quantized_pose(&root_from_dh0);
    Ok((
        signs,
        std::array::from_fn(|i| rows[i]),
        offsets,
        base_from_dh0,
        dh6_from_flange,
    ))
}

/// The flange by the URDF's own chain at joint angles `q`.
fn chain_flange(robot: &Robot, chain: &[usize], q: &JointVector) -> Isometry3<f64> {
    let mut pose = Isometry3::identity();
    let mut next = 0;
    for &j in chain {
        let joint = &robot.joints[j];
        pose *= isometry(&joint.origin);
        if matches!(
            joint.joint_type,
            JointType::Revolute | JointType::Continuous
        ) && next < DOF
        {
            let axis = nalgebra::Unit::new_normalize(Vector3::from_row_slice(&joint.axis.xyz.0));
            pose *= UnitQuaternion::from_axis_angle(&axis, q[next]);
            next += 1;
            if next == DOF {
                return pose;
            }
        }
    }
    pose
}

/// Checks the table against the URDF's chain at a spread of joint angles.
fn check_against_chain(
    robot: &Robot,
    chain: &[usize],
    model: &ArmModel,
) -> Result<(), KinematicsError> {
    for k in 0..16 {
        let q: JointVector = std::array::from_fn(|i| ((k * 7 + i * 3) % 13) as f64 * 0.45 - 2.7);
        let by_table = flange_pose(model, &q);
        let by_chain = chain_flange(robot, chain, &q);
        let position_m = (by_table.translation.vector - by_chain.translation.vector).norm();
        let angle_rad = by_table.rotation.angle_to(&by_chain.rotation);
        if position_m > CHECK_TOLERANCE || angle_rad > CHECK_TOLERANCE {
            return Err(unsupported(format!(
                "the DH table read from the URDF puts the flange {:.3} mm and {:.4} deg from the URDF's own chain",
                position_m * 1e3,
                angle_rad.to_degrees()
            )));
        }
    }
    Ok(())
}
