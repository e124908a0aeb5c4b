//! The arm and gripper in the physics world, loaded from URDF: every moving link a kinematic body
//! placed by its servo's response (`sim::servo`), the fingers at the jaws' offset (`sim::jaws`).

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Isometry3;
use rapier3d::prelude::*;
use rapier3d_urdf::{UrdfJoint, UrdfLoaderOptions, UrdfRobot};

use super::jaws::{JawFinger, Jaws};
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
    /// The body each arm joint moves, base to flange.
    joint_bodies: [RigidBodyHandle; DOF],
    /// The pads' separation with the jaws closed on nothing, m.
    closed_gap_m: f64,
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
        let revolute = |j: &UrdfJoint| j.joint.locked_axes == JointAxesMask::LOCKED_REVOLUTE_AXES;
        let physics = &mut world.physics;
        // Every link but the root is a kinematic body, placed by the drive. Kinematic bodies
        // never touch each other or fixed ones: the planner keeps the arm clear of itself and
        // of the cell's fixed frame.
        let mut bodies = Vec::with_capacity(robot.links.len());
        let mut link_colliders = Vec::with_capacity(robot.links.len());
        let mut masses = Vec::with_capacity(robot.links.len());
        for link in robot.links {
            let mut body = link.body;
            masses.push(f64::from(body.mass()));
            if !body.is_fixed() {
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
        let missing = |name: &str| SimError::MissingJoint {
            joint: name.to_string(),
            path: path.to_path_buf(),
        };
        let find_joint = |name: &str| -> Result<&UrdfJoint, SimError> {
            let index = joint_names.iter().position(|n| n == name);
            index.map(|i| &robot.joints[i]).ok_or_else(|| missing(name))
        };
        let servos: Vec<ServoJoint> = robot
            .joints
            .iter()
            .filter(|j| revolute(j))
            .map(|j| ServoJoint::new((j.link1, j.link2), bodies[j.link2], &j.joint))
            .collect();
        let mut joints = [0usize; DOF];
        for (i, name) in kinematics.joints.iter().enumerate() {
            let joint = find_joint(name)?;
            if !revolute(joint) {
                return Err(missing(name));
            }
            joints[i] = joint.link2;
        }
        let mut fingers = Vec::with_capacity(2);
        let mut range_m = [f64::NEG_INFINITY, f64::INFINITY];
        let mut finger_mass_kg = 0.0;
        let mut speed_m_s = f64::INFINITY;
        for name in FINGER_JOINTS {
            let joint = find_joint(name)?;
            if !prismatic(joint) {
                return Err(missing(name));
            }
            if let Some(limits) = joint.joint.limits(JointAxis::LinX) {
                // The pad offset is the joint's coordinate: where it stops closing on nothing,
                // and how far it opens.
                range_m[0] = range_m[0].max(f64::from(limits.min).max(0.0));
                range_m[1] = range_m[1].min(f64::from(limits.max));
            }
            finger_mass_kg += masses[joint.link2];
            let limit = &description.joints[joint.urdf_joint_index].limit;
            if limit.velocity > 0.0 {
                speed_m_s = speed_m_s.min(limit.velocity);
            }
            fingers.push(JawFinger {
                parent: joint.link1,
                child: joint.link2,
                body: bodies[joint.link2],
                frame1: joint.joint.local_frame1,
                frame2: joint.joint.local_frame2,
            });
        }
        if !range_m[0].is_finite() {
            range_m[0] = 0.0;
        }
        if !range_m[1].is_finite() {
            range_m[1] = 0.1;
        }
        if !speed_m_s.is_finite() {
            // No velocity limit in the file: the drive's own jaw speed, with a margin.
            speed_m_s = 1.5 * JAW_SPEED_M_S;
        }
        let jaws = Jaws::new([fingers[0], fingers[1]], range_m, speed_m_s, finger_mass_kg);
        let closed_gap_m = 2.0 * jaws.stop_m();
        world.drive = Some(ServoDrive::new(servos, jaws, poses));
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
            joint_bodies: joints.map(|link| bodies[link]),
            closed_gap_m,
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

    /// Which arm joint moves `link`, base to flange from 0, whatever the links are called: the
    /// joint whose own link's body carries it (a link fixed to another rides on its body).
    /// `None` for the root and what is fixed to it, and for the fingers' own slides.
    pub fn joint_moving(&self, link: &ArmLink) -> Option<usize> {
        self.joint_bodies.iter().position(|body| *body == link.body)
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
        let drive = world.drive.as_ref();
        self.joints
            .map(|link| drive.and_then(|d| d.state(link)).map_or(0.0, |s| s.0))
    }

    /// Measured finger positions: each pad's distance from the gripper's centre line.
    pub fn finger_positions_m(&self, world: &World) -> [f64; 2] {
        let offset = world.drive.as_ref().map_or(0.0, |d| d.jaws.offset_m());
        [offset; 2]
    }

    /// The pads' separation with the jaws closed on nothing, m: twice the fingers' lower
    /// limit in the URDF.
    pub fn closed_gap_m(&self) -> f64 {
        self.closed_gap_m
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
        if let Some(drive) = world.drive.as_mut() {
            drive.jaws.command(pad_offset_m, max_force_n);
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
        drive.jaws.reset(pad_offset_m, 40.0);
        drive.forward_kinematics();
        drive.place(&mut world.physics, true);
        self.command(world, q, &[0.0; DOF]);
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
