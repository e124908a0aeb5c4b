//! The arm and gripper in the physics world: loaded from URDF as a multibody with joint motors.

use std::path::Path;

use nalgebra::Isometry3;
use rapier3d::prelude::*;
use rapier3d_urdf::{UrdfLoaderOptions, UrdfMultibodyOptions, UrdfRobot};

use super::{SimError, World};
use crate::kinematics::{DOF, JointVector};
use crate::math::{pose_from_physics, pose_to_physics};

/// Where the built-in URDF lives in the source tree (named in errors).
pub const BUILTIN_URDF_PATH: &str = "assets/urdf/aubo_i5.urdf";
/// The project's AUBO i5 + gripper description.
const BUILTIN_URDF: &str = include_str!("../../assets/urdf/aubo_i5.urdf");

/// Names of the six arm joints in the URDF, base to flange.
pub const ARM_JOINTS: [&str; DOF] = [
    "shoulder_joint",
    "upperArm_joint",
    "foreArm_joint",
    "wrist1_joint",
    "wrist2_joint",
    "wrist3_joint",
];
/// Names of the two finger joints in the URDF.
pub const FINGER_JOINTS: [&str; 2] = ["finger_left_joint", "finger_right_joint"];
/// Index of a revolute joint's angle in a multibody joint's coordinates.
const REVOLUTE_COORD: usize = 3;
/// Direction of each finger joint's axis along the gripper's x axis (left, right).
const FINGER_SIGNS: [f64; 2] = [1.0, -1.0];
/// Jaw travel speed, m/s per jaw (the gripper controller ramps commands at this rate).
pub const JAW_SPEED_M_S: f64 = 0.1;
/// Position gain of the jaw drive, N/m.
const JAW_STIFFNESS_N_M: f64 = 4_000.0;
/// Velocity gain of the jaw drive, N s/m.
const JAW_DAMPING_N_S_M: f64 = 120.0;

/// Puts every robot collider in one collision group that ignores itself: links that meet at
/// joints, and the jaws riding on the gripper, never push on each other.
fn isolate_robot_colliders(world: &mut World, bodies: impl Iterator<Item = RigidBodyHandle>) {
    let groups = InteractionGroups::new(
        Group::GROUP_1,
        Group::ALL.difference(Group::GROUP_1),
        InteractionTestMode::And,
    );
    let physics = &mut world.physics;
    for body in bodies {
        let Some(rb) = physics.bodies.get(body) else {
            continue;
        };
        for handle in rb.colliders().to_vec() {
            if let Some(collider) = physics.colliders.get_mut(handle) {
                collider.set_collision_groups(groups);
            }
        }
    }
}
/// The flange link.
const FLANGE_LINK: &str = "wrist3_Link";

/// Servo gains of the joint position controllers (acceleration-based, per unit inertia).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmGains {
    /// Position gain, 1/s^2.
    pub stiffness: f32,
    /// Velocity gain, 1/s.
    pub damping: f32,
}

impl Default for ArmGains {
    fn default() -> Self {
        // Natural frequency 1000 rad/s, critically damped: stiff like a geared industrial servo.
        Self {
            stiffness: 1.0e6,
            damping: 2.0e3,
        }
    }
}

/// Handles of the arm in a [`World`].
#[derive(Debug, Clone)]
pub struct SimArm {
    joints: [MultibodyJointHandle; DOF],
    fingers: [ImpulseJointHandle; 2],
    finger_bodies: [RigidBodyHandle; 2],
    jaw_carrier: RigidBodyHandle,
    gripper_body: RigidBodyHandle,
    efforts: [f32; DOF],
    flange_body: RigidBodyHandle,
    link_bodies: Vec<(String, RigidBodyHandle)>,
    world_from_base: Isometry3<f64>,
    gains: ArmGains,
}

impl SimArm {
    /// Loads the URDF file at `path` into `world` with its `base_link` at `world_from_base`.
    pub fn load(
        world: &mut World,
        path: &Path,
        world_from_base: Isometry3<f64>,
    ) -> Result<Self, SimError> {
        let text = std::fs::read_to_string(path).map_err(|e| SimError::Urdf {
            reason: e.to_string(),
            path: path.to_path_buf(),
        })?;
        Self::from_urdf_str(world, &text, path, world_from_base)
    }

