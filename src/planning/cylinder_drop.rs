//! The drop of a picked foreign body into a waste bin: carried over the bin with its middle
//! over a free spot, lowered until its lowest point is just over the floor (or, where the arm
//! cannot take it that low, just above the rim), and let go at the lean that puts it as it stood
//! or lay on the belt.

use nalgebra::{Isometry3, Vector3};
use rapier3d::geometry::SharedShape;

use super::pick_planner::{PLACE_YAWS_DEG, PlaceSpot};
use super::{Carried, CylinderPick, Obstacle, PickPlanner, PlacePlan};
use crate::cell::BinBody;
use crate::math::pose_to_physics;
use crate::outcome::{Failure, FailureReason};
use crate::station::PerceivedObstacle;

/// How far above a waste bin's rim the carried body's lowest point is let go, m.
const DROP_ABOVE_RIM_M: f64 = 0.02;
/// How far above a waste bin's floor the carried body's lowest point is let go where the arm
/// can take it that low, m (past the planning margin).
const DROP_ABOVE_FLOOR_M: f64 = 0.015;
/// How far above the rim-level release point the straight descent over the bin starts, m.
const DROP_APPROACH_M: f64 = 0.04;
/// The largest lean of the tool at a drop, deg (the grasps lean up to 35).
const MAX_DROP_TILT_DEG: f64 = 40.0;
/// A lean that undoes less than this is none: the tool points straight down, deg.
const DROP_TILT_DEADBAND_DEG: f64 = 0.5;
/// How far from a wall the open jaws' centre line keeps, beyond their opening, where a lying body
/// is set down along it, m: a finger's thickness and the planning margin.
const LYING_WALL_CLEARANCE_M: f64 = 0.03;
/// Clearance to the walls of a body set down standing in a bin's corner, m (past the planning
/// margin).
const CORNER_INSET_M: f64 = 0.012;

impl PickPlanner {
    /// The drop of a picked cylinder into `bin`, where `in_bin` (world) already lies: the body
    /// (not the TCP: a grip off its middle shifts it) set down with its lowest point just over
    /// the floor where the arm clears the walls at some spot and yaw: a lying one against a wall
    /// and along it, else over the middle along a diagonal; a standing one over the middle, or
    /// when what is in the bin takes the middle, over a free corner. Where none is reachable
    /// that low, it is let go just above the rim over the middle (a standing one over a free
    /// corner). Either way clear of what is in the bin, at the lean that puts it as it stood or
    /// lay. When no spot is clear of what the bin holds, it is let go above the rim over the
    /// middle. Returns the plan and the body as it will rest on the floor.
    pub fn plan_drop(
        &self,
        picked: &CylinderPick,
        bin: &BinBody,
        in_bin: &[PerceivedObstacle],
    ) -> Result<(PlacePlan, PerceivedObstacle), Failure> {
        self.drop_into(picked, bin, in_bin, true)
    }

