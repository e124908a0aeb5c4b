//! The arm and gripper in the physics world, loaded from URDF: the arm's links kinematic bodies
//! placed by their servos' response (`sim::servo`), the fingers dynamic bodies on prismatic
//! impulse joints with force-limited motors.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Isometry3;
use rapier3d::prelude::*;
use rapier3d_urdf::{UrdfJoint, UrdfLoaderOptions, UrdfRobot};

use super::servo::{ServoDrive, ServoJoint};
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
    /// The servo drive's index of the link each arm joint moves.
    joints: [usize; DOF],
    /// The fingers' joints on the jaws' carrier, left then right.
    fingers: [MultibodyJointHandle; 2],
    /// The jaws' carrier, and the gripper's body it is welded to.
    carrier: RigidBodyHandle,
    host: RigidBodyHandle,
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
        let prismatic = |j: &UrdfJoint| j.joint.locked_axes == JointAxesMask::LOCKED_PRISMATIC_AXES;
        // Links on a prismatic joint (the fingers) stay dynamic; the rest are placed by the
        // servo drive.
        let dynamic: Vec<bool> = (0..robot.links.len())
            .map(|i| robot.joints.iter().any(|j| j.link2 == i && prismatic(j)))
            .collect();
        let physics = &mut world.physics;
        let mut bodies = Vec::with_capacity(robot.links.len());
        let mut link_colliders = Vec::with_capacity(robot.links.len());
        for (link, &dynamic) in robot.links.into_iter().zip(&dynamic) {
            let mut body = link.body;
            if !dynamic {
                body.set_body_type(RigidBodyType::KinematicPositionBased, false);
            }
            let handle = physics.bodies.insert(body);
            let colliders: Vec<ColliderHandle> = link
                .colliders
                .into_iter()
                .map(|c| {
                    physics
                        .colliders
                        .insert_with_parent(c.collider, handle, &mut physics.bodies)
                })
                .collect();
            bodies.push(handle);
            link_colliders.push(colliders);
        }
        let poses: Vec<Pose> = bodies
            .iter()
            .map(|b| {
                physics
                    .bodies
                    .get(*b)
                    .map_or(Pose::IDENTITY, |b| *b.position())
            })
            .collect();
        // Revolute joints go to the servo drive by the link they move; the fingers' prismatic
        // joints make the jaws (`sim::servo::Jaws`).
        let mut servos = Vec::new();
        let mut joint_links: Vec<Option<usize>> = vec![None; robot.joints.len()];
        for (i, joint) in robot.joints.iter().enumerate() {
            if joint.joint.locked_axes == JointAxesMask::LOCKED_REVOLUTE_AXES {
                let link = (joint.link1, joint.link2);
                servos.push(ServoJoint::new(link, bodies[joint.link2], &joint.joint));
                joint_links[i] = Some(joint.link2);
            }
        }
        let index_of = |name: &str| -> Result<usize, SimError> {
            joint_names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| SimError::MissingJoint {
                    joint: name.to_string(),
                    path: path.to_path_buf(),
                })
        };
        let missing = |name: &str| SimError::MissingJoint {
            joint: name.to_string(),
            path: path.to_path_buf(),
        };
        let mut joints = [0usize; DOF];
        for (i, name) in kinematics.joints.iter().enumerate() {
            joints[i] = joint_links[index_of(name)?].ok_or_else(|| missing(name))?;
        }
        let mut finger_joints = Vec::with_capacity(2);
        for name in FINGER_JOINTS {
            let joint = &robot.joints[index_of(name)?];
            if !prismatic(joint) {
                return Err(missing(name));
            }
            finger_joints.push(joint);
        }
        // The jaws: a small multibody, the two fingers on their prismatic joints coupled as a
        // rack couples them, rooted on a heavy, weightless carrier welded to the gripper's
        // kinematic body (a multibody's non-dynamic root would not pass its motion on to the
        // fingers' velocities, which the pads' friction needs).
        let host = bodies[finger_joints[0].link1];
        let host_pose = physics
            .bodies
            .get(host)
            .map_or(Pose::IDENTITY, |b| *b.position());
        let carrier = physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .pose(host_pose)
                .additional_mass_properties(MassProperties::new(
                    Vector::ZERO,
                    CARRIER_MASS_KG,
                    Vector::splat(CARRIER_INERTIA_KG_M2),
                ))
                .gravity_scale(0.0)
                .can_sleep(false),
        );
        physics.impulse_joints.insert(
            host,
            carrier,
            FixedJointBuilder::new().contacts_enabled(false),
            true,
        );
        let mut fingers = [MultibodyJointHandle::invalid(); 2];
        for (i, joint) in finger_joints.iter().enumerate() {
            fingers[i] = physics
                .multibody_joints
                .insert(carrier, bodies[joint.link2], joint.joint, true)
                .ok_or_else(|| missing(FINGER_JOINTS[i]))?;
        }
        couple_fingers(world, &fingers);
        let drive = ServoDrive::new(servos, poses);
        world.drive = Some(drive);
        // Every URDF link with a body or a collider, in the file's order; a welded link names
        // its host's body and its own colliders.
        let mut links: Vec<(usize, ArmLink)> = Vec::new();
        for (((own, body), colliders), sources) in own_links
            .iter()
            .zip(&bodies)
            .zip(&link_colliders)
            .zip(&collider_sources)
        {
            let mut by_source: BTreeMap<usize, Vec<ColliderHandle>> = BTreeMap::new();
            by_source.entry(*own).or_default();
            for (collider, source) in colliders.iter().zip(sources) {
                by_source.entry(*source).or_default().push(*collider);
            }
            links.extend(by_source.into_iter().map(|(source, colliders)| {
                let link = ArmLink {
                    name: description.links[source].name.clone(),
                    body: *body,
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
            carrier,
            host,
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
        self.joints.map(|link| {
            world
                .drive
                .as_ref()
                .and_then(|d| d.state(link))
                .map_or(0.0, |s| s.0)
        })
    }

    /// Joint velocities, rad/s.
    pub fn joint_velocities(&self, world: &World) -> JointVector {
        self.joints.map(|link| {
            world
                .drive
                .as_ref()
                .and_then(|d| d.state(link))
                .map_or(0.0, |s| s.1)
        })
    }

    /// Measured finger positions: each pad's distance from the gripper's centre line.
    pub fn finger_positions_m(&self, world: &World) -> [f64; 2] {
        self.fingers
            .map(|handle| f64::from(joint_coord(world, handle, PRISMATIC_COORD).unwrap_or(0.0)))
    }

    /// Commands the joint servos to a position and feed-forward velocity.
    pub fn command(&self, world: &mut World, q: &JointVector, qd: &JointVector) {
        let gains = (
            f64::from(self.gains.stiffness),
            f64::from(self.gains.damping),
        );
        let Some(drive) = world.drive.as_mut() else {
            return;
        };
        for (i, &link) in self.joints.iter().enumerate() {
            // Rounded as rapier's motor held its targets, so the response is the same.
            let (q, qd) = (f64::from(q[i] as f32), f64::from(qd[i] as f32));
            drive.command(link, q, qd, gains);
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
        let Some(drive) = world.drive.as_mut() else {
            return;
        };
        for (i, &link) in self.joints.iter().enumerate() {
            drive.reset(link, f64::from(q[i] as f32));
        }
        drive.forward_kinematics();
        let physics = &mut world.physics;
        drive.place(&mut physics.bodies, true);
        // The carrier where the gripper now is, at rest, and the fingers at `pad_offset_m`.
        let host_pose = physics.bodies.get(self.host).map(|b| *b.position());
        if let (Some(pose), Some(carrier)) = (host_pose, physics.bodies.get_mut(self.carrier)) {
            carrier.set_position(pose, true);
            carrier.set_linvel(Vector::ZERO, true);
            carrier.set_angvel(Vector::ZERO, true);
        }
        let targets: Vec<usize> = self
            .fingers
            .iter()
            .filter_map(|handle| physics.multibody_joints.get(*handle).map(|(_, link)| link))
            .collect();
        if let Some((multibody, _)) = physics.multibody_joints.get_mut(self.fingers[0]) {
            let mut displacement = vec![0.0f32; multibody.ndofs()];
            for link_id in targets {
                if let Some(link) = multibody.link(link_id) {
                    let offset = pad_offset_m as f32 - link.joint().coords()[PRISMATIC_COORD];
                    displacement[link.assembly_id()] = offset;
                }
            }
            multibody.apply_displacements(&displacement);
            multibody.generalized_velocity_mut().fill(0.0);
            multibody.forward_kinematics(&physics.bodies, true);
            multibody.update_rigid_bodies(&mut physics.bodies, false);
        }
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

/// Index of a prismatic joint's offset in a multibody joint's coordinates.
const PRISMATIC_COORD: usize = 0;
/// Mass (kg) and principal inertia (kg m^2) of the jaws' carrier: heavy enough that what the
/// pads hold barely moves it against its weld to the gripper.
const CARRIER_MASS_KG: f32 = 50.0;
const CARRIER_INERTIA_KG_M2: f32 = 1.0;

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
                        // Contacts of a hooked collider are never recycled: rapier otherwise keeps
                        // a pair's contacts, normal and lever arms frozen in world space while the
                        // pair's relative pose barely changes, which is exactly a held part. As
                        // the arm turned the gripper (up to 11 deg before a refresh) the pads'
                        // squeeze then pushed along stale normals, twisted the part and walked it
                        // out of the jaws. Pad contacts are rebuilt every step instead.
                        collider.set_active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS);
                    }
                    collider.user_data = Tag::Robot as u128;
                    collider.set_collision_groups(super::groups::robot());
                }
            }
        }
    }
}