    /// Loads the project's own arm-and-gripper URDF, built into the binary.
    pub fn load_builtin(
        world: &mut World,
        world_from_base: Isometry3<f64>,
    ) -> Result<Self, SimError> {
        Self::from_urdf_str(
            world,
            BUILTIN_URDF,
            Path::new(BUILTIN_URDF_PATH),
            world_from_base,
        )
    }

    /// Loads URDF `text` (read from `path`, which names it in errors and anchors mesh paths).
    pub fn from_urdf_str(
        world: &mut World,
        text: &str,
        path: &Path,
        world_from_base: Isometry3<f64>,
    ) -> Result<Self, SimError> {
        let urdf_error = |reason: String| SimError::Urdf {
            reason,
            path: path.to_path_buf(),
        };
        let options = UrdfLoaderOptions {
            make_roots_fixed: true,
            shift: pose_to_physics(&world_from_base),
            // Powered servos never sleep: a new command must act at once.
            rigid_body_blueprint: RigidBodyBuilder::dynamic().can_sleep(false),
            ..UrdfLoaderOptions::default()
        };
        let mesh_dir = path.parent().unwrap_or(Path::new("."));
        let (mut robot, description) = UrdfRobot::from_str(text, options, mesh_dir)
            .map_err(|e| urdf_error(format!("{e:#}")))?;
        // The jaws are not joints of the arm's multibody: rapier's friction between a multibody
        // link and a free body let a firmly held part creep down the pads. They are kinematic
        // bodies driven by the gripper's own force-controlled jaw drive (see `drive_jaws`).
        let joint_name =
            |j: &rapier3d_urdf::UrdfJoint| description.joints[j.urdf_joint_index].name.clone();
        let (finger_joints, arm_joints): (Vec<_>, Vec<_>) = robot
            .joints
            .drain(..)
            .partition(|j| FINGER_JOINTS.contains(&joint_name(j).as_str()));
        robot.joints = arm_joints;
        let link_names: Vec<String> = robot
            .links
            .iter()
            .map(|l| description.links[l.urdf_link_index].name.clone())
            .collect();
        let joint_names: Vec<String> = robot
            .joints
            .iter()
            .map(|j| description.joints[j.urdf_joint_index].name.clone())
            .collect();
        let efforts_by_name: Vec<f32> = robot
            .joints
            .iter()
            .map(|j| description.joints[j.urdf_joint_index].limit.effort as f32)
            .collect();
        let physics = &mut world.physics;
        // Self-contacts off: neighbouring links overlap at their joints by design; the planner
        // keeps the arm clear of itself.
        let handles = robot.insert_using_multibody_joints(
            &mut physics.bodies,
            &mut physics.colliders,
            &mut physics.multibody_joints,
            UrdfMultibodyOptions::DISABLE_SELF_CONTACTS,
        );
        let find_joint = |name: &str| -> Result<(MultibodyJointHandle, f32), SimError> {
            let index = joint_names.iter().position(|n| n == name);
            let handle =
                index.and_then(|i| handles.joints[i].joint.map(|h| (h, efforts_by_name[i])));
            handle.ok_or_else(|| SimError::MissingJoint {
                joint: name.to_string(),
                path: path.to_path_buf(),
            })
        };
        let mut joints = [MultibodyJointHandle::invalid(); DOF];
        let mut efforts = [0.0f32; DOF];
        for (i, name) in ARM_JOINTS.iter().enumerate() {
            (joints[i], efforts[i]) = find_joint(name)?;
        }
        let gripper_body = handles.links[finger_joints.first().map_or(0, |j| j.link1)].body;
        let carrier_pose = world
            .physics
            .bodies
            .get(gripper_body)
            .map_or(Pose::IDENTITY, |b| *b.position());
        let jaw_carrier = world.physics.bodies.insert(
            RigidBodyBuilder::kinematic_position_based()
                .pose(carrier_pose)
                .can_sleep(false),
        );
        let mut finger_bodies = [RigidBodyHandle::invalid(); 2];
        let mut fingers = [ImpulseJointHandle::invalid(); 2];
        for (i, name) in FINGER_JOINTS.iter().enumerate() {
            let Some(joint) = finger_joints.iter().find(|j| joint_name(j) == *name) else {
                return Err(SimError::MissingJoint {
                    joint: name.to_string(),
                    path: path.to_path_buf(),
                });
            };
            finger_bodies[i] = handles.links[joint.link2].body;
            // The URDF joint's frames are relative to the gripper link, whose pose the carrier
            // shares.
            fingers[i] = world.physics.impulse_joints.insert(
                jaw_carrier,
                finger_bodies[i],
                joint.joint,
                true,
            );
        }
        isolate_robot_colliders(world, handles.links.iter().map(|l| l.body));
        let gripper_body = handles.links[finger_joints[0].link1].body;
        let link_bodies: Vec<(String, RigidBodyHandle)> = link_names
            .into_iter()
            .zip(handles.links.iter().map(|l| l.body))
            .collect();
        let Some(flange_body) = link_bodies
            .iter()
            .find(|(name, _)| name == FLANGE_LINK)
            .map(|(_, body)| *body)
        else {
            return Err(urdf_error(format!("no link named `{FLANGE_LINK}`")));
        };
        let arm = Self {
            joints,
            fingers,
            finger_bodies,
            jaw_carrier,
            gripper_body,
            efforts,
            flange_body,
            link_bodies,
            world_from_base,
            gains: ArmGains::default(),
        };
        Ok(arm)
    }

