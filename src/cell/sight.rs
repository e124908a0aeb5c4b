//! Whether the camera sees the pick station past the robot standing at its home pose: the
//! renderer draws the robot's collision shapes, so a sight line from the camera's centre to an
//! end face that crosses one of them is a part the camera cannot see while the arm waits there.
//!
//! A camera mounted where the arm hides the station (inside the arm's reach, on the robot's
//! side of the belt) otherwise shows up only as every trial's `not_detected`.

use nalgebra::{Isometry3, Point3, Vector3};
use rapier3d::prelude::{Pose, Ray, SharedShape, Vector};

use super::cell_model::CellModel;
use super::layout::{CellError, FINGER_REFERENCE_M};
use crate::math::{pose_from_physics, pose_to_physics};
use crate::scenario::CameraSection;
use crate::sim::{SimArm, World};

/// Least distance between the camera's centre and the arm at home, m: a camera's housing
/// reaches at least this far from its centre (and the renderer clips what lies nearer than its
/// 2 cm near plane).
pub const MIN_EYE_CLEARANCE_M: f64 = 0.02;

/// What the camera sees of the pick station past the arm at home.
#[derive(Debug, Clone, PartialEq)]
pub struct StationSight {
    /// Sight lines cast: end-face points over the station's spread (along the belt by the
    /// widest part's radius, across it by the largest lateral offset, at the lowest and highest
    /// end face).
    pub lines: usize,
    /// Those the robot blocks.
    pub blocked: usize,
    /// Whether the line to the station's centre, at the tallest part's end face, is blocked.
    pub center_blocked: bool,
    /// The robot link that blocks the first blocked line, nearest the camera.
    pub link: Option<String>,
    /// The camera centre's distance from the nearest robot link at home, m (0 inside one).
    pub eye_clearance_m: f64,
    /// That link.
    pub nearest_link: String,
}

impl StationSight {
    /// The camera's sight of the pick station in `model`'s scenario, the arm at
    /// `robot.home_q_rad`.
    pub fn of(model: &CellModel) -> Result<Self, CellError> {
        let scenario = model.scenario();
        let (mut world, arm) = model.arm_world()?;
        arm.reset_to(&mut world, &scenario.robot.home_q_rad, FINGER_REFERENCE_M);

        let (eye, _) = scenario.camera.eye_and_target(&scenario.conveyor);
        let eye = Point3::from(eye);
        let [px, py, pz] = CameraSection::pick_station(&scenario.conveyor);
        let heights = scenario.part_types.iter().map(|p| p.height_mm / 1000.0);
        let low = heights.clone().fold(f64::INFINITY, f64::min);
        let high = heights.fold(0.0, f64::max);
        let radius = scenario
            .part_types
            .iter()
            .map(|p| p.outer_diameter_mm / 2000.0)
            .fold(0.0, f64::max);
        let lateral = scenario.parts.max_lateral_offset_m;

        // The centre's line first: `center_blocked` reads the first result.
        let mut targets = vec![Point3::new(px, py, pz + high)];
        for z in [low, high] {
            for dx in [-radius, 0.0, radius] {
                for dy in [-lateral, 0.0, lateral] {
                    if z == high && dx == 0.0 && dy == 0.0 {
                        continue;
                    }
                    targets.push(Point3::new(px + dx, py + dy, pz + z));
                }
            }
        }
        let shapes = link_shapes(&world, &arm);
        let mut sight = Self {
            lines: targets.len(),
            blocked: 0,
            center_blocked: false,
            link: None,
            eye_clearance_m: f64::INFINITY,
            nearest_link: String::new(),
        };
        let at_eye = Vector::new(eye.x as f32, eye.y as f32, eye.z as f32);
        for (name, shape, pose) in &shapes {
            let d = f64::from(shape.distance_to_point(pose, at_eye, true));
            if d < sight.eye_clearance_m {
                sight.eye_clearance_m = d;
                sight.nearest_link = name.clone();
            }
        }
        for (i, target) in targets.iter().enumerate() {
            if let Some(link) = blocking_link(&shapes, &eye, target) {
                sight.blocked += 1;
                sight.center_blocked |= i == 0;
                sight.link.get_or_insert(link);
            }
        }
        Ok(sight)
    }

