//! The arm and gripper in the physics world: loaded from URDF as a multibody with joint motors.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Isometry3;
use rapier3d::prelude::*;
use rapier3d_urdf::{UrdfLoaderOptions, UrdfMultibodyOptions, UrdfRobot};

use super::urdf_graph::{tree_error, value_error};
use super::weld::{WeldedRobot, weld_fixed_links};
use super::{SimError, Tag, World};
use crate::kinematics::{BUILTIN_URDF, BUILTIN_URDF_PATH, DOF, JointVector, UrdfArm};
use crate::math::{pose_from_physics, pose_to_physics};

/// Names of the two finger joints in the URDF.
pub const FINGER_JOINTS: [&str; 2] = ["finger_left_joint", "finger_right_joint"];
/// Names of the finger links, left then right: their contacts with a part make the grip.
pub const FINGER_LINKS: [&str; 2] = ["finger_left_Link", "finger_right_Link"];
/// Jaw travel speed, m/s per jaw.
pub const JAW_SPEED_M_S: f64 = 0.1;
/// Index of a revolute joint's angle in a multibody joint's coordinates.
const REVOLUTE_COORD: usize = 3;
/// Index of a prismatic joint's offset in a multibody joint's coordinates.
const PRISMATIC_COORD: usize = 0;

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

/// One link of the URDF in the world: the body it rides on (its parent's, when a fixed joint
/// welded it there) and the colliders declared on it.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmLink {
    /// The link's name in the URDF.
    pub name: String,
    /// The body that carries the link.
    pub body: RigidBodyHandle,
    /// The colliders of the link's `<collision>` shapes.
    pub colliders: Vec<ColliderHandle>,
}