    /// Pose of the arm's `base_link` in the world.
    pub fn world_from_base(&self) -> &Isometry3<f64> {
        &self.world_from_base
    }

    /// The arm's links and their bodies, in URDF order.
    pub fn link_bodies(&self) -> &[(String, RigidBodyHandle)] {
        &self.link_bodies
    }

    /// Sets the servo gains used by later commands.
    pub fn set_gains(&mut self, gains: ArmGains) {
        self.gains = gains;
    }

    /// Measured joint angles (controller convention).
    pub fn joint_positions(&self, world: &World) -> JointVector {
        self.joints
            .map(|handle| f64::from(joint_coord(world, handle, REVOLUTE_COORD).unwrap_or(0.0)))
    }

    /// Measured finger positions: each pad's distance from the gripper's centre line.
    pub fn finger_positions_m(&self, world: &World) -> [f64; 2] {
        let bodies = &world.physics.bodies;
        let Some(carrier) = bodies.get(self.jaw_carrier) else {
            return [0.0; 2];
        };
        let carrier = pose_from_physics(carrier.position());
        let mut offsets = [0.0; 2];
        for (i, (body, sign)) in self.finger_bodies.iter().zip(FINGER_SIGNS).enumerate() {
            if let Some(finger) = bodies.get(*body) {
                let local = carrier.inverse() * pose_from_physics(finger.position());
                offsets[i] = sign * local.translation.x;
            }
        }
        offsets
    }

    /// Commands the joint servos to a position and feed-forward velocity.
    pub fn command(&self, world: &mut World, q: &JointVector, qd: &JointVector) {
        let gains = self.gains;
        for (i, handle) in self.joints.iter().enumerate() {
            with_joint_mut(world, *handle, |joint| {
                joint.set_motor(
                    JointAxis::AngX,
                    q[i] as f32,
                    qd[i] as f32,
                    gains.stiffness,
                    gains.damping,
                );
                joint.set_motor_max_force(JointAxis::AngX, self.efforts[i]);
            });
        }
    }

    /// Drives the jaws towards `pad_offset_m` from the centre line, squeezing with at most
    /// `max_force_n` each: a force-limited parallel gripper whose jaws stay centred on what
    /// they hold, and moves the jaw carrier with the gripper for the coming step.
    ///
    /// Both jaws get one target, never tighter than their mean opening less the squeeze travel
    /// `F / k`: blocked by a part, each presses with the full force when centred, and a jaw
    /// pushed outward presses harder than its partner, which re-centres the part as a geared
    /// pair of jaws would. Call once before every physics step.
    pub fn drive_gripper(&self, world: &mut World, pad_offset_m: f64, max_force_n: f64) {
        let [left, right] = self.finger_positions_m(world);
        let squeeze_travel_m = max_force_n / JAW_STIFFNESS_N_M;
        let target = pad_offset_m.max(0.5 * (left + right) - squeeze_travel_m);
        let dt = world.params().dt_s as f32;
        let physics = &mut world.physics;
        for handle in &self.fingers {
            if let Some(joint) = physics.impulse_joints.get_mut(*handle, true) {
                let data = &mut joint.data;
                data.set_motor_model(JointAxis::LinX, MotorModel::ForceBased);
                data.set_motor(
                    JointAxis::LinX,
                    target as f32,
                    0.0,
                    JAW_STIFFNESS_N_M as f32,
                    JAW_DAMPING_N_S_M as f32,
                );
                data.set_motor_max_force(JointAxis::LinX, max_force_n as f32);
            }
        }
        // The carrier is the gripper housing: where the arm's gripper link will be after the step.
        let next = physics
            .bodies
            .get(self.gripper_body)
            .map(|b| b.predict_position_using_velocity(dt));
        if let (Some(next), Some(carrier)) = (next, physics.bodies.get_mut(self.jaw_carrier)) {
            carrier.set_next_kinematic_position(next);
        }
    }

