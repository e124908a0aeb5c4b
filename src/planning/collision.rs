//! Collision checking of planned arm motion against the cell's static obstacles, with parry.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::geometry::SharedShape;
use rapier3d::math::Vector;
use rapier3d::parry::bounding_volume::{Aabb, BoundingVolume};
use rapier3d::parry::query;
use rapier3d::prelude::Pose;

use super::JointTrajectory;
use crate::kinematics::{ArmModel, DOF, JointVector, link_frames};
use crate::math::pose_to_physics;

/// What a robot shape moves with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinkMount {
    /// Rigid with DH frame `k` (0 is the fixed base, 6 the flange).
    Dh(usize),
    /// A finger: rigid with the flange, moved along the gripper's x axis by `sign` times the
    /// finger offset from its reference position.
    Finger {
        /// +1 for the finger that opens along +x, -1 for the other.
        sign: f64,
    },
}

/// One collision shape of the robot.
#[derive(Debug, Clone)]
pub struct RobotShape {
    /// Link name, for reports.
    pub link: String,
    /// What it moves with.
    pub mount: LinkMount,
    /// Pose of the shape in its mount frame (for fingers, at the reference finger offset).
    pub mount_from_shape: Isometry3<f64>,
    /// The shape.
    pub shape: SharedShape,
}

/// A static obstacle of the cell.
#[derive(Debug, Clone)]
pub struct Obstacle {
    /// Name, for reports.
    pub name: String,
    /// Pose in the robot's base frame.
    pub base_from_shape: Isometry3<f64>,
    /// The shape.
    pub shape: SharedShape,
}

/// An obstacle's pose as parry takes it, and its bounding box there.
fn placed(obstacle: &Obstacle) -> (Pose, Aabb) {
    let pose = pose_to_physics(&obstacle.base_from_shape);
    let aabb = obstacle.shape.compute_aabb(&pose);
    (pose, aabb)
}

/// A body carried in the gripper, fixed to the TCP.
#[derive(Debug, Clone)]
pub struct Carried {
    /// Pose of the body's shape in the TCP frame.
    pub tcp_from_shape: Isometry3<f64>,
    /// The shape.
    pub shape: SharedShape,
}

impl Carried {
    /// The body as held by a tool leaning `tilt_rad` about its jaw line (the TCP's x axis) at
    /// the grasp: turned by the opposite lean about the TCP (itself for no lean).
    pub fn leaning(&self, tilt_rad: f64) -> Self {
        if tilt_rad == 0.0 {
            return self.clone();
        }
        let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -tilt_rad);
        Self {
            tcp_from_shape: Isometry3::from_parts(Translation3::identity(), turn)
                * self.tcp_from_shape,
            shape: self.shape.clone(),
        }
    }
}

/// The first collision found along a motion.
#[derive(Debug, Clone, PartialEq)]
pub struct CollisionHit {
    /// The robot link (or `carried part`).
    pub link: String,
    /// The obstacle.
    pub obstacle: String,
    /// Time along the trajectory, s.
    pub time_s: f64,
}

/// What parry's f32 distances may come out short by, m: the fingertips stop exactly the
/// margin above the belt by design, and the distance there comes out a hair under it.
const F32_SLACK_M: f64 = 1e-4;

/// The nearest pair of a robot shape and an obstacle at one configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Clearance {
    /// Their distance, m (0 when they touch or overlap).
    pub distance_m: f64,
    /// The robot link (or `carried part`).
    pub link: String,
    /// The obstacle.
    pub obstacle: String,
}

/// The gap between two bounding boxes, m (0 when they overlap).
fn aabb_gap_m(a: &Aabb, b: &Aabb) -> f64 {
    let gap = (b.mins - a.maxs).max(a.mins - b.maxs).max(Vector::ZERO);
    f64::from(gap.length())
}

/// Checks arm configurations and trajectories against static obstacles with a clearance margin.
#[derive(Debug, Clone)]
pub struct CollisionChecker {
    model: ArmModel,
    robot: Vec<RobotShape>,
    obstacles: Vec<Obstacle>,
    /// Each obstacle's pose as parry takes it and its bounding box, worked out once: a plan
    /// checks thousands of configurations against the same static obstacles.
    placed_obstacles: Vec<(Pose, Aabb)>,
    finger_reference_m: f64,
    margin_m: f64,
    /// Largest joint step between checked configurations, rad.
    resolution_rad: f64,
}