/// Handles of the arm in a [`World`].
#[derive(Debug, Clone)]
pub struct SimArm {
    joints: [MultibodyJointHandle; DOF],
    fingers: [MultibodyJointHandle; 2],
    finger_stops_m: [f64; 2],
    efforts: [f32; DOF],
    flange_body: RigidBodyHandle,
    links: Vec<ArmLink>,
    world_from_base: Isometry3<f64>,
    gains: ArmGains,
    kinematics: UrdfArm,
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
        Self::from_urdf_with(world, text, path, None, world_from_base)
    }

    /// As [`Self::from_urdf_str`], with the arm `kinematics` already read from the same `text`
    /// (a cell model reads it once for all its trials); `None` reads it here.
    pub fn from_urdf_with(
        world: &mut World,
        text: &str,
        path: &Path,
        kinematics: Option<&UrdfArm>,
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
        // Parsed and checked here, not by `UrdfRobot::from_str`: its loader panics on a joint
        // naming a link the file lacks, and on a cylinder of negative size.
        let description = rapier3d_urdf::urdf_rs::read_from_string(text)
            .map_err(|e| urdf_error(format!("{e:#}")))?;
        if let Some(reason) = tree_error(&description).or_else(|| value_error(&description)) {
            return Err(urdf_error(reason));
        }
        let kinematics = match kinematics {
            Some(arm) => arm.clone(),
            None => UrdfArm::from_robot(&description).map_err(|e| urdf_error(e.to_string()))?,
        };
        let WeldedRobot {
            robot,
            collider_sources,
        } = weld_fixed_links(
            UrdfRobot::from_robot(&description, options, mesh_dir),
            &description,
        );
        let own_links: Vec<usize> = robot.links.iter().map(|l| l.urdf_link_index).collect();
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
        let lowers_by_name: Vec<f64> = robot
            .joints
            .iter()
            .map(|j| description.joints[j.urdf_joint_index].limit.lower)
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
        // A joint by name: its handle and its index among the URDF's joints.
        let find_joint = |name: &str| -> Result<(MultibodyJointHandle, usize), SimError> {
            let index = joint_names.iter().position(|n| n == name);
            let handle = index.and_then(|i| handles.joints[i].joint.map(|h| (h, i)));
            handle.ok_or_else(|| SimError::MissingJoint {
                joint: name.to_string(),
                path: path.to_path_buf(),
            })
        };
        let mut joints = [MultibodyJointHandle::invalid(); DOF];
        let mut efforts = [0.0f32; DOF];
        for (i, name) in kinematics.joints.iter().enumerate() {
            let (handle, j) = find_joint(name)?;
            (joints[i], efforts[i]) = (handle, efforts_by_name[j]);
        }
        let mut fingers = [MultibodyJointHandle::invalid(); 2];
        let mut finger_stops_m = [0.0; 2];
        for (i, name) in FINGER_JOINTS.iter().enumerate() {
            let (handle, j) = find_joint(name)?;
            // The joint's lower limit: where the pad stops when the jaws close on nothing.
            (fingers[i], finger_stops_m[i]) = (handle, lowers_by_name[j].max(0.0));
        }
        couple_fingers(world, &fingers);
        // Every URDF link with a body or a collider, in the file's order; a welded link names
        // its host's body and its own colliders.
        let mut links: Vec<(usize, ArmLink)> = Vec::new();
        for ((own, handle), sources) in own_links.iter().zip(&handles.links).zip(&collider_sources)
        {
            let mut by_source: BTreeMap<usize, Vec<ColliderHandle>> = BTreeMap::new();
            by_source.entry(*own).or_default();
            for (collider, source) in handle.colliders.iter().zip(sources) {
                by_source.entry(*source).or_default().push(collider.handle);
            }
            links.extend(by_source.into_iter().map(|(source, colliders)| {
                let link = ArmLink {
                    name: description.links[source].name.clone(),
                    body: handle.body,
                    colliders,
                };
                (source, link)
            }));
        }
        links.sort_by_key(|(source, _)| *source);
        let links: Vec<ArmLink> = links.into_iter().map(|(_, link)| link).collect();
        let Some(flange_body) = links
            .iter()
            .find(|link| link.name == kinematics.flange_link)
            .map(|link| link.body)
        else {
            return Err(urdf_error(format!(
                "no link named `{}`",
                kinematics.flange_link
            )));
        };
        let arm = Self {
            joints,
            fingers,
            finger_stops_m,
            efforts,
            flange_body,
            links,
            world_from_base,
            gains: ArmGains::default(),
            kinematics,
        };
        Ok(arm)
    }

    /// The arm's joints, links and kinematic model as its URDF gives them.
    pub fn kinematics(&self) -> &UrdfArm {
        &self.kinematics
    }

    /// Pose of the arm's `base_link` in the world.
    pub fn world_from_base(&self) -> &Isometry3<f64> {
        &self.world_from_base
    }

    /// The arm's links with their bodies and colliders, in URDF order.
    pub fn links(&self) -> &[ArmLink] {
        &self.links
    }

    /// The link a collider of the arm was declared on.
    pub fn link_of_collider(&self, collider: ColliderHandle) -> Option<&ArmLink> {
        self.links
            .iter()
            .find(|link| link.colliders.contains(&collider))
    }

    /// The body that carries the link named `name`.
    pub fn link_body(&self, name: &str) -> Option<RigidBodyHandle> {
        self.links
            .iter()
            .find(|link| link.name == name)
            .map(|link| link.body)
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
        self.fingers
            .map(|handle| f64::from(joint_coord(world, handle, PRISMATIC_COORD).unwrap_or(0.0)))
    }

    /// The pads' separation with the jaws closed on nothing, m: the sum of the finger joints'
    /// lower limits in the URDF.
    pub fn closed_gap_m(&self) -> f64 {
        self.finger_stops_m.iter().sum()
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

    /// Drives both fingers towards `pad_offset_m` from the centre line, pushing with at most
    /// `max_force_n` each: a force-limited parallel gripper.
    pub fn command_gripper(&self, world: &mut World, pad_offset_m: f64, max_force_n: f64) {
        for handle in &self.fingers {
            with_joint_mut(world, *handle, |joint| {
                // Force-based so that the limit is in newtons: a stiff, well-damped servo that
                // saturates at the force limit when the jaws are blocked by a part.
                joint.set_motor_model(JointAxis::LinX, MotorModel::ForceBased);
                joint.set_motor(JointAxis::LinX, pad_offset_m as f32, 0.0, 4_000.0, 120.0);
                joint.set_motor_max_force(JointAxis::LinX, max_force_n as f32);
            });
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
            .chain(
                self.fingers
                    .iter()
                    .map(|handle| (*handle, pad_offset_m as f32, PRISMATIC_COORD)),
            )
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
        self.command(world, q, &[0.0; DOF]);
        self.command_gripper(world, pad_offset_m, 40.0);
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

/// Couples the two finger joints so they open and close together, as a parallel gripper's jaws
/// do through their rack and pinion.
fn couple_fingers(world: &mut World, fingers: &[MultibodyJointHandle; 2]) {
    let joints = &mut world.physics.multibody_joints;
    let (Some((_, left)), Some((_, right))) = (joints.get(fingers[0]), joints.get(fingers[1]))
    else {
        return;
    };
    if let Some((multibody, _)) = joints.get_mut(fingers[0]) {
        multibody.add_dof_coupling(MultibodyDofCoupling {
            link1: left,
            dof1: 0,
            axis1: PRISMATIC_COORD,
            link2: right,
            dof2: 0,
            axis2: PRISMATIC_COORD,
            coeff: 1.0,
            offset: 0.0,
        });
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

impl SimArm {
    /// Tags every robot collider as [`Tag::Robot`] and puts it in the robot's collision groups;
    /// finger pads get `pad_friction`, the rest of the robot a moderate one.
    pub fn dress_colliders(&self, world: &mut World, pad_friction: f64) {
        let physics = &mut world.physics;
        for link in self.links() {
            let name = &link.name;
            let friction = if name.starts_with("finger") {
                pad_friction
            } else {
                0.5
            };
            for handle in &link.colliders {
                if let Some(collider) = physics.colliders.get_mut(*handle) {
                    collider.set_friction(friction as f32);
                    if name.starts_with("finger") {
                        // Rubber pads grip with their own coefficient, whatever they touch.
                        collider.set_friction_combine_rule(CoefficientCombineRule::Max);
                        // The pads' contacts go through the contact hook, where the pads'
                        // stiction (`sim::PadStiction`) holds what they press.
                        collider.set_active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS);
                    }
                    collider.user_data = Tag::Robot as u128;
                    collider.set_collision_groups(super::groups::robot());
                }
            }
        }
    }
}