    /// Places the arm at rest at `q` with the finger pads at `pad_offset_m`, as a trial's
    /// initial state (this sets the robot's state; it never moves other bodies).
    pub fn reset_to(&self, world: &mut World, q: &JointVector, pad_offset_m: f64) {
        let targets: Vec<(usize, f32, usize)> = self
            .joints
            .iter()
            .zip(q)
            .map(|(handle, &value)| (*handle, value as f32, REVOLUTE_COORD))
            .filter_map(|(handle, value, axis)| {
                let (_, link_id) = world.physics.multibody_joints.get(handle)?;
                Some((link_id, value, axis))
            })
            .collect();
        let physics = &mut world.physics;
        let Some((multibody, _)) = physics.multibody_joints.get_mut(self.joints[0]) else {
            return;
        };
        let mut displacement = vec![0.0f32; multibody.ndofs()];
        for (link_id, value, axis) in targets {
            if let Some(link) = multibody.link(link_id) {
                displacement[link.assembly_id()] = value - link.joint().coords()[axis];
            }
        }
        multibody.apply_displacements(&displacement);
        multibody.generalized_velocity_mut().fill(0.0);
        multibody.forward_kinematics(&physics.bodies, true);
        multibody.update_rigid_bodies(&mut physics.bodies, false);
        // Carrier on the gripper, jaws at the requested opening, at rest.
        let gripper = physics.bodies.get(self.gripper_body).map(|b| *b.position());
        if let Some(gripper) = gripper {
            if let Some(carrier) = physics.bodies.get_mut(self.jaw_carrier) {
                carrier.set_position(gripper, true);
                carrier.set_next_kinematic_position(gripper);
            }
            for (body, sign) in self.finger_bodies.iter().zip(FINGER_SIGNS) {
                if let Some(finger) = physics.bodies.get_mut(*body) {
                    let offset =
                        Pose::from_translation(Vector::new((sign * pad_offset_m) as f32, 0.0, 0.0));
                    finger.set_position(gripper * offset, true);
                    finger.set_linvel(Vector::ZERO, true);
                    finger.set_angvel(Vector::ZERO, true);
                }
            }
        }
        self.command(world, q, &[0.0; DOF]);
        self.drive_gripper(world, pad_offset_m, 40.0);
    }

    /// Pose of the flange in the world.
    pub fn flange_in_world(&self, world: &World) -> Isometry3<f64> {
        world
            .physics
            .bodies
            .get(self.flange_body)
            .map(|body| pose_from_physics(body.position()))
            .unwrap_or_else(Isometry3::identity)
    }
}

/// Coordinate `axis` of a multibody joint, if the joint exists.
fn joint_coord(world: &World, handle: MultibodyJointHandle, axis: usize) -> Option<f32> {
    let (multibody, link) = world.physics.multibody_joints.get(handle)?;
    Some(multibody.link(link)?.joint().coords()[axis])
}

/// Applies `edit` to a multibody joint's description, if the joint exists.
fn with_joint_mut(
    world: &mut World,
    handle: MultibodyJointHandle,
    edit: impl FnOnce(&mut GenericJoint),
) {
    if let Some((multibody, link)) = world.physics.multibody_joints.get_mut(handle)
        && let Some(link) = multibody.link_mut(link)
    {
        edit(&mut link.joint.data);
    }
}