    /// [`Self::plan_drop`], letting go over the floor only when `low` allows it.
    fn drop_into(
        &self,
        picked: &CylinderPick,
        bin: &BinBody,
        in_bin: &[PerceivedObstacle],
        low: bool,
    ) -> Result<(PlacePlan, PerceivedObstacle), Failure> {
        let carried = &picked.carried;
        let axis_in_tcp = carried.tcp_from_shape.rotation * Vector3::y();
        let lying = axis_in_tcp.z.abs() < std::f64::consts::FRAC_1_SQRT_2;
        // Let go as it was on the belt: a grasp's lean undone, so that a standing body is
        // carried and let go upright, not hanging askew in the jaws.
        let tilt_rad = restoring_tilt_rad(&axis_in_tcp, lying);
        // The tool points down, leaned about its x: the carried body's lowest point is its
        // largest z in the unleaned tool frame.
        let leaned = Isometry3::rotation(Vector3::x() * tilt_rad) * carried.tcp_from_shape;
        let aabb = carried.shape.compute_aabb(&pose_to_physics(&leaned));
        let below_tcp_m = f64::from(aabb.maxs.z);
        let radius_m = carried
            .shape
            .as_cylinder()
            .map_or(0.0, |c| f64::from(c.radius));
        let base_from_world = self.world_from_base.inverse();
        let clear_of: Vec<Obstacle> = in_bin
            .iter()
            .map(|o| Obstacle {
                name: o.name.to_owned(),
                base_from_shape: base_from_world * o.world_from_shape,
                shape: o.shape.clone(),
            })
            .collect();
        let mut checker = picked.checker.clone();
        for obstacle in &clear_of {
            checker.add_obstacle(obstacle.clone());
        }
        let floor = bin.floor_center;
        let rim_z = floor.z + bin.wall_height;
        let [hx, hy] = [0, 1].map(|i| (bin.size[i] / 2.0 - radius_m - CORNER_INSET_M).max(0.0));
        // The middle first; a standing body finds a free corner when the middle is taken.
        let spots: Vec<[f64; 2]> = if lying {
            vec![[0.0, 0.0]]
        } else {
            vec![[0.0, 0.0], [hx, hy], [-hx, -hy], [hx, -hy], [-hx, hy]]
        };
        // A lying body along a diagonal first (the longest line in the bin: a body as long as
        // the bin is wide, let go along a side, lands on the rim), then at the usual yaws.
        let diagonal = bin.size[1].atan2(bin.size[0]);
        let yaws: Vec<f64> = if lying {
            self.yaws_along(carried, bin, tilt_rad, &[diagonal, -diagonal])
                .into_iter()
                .chain(PLACE_YAWS_DEG)
                .collect()
        } else {
            PLACE_YAWS_DEG.to_vec()
        };
        let limits = picked.payload.tool_limits();
        let above_z = rim_z + DROP_ABOVE_RIM_M + DROP_APPROACH_M + below_tcp_m;
        let mut last = None;
        // The body's middle from the TCP, world, with the tool at `yaw_deg`.
        let body_offset = |yaw_deg: f64| {
            let world_from_tcp = self.world_from_base
                * self.base_from_tcp(Vector3::zeros(), yaw_deg.to_radians(), tilt_rad);
            world_from_tcp.rotation * carried.tcp_from_shape.translation.vector
        };
        // Set down low, the body's lowest point just over the floor, at any spot and yaw where
        // the arm takes it there clear of the walls; else let go just above the rim. A body
        // dropped from the rim falls the bin's depth and more: a standing bottle topples, or,
        // turned in the jaws on the way (they hold a round body on a line), lands across the
        // rim; one set down on the floor stays where it was put.
        let mut tries: Vec<(f64, [f64; 2], f64)> = Vec::new();
        if low {
            let low_z = floor.z + DROP_ABOVE_FLOOR_M;
            if lying {
                // Set down low, a lying body goes against a wall first, along it (the longer
                // walls first): bodies side by side leave the rest of the floor free, where one
                // along the middle's diagonal takes it all. The finger between the body and the
                // wall keeps its clearance.
                let [wx, wy] = [0, 1]
                    .map(|i| (bin.size[i] / 2.0 - picked.open_m - LYING_WALL_CLEARANCE_M).max(0.0));
                let along_x = self.yaws_along(carried, bin, tilt_rad, &[0.0]);
                let along_y =
                    self.yaws_along(carried, bin, tilt_rad, &[std::f64::consts::FRAC_PI_2]);
                let x_walls = [([0.0, -wy], &along_x), ([0.0, wy], &along_x)];
                let y_walls = [([-wx, 0.0], &along_y), ([wx, 0.0], &along_y)];
                let walls = if bin.size[0] >= bin.size[1] {
                    [x_walls, y_walls]
                } else {
                    [y_walls, x_walls]
                };
                for (spot, along) in walls.into_iter().flatten() {
                    tries.extend(along.iter().map(|&yaw_deg| (low_z, spot, yaw_deg)));
                }
            }
            for s in &spots {
                tries.extend(yaws.iter().map(|&yaw_deg| (low_z, *s, yaw_deg)));
            }
        }
        // Above the rim, over the middle (or a free corner for a standing body) as before: a
        // body let go that high near a wall lands on the rim.
        let rim_release_z = rim_z + DROP_ABOVE_RIM_M;
        for s in &spots {
            tries.extend(yaws.iter().map(|&yaw_deg| (rim_release_z, *s, yaw_deg)));
        }
        for (release_z, [dx, dy], yaw_deg) in tries {
            let place_z = release_z + below_tcp_m;
            let offset = body_offset(yaw_deg);
            let spot = PlaceSpot {
                xy: [floor.x + dx - offset.x, floor.y + dy - offset.y],
                above_z: above_z.max(place_z),
                place_z,
                bin_name: &bin.name,
                clear_of: &clear_of,
                yaws_deg: Some(&[yaw_deg]),
                tilt_rad,
            };
            let plan = self.place_carried(
                carried,
                (picked.grip_m, picked.open_m),
                &spot,
                &picked.pick,
                &limits,
                &checker,
            );
            let plan = match plan {
                Ok(plan) => plan,
                Err(failure) => {
                    last = Some(failure);
                    continue;
                }
            };
            let Some(q_release) = plan.lower.end() else {
                continue;
            };
            // Let go, it comes to rest on the floor.
            let world_from_tcp =
                self.world_from_base * crate::kinematics::tcp_pose(&self.model, &q_release);
            let mut world_from_shape = world_from_tcp * carried.tcp_from_shape;
            world_from_shape.translation.vector.z -= release_z - floor.z;
            // What the bin holds from now on is the body itself, not its perceived bounds.
            let half_m = carried
                .shape
                .as_cylinder()
                .map_or(0.0, |c| f64::from(c.half_height));
            let shape = SharedShape::cylinder(half_m as f32, picked.grip_m as f32);
            let top_z = world_from_shape.translation.vector.z
                + cylinder_obstacle_top(&shape, &world_from_shape);
            let rests = PerceivedObstacle {
                name: "bottle",
                world_from_shape,
                shape,
                top_z,
            };
            return Ok((plan, rests));
        }
        if in_bin.is_empty() {
            return Err(last.unwrap_or_else(|| {
                Failure::new(
                    FailureReason::Unreachable,
                    format!("no place in bin {}", bin.name),
                )
            }));
        }
        // No spot clear of what the bin holds: over its middle all the same (the bodies in it
        // have seldom come to rest where they were let go; a drop onto them ends in the bin
        // about as often as not, measured in docs/removal.md).
        self.drop_into(picked, bin, &[], false)
    }