impl CollisionChecker {
    /// A checker for the arm `model` (with its TCP) whose shapes are `robot`, fingers modelled at
    /// `finger_reference_m`, against `obstacles` in the base frame.
    pub fn new(
        model: ArmModel,
        robot: Vec<RobotShape>,
        finger_reference_m: f64,
        obstacles: Vec<Obstacle>,
        margin_m: f64,
    ) -> Self {
        let placed_obstacles = obstacles.iter().map(placed).collect();
        Self {
            model,
            robot,
            obstacles,
            placed_obstacles,
            finger_reference_m,
            margin_m,
            resolution_rad: 0.015,
        }
    }

    /// The obstacles checked against.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Adds an obstacle (the bottle once perception has seen it, say).
    pub fn add_obstacle(&mut self, obstacle: Obstacle) {
        self.placed_obstacles.push(placed(&obstacle));
        self.obstacles.push(obstacle);
    }

    /// The robot's shapes (and what it carries) placed at configuration `q`, as parry takes
    /// them, each with its bounding box.
    fn placed_robot<'s>(
        &'s self,
        q: &JointVector,
        finger_offset_m: f64,
        carried: Option<&'s Carried>,
    ) -> Vec<(&'s str, Pose, &'s SharedShape, Aabb)> {
        let frames = link_frames(&self.model, q);
        let flange = frames[DOF];
        let tcp = flange * self.model.flange_from_tcp;
        let mount_pose = |shape: &RobotShape| match shape.mount {
            LinkMount::Dh(k) => frames[k.min(DOF)],
            LinkMount::Finger { sign } => {
                let shift = sign * (finger_offset_m - self.finger_reference_m);
                flange * Translation3::new(shift, 0.0, 0.0)
            }
        };
        let mut placed: Vec<(&str, Isometry3<f64>, &SharedShape)> = self
            .robot
            .iter()
            .map(|shape| {
                let pose = mount_pose(shape) * shape.mount_from_shape;
                (shape.link.as_str(), pose, &shape.shape)
            })
            .collect();
        if let Some(carried) = carried {
            placed.push(("carried part", tcp * carried.tcp_from_shape, &carried.shape));
        }
        placed
            .into_iter()
            .map(|(link, pose, shape)| {
                let pose = pose_to_physics(&pose);
                let aabb = shape.compute_aabb(&pose);
                (link, pose, shape, aabb)
            })
            .collect()
    }

    /// The first robot shape within the margin of an obstacle at configuration `q`, skipping
    /// obstacles whose names are in `ignore`.
    pub fn check_configuration(
        &self,
        q: &JointVector,
        finger_offset_m: f64,
        carried: Option<&Carried>,
        ignore: &[&str],
    ) -> Option<(String, String)> {
        for (link, pose, shape, aabb) in self.placed_robot(q, finger_offset_m, carried) {
            let aabb = aabb.loosened(self.margin_m as f32);
            for (obstacle, (obstacle_pose, obstacle_aabb)) in
                self.obstacles.iter().zip(&self.placed_obstacles)
            {
                if ignore.contains(&obstacle.name.as_str()) {
                    continue;
                }
                if !aabb.intersects(obstacle_aabb) {
                    continue;
                }
                let close = match query::distance(
                    &pose,
                    shape.as_ref(),
                    obstacle_pose,
                    obstacle.shape.as_ref(),
                ) {
                    Ok(d) => f64::from(d.distance) + F32_SLACK_M < self.margin_m,
                    // Pairs parry cannot measure fall back to an overlap test.
                    Err(_) => query::intersection_test(
                        &pose,
                        shape.as_ref(),
                        obstacle_pose,
                        obstacle.shape.as_ref(),
                    )
                    .map(|hit| hit.intersecting)
                    .unwrap_or(true),
                };
                if close {
                    return Some((link.to_string(), obstacle.name.clone()));
                }
            }
        }
        None
    }

    /// The smallest distance from a robot shape (or what it carries) at configuration `q` to
    /// an obstacle not named in `ignore`, when it is below `cap_m`; `None` when every pair is at
    /// least `cap_m` apart. Pairs whose bounding boxes are `cap_m` apart are not measured.
    pub fn clearance(
        &self,
        q: &JointVector,
        finger_offset_m: f64,
        carried: Option<&Carried>,
        ignore: &[&str],
        cap_m: f64,
    ) -> Option<Clearance> {
        let placed = self.placed_robot(q, finger_offset_m, carried);
        self.nearest(placed, ignore, cap_m)
    }

    /// [`Self::clearance`] of the shapes rigid with the flange and the fingers alone: those
    /// that the TCP's pose places whatever the arm's configuration, so it bounds the whole
    /// robot's clearance from above for every IK branch of that pose.
    pub fn tool_clearance(
        &self,
        q: &JointVector,
        finger_offset_m: f64,
        ignore: &[&str],
        cap_m: f64,
    ) -> Option<Clearance> {
        let placed = self
            .placed_robot(q, finger_offset_m, None)
            .into_iter()
            .zip(&self.robot)
            .filter(|(_, shape)| {
                matches!(shape.mount, LinkMount::Dh(DOF) | LinkMount::Finger { .. })
            })
            .map(|(placed, _)| placed)
            .collect();
        self.nearest(placed, ignore, cap_m)
    }

    /// The nearest pair of `placed` robot shapes and obstacles below `cap_m` apart.
    fn nearest(
        &self,
        placed: Vec<(&str, Pose, &SharedShape, Aabb)>,
        ignore: &[&str],
        cap_m: f64,
    ) -> Option<Clearance> {
        let mut nearest: Option<Clearance> = None;
        let mut limit_m = cap_m;
        for (link, pose, shape, aabb) in placed {
            for (obstacle, (obstacle_pose, obstacle_aabb)) in
                self.obstacles.iter().zip(&self.placed_obstacles)
            {
                if ignore.contains(&obstacle.name.as_str()) {
                    continue;
                }
                // Only pairs that could beat the nearest found so far are measured.
                if !aabb.loosened(limit_m as f32).intersects(obstacle_aabb) {
                    continue;
                }
                let distance_m = match query::distance(
                    &pose,
                    shape.as_ref(),
                    obstacle_pose,
                    obstacle.shape.as_ref(),
                ) {
                    Ok(d) => f64::from(d.distance),
                    // Pairs parry cannot measure count as touching when they overlap, and
                    // as the box-to-box gap (a lower bound) when they do not.
                    Err(_) => match query::intersection_test(
                        &pose,
                        shape.as_ref(),
                        obstacle_pose,
                        obstacle.shape.as_ref(),
                    ) {
                        Ok(hit) if !hit.intersecting => aabb_gap_m(&aabb, obstacle_aabb),
                        _ => 0.0,
                    },
                };
                if distance_m < limit_m {
                    limit_m = distance_m;
                    nearest = Some(Clearance {
                        distance_m,
                        link: link.to_string(),
                        obstacle: obstacle.name.clone(),
                    });
                }
            }
        }
        nearest
    }

    /// The first collision along `trajectory`, sampled finely enough that no joint moves more
    /// than the checker's resolution between samples.
    pub fn check_trajectory(
        &self,
        trajectory: &JointTrajectory,
        finger_offset_m: f64,
        carried: Option<&Carried>,
        ignore: &[&str],
    ) -> Option<CollisionHit> {
        let span = (0.0, trajectory.duration_s());
        self.check_span(trajectory, span, finger_offset_m, carried, ignore)
    }

    /// The first collision along `trajectory` between `from_s` and `to_s` seconds from its
    /// start. Samples are spaced so that no joint at its velocity limit moves more than the
    /// checker's resolution between them (a blended path may leave its waypoints' polyline).
    pub fn check_span(
        &self,
        trajectory: &JointTrajectory,
        (from_s, to_s): (f64, f64),
        finger_offset_m: f64,
        carried: Option<&Carried>,
        ignore: &[&str],
    ) -> Option<CollisionHit> {
        // Walk the trajectory in fine time steps (cheap) and check a configuration (dear)
        // whenever a joint has moved the resolution since the last one checked.
        let fastest = self
            .model
            .limits
            .iter()
            .map(|l| l.max_velocity_rad_s)
            .fold(0.0, f64::max);
        let length = (to_s - from_s).max(0.0);
        let steps = ((4.0 * length * fastest / self.resolution_rad).ceil() as usize).max(1);
        let mut checked: Option<JointVector> = None;
        for i in 0..=steps {
            let t = from_s + length * i as f64 / steps as f64;
            let q = trajectory.sample(t)?.q;
            let moved = checked.is_none_or(|last| {
                let step = q
                    .iter()
                    .zip(&last)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                step >= 0.75 * self.resolution_rad
            });
            if !(moved || i == steps) {
                continue;
            }
            checked = Some(q);
            if let Some((link, obstacle)) =
                self.check_configuration(&q, finger_offset_m, carried, ignore)
            {
                return Some(CollisionHit {
                    link,
                    obstacle,
                    time_s: t,
                });
            }
        }
        None
    }
}