    /// The refusal when the robot at home hides the station's centre from the camera, naming
    /// the keys that move the one or the other.
    pub fn check(&self) -> Result<(), CellError> {
        if self.eye_clearance_m < MIN_EYE_CLEARANCE_M {
            return Err(CellError::Scenario(format!(
                "camera.position_m: the camera's centre lies {:.1} mm from the robot's {} at \
                 robot.home_q_rad, {}: a camera there stands where the arm is; mount it at \
                 least {:.0} mm clear of the arm at home",
                self.eye_clearance_m * 1000.0,
                self.nearest_link,
                if self.eye_clearance_m > 0.0 {
                    "closer than any camera housing allows"
                } else {
                    "inside it"
                },
                MIN_EYE_CLEARANCE_M * 1000.0
            )));
        }
        if !self.center_blocked {
            return Ok(());
        }
        Err(CellError::Scenario(format!(
            "camera.position_m: the robot at robot.home_q_rad hides the pick station from the \
             camera ({} blocks the line of sight to the station's centre, {} of {} lines to \
             the end faces there are blocked); mount the camera where the arm at home does \
             not stand between it and the station, or give the arm another home",
            self.link.as_deref().unwrap_or("a link"),
            self.blocked,
            self.lines
        )))
    }

    /// A warning for a station partly hidden, `None` when every line is clear or the centre is
    /// hidden or the camera stands in the arm (then [`Self::check`] refuses).
    pub fn partial_warning(&self) -> Option<String> {
        (self.blocked > 0 && self.check().is_ok()).then(|| {
            format!(
                "camera.position_m: the robot at robot.home_q_rad ({}) blocks {} of {} lines of \
                 sight to the end faces at the pick station; parts standing there may go \
                 undetected",
                self.link.as_deref().unwrap_or("a link"),
                self.blocked,
                self.lines
            )
        })
    }
}

/// Each robot link's collision shapes with their poses in the world: the link's name, the shape,
/// its pose.
fn link_shapes(world: &World, arm: &SimArm) -> Vec<(String, SharedShape, Pose)> {
    let physics = &world.physics;
    let mut shapes = Vec::new();
    for link in arm.links() {
        let Some(body) = physics.bodies.get(link.body) else {
            continue;
        };
        let world_from_body = pose_from_physics(body.position());
        for handle in &link.colliders {
            let Some(collider) = physics.colliders.get(*handle) else {
                continue;
            };
            let body_from_collider = collider
                .position_wrt_parent()
                .map(pose_from_physics)
                .unwrap_or_else(Isometry3::identity);
            let pose = pose_to_physics(&(world_from_body * body_from_collider));
            shapes.push((link.name.clone(), collider.shared_shape().clone(), pose));
        }
    }
    shapes
}

/// The link among `shapes` whose shape the segment from `eye` to `target` crosses nearest the
/// camera, if any.
fn blocking_link(
    shapes: &[(String, SharedShape, Pose)],
    eye: &Point3<f64>,
    target: &Point3<f64>,
) -> Option<String> {
    let along = target - eye;
    let length = along.norm();
    let dir: Vector3<f64> = along / length;
    let ray = Ray::new(
        Vector::new(eye.x as f32, eye.y as f32, eye.z as f32),
        Vector::new(dir.x as f32, dir.y as f32, dir.z as f32),
    );
    // Up to 1 mm short of the target: the end face itself is never hidden by itself.
    let reach = (length - 1e-3) as f32;
    let mut nearest: Option<(f32, &str)> = None;
    for (name, shape, pose) in shapes {
        if let Some(toi) = shape.cast_ray(pose, &ray, reach, true)
            && nearest.is_none_or(|(best, _)| toi < best)
        {
            nearest = Some((toi, name));
        }
    }
    nearest.map(|(_, name)| name.to_owned())
}