    /// Tool yaws at a place (deg, in 1 degree steps) that put the carried body's axis along one
    /// of `headings` (world, rad, as lines: a half turn apart are one).
    fn yaws_along(
        &self,
        carried: &Carried,
        bin: &BinBody,
        tilt_rad: f64,
        headings: &[f64],
    ) -> Vec<f64> {
        let here = Vector3::new(bin.floor_center.x, bin.floor_center.y, bin.floor_center.z);
        let base_here = self.world_from_base.inverse() * nalgebra::Point3::from(here);
        let mut yaws = Vec::new();
        for yaw_deg in (0..360).map(f64::from) {
            let base_from_tcp =
                self.base_from_tcp(base_here.coords, yaw_deg.to_radians(), tilt_rad);
            let axis = (self.world_from_base * base_from_tcp * carried.tcp_from_shape).rotation
                * Vector3::y();
            let heading = axis.y.atan2(axis.x);
            let off = |target: f64| {
                // Distance between headings as lines (a half turn apart are one line).
                let d = (heading - target).rem_euclid(std::f64::consts::PI);
                d.min(std::f64::consts::PI - d)
            };
            if headings.iter().any(|&h| off(h) < 0.5_f64.to_radians()) {
                yaws.push(yaw_deg);
            }
        }
        yaws
    }
}

/// The tool's lean about its jaw line (its x) that puts a body held with its axis along
/// `axis_in_tcp` as it was on the belt, rad: upright when it stood, level when it lay; the lean
/// nearest the tool pointing straight down, at most [`MAX_DROP_TILT_DEG`].
pub(super) fn restoring_tilt_rad(axis_in_tcp: &Vector3<f64>, lying: bool) -> f64 {
    // Leaned by t about x, the tool's frame turns the axis's world z into
    // -(a.y sin t + a.z cos t): zero for a level body, largest for an upright one.
    let a = axis_in_tcp;
    let t = if lying {
        (-a.z).atan2(a.y)
    } else {
        a.y.atan2(a.z)
    };
    // A half turn gives the same line.
    let t = t - std::f64::consts::PI * (t / std::f64::consts::PI).round();
    let max = MAX_DROP_TILT_DEG.to_radians();
    if t.abs() < DROP_TILT_DEADBAND_DEG.to_radians() {
        0.0
    } else {
        t.clamp(-max, max)
    }
}

/// How high a cylinder shape at `world_from_shape` reaches above its centre, m.
fn cylinder_obstacle_top(shape: &SharedShape, world_from_shape: &Isometry3<f64>) -> f64 {
    let aabb = shape.compute_aabb(&pose_to_physics(world_from_shape));
    f64::from(aabb.maxs.z) - world_from_shape.translation.vector.z
}
