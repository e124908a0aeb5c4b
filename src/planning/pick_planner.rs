//! The grasp and place search: from a percept and the cell's obstacles to collision-checked
//! joint trajectories down to the part, up with it, over to a bin and back home.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::geometry::SharedShape;

use super::capture_robot_shapes;
use super::grasp_search::{GraspRanking, GraspSearch};
use super::{
    Carried, CollisionChecker, JointTrajectory, Obstacle, Payload, RobotShape, ToolLimits,
    straight_line,
};
use crate::cell::{BinBody, Cell, CellModel, SceneryBox};
use crate::kinematics::{AnalyticIk, ArmModel, IkSolver, JointVector};
use crate::outcome::{Failure, FailureReason, fail};
use crate::station::Percept;

/// Height of the TCP above the part's bottom while grasping a tube short enough to clear the
/// gripper's palm from there: the fingertips stop 8 mm above the belt
/// ([`PickPlanner::grasp_tcp_above_bottom_m`] grips a taller one higher).
pub const GRASP_TCP_ABOVE_BOTTOM_M: f64 = 0.023;
/// Least gap between a grasped tube's top and the gripper's palm, m.
pub const PALM_CLEARANCE_M: f64 = 0.005;
/// Approach and retreat distance above grasp and place poses, m.
pub(super) const APPROACH_M: f64 = 0.12;
/// How far the fingertips reach below the TCP along the tool axis, m.
pub(super) const FINGERTIP_BELOW_TCP_M: f64 = 0.015;
/// Half the width of a finger pad across the jaw axis, m.
pub(super) const PAD_HALF_WIDTH_M: f64 = 0.015;
/// Sample spacing of straight tool lines, m.
pub(super) const LINE_STEP_M: f64 = 0.005;
/// The planner's name for the part while it stands on the belt.
pub const PART_OBSTACLE: &str = "part";
/// Perception's name for a tube other than the part.
const OTHER_PART: &str = "other part";
/// Distance between neighbouring places for parts in a bin, m.
const BIN_SLOT_PITCH_M: f64 = 0.09;
/// Clearance the planner keeps from obstacles, m.
pub(super) const PLANNING_MARGIN_M: f64 = 0.008;

/// The motion of a pick: over the part and down to it.
#[derive(Debug, Clone)]
pub struct PickPlan {
    /// From where the arm stands to above the part (part 0), blended into the straight descent
    /// to the grasp pose (part 1), jaws open.
    pub approach: JointTrajectory,
    /// The arm above the part, where the descent's straight line starts.
    pub pregrasp: JointVector,
    /// Straight up from the grasp pose, the joint path not yet timed (the carry limit times it).
    pub lift_path: Vec<JointVector>,
    /// Where the lift ends.
    pub lift_end: JointVector,
    /// Smallest clearance of the robot to the obstacles along descent, grasp and lift, m (at
    /// most [`super::CLEARANCE_CAP_M`]: beyond it every grasp counts as clear).
    pub clearance_m: f64,
    /// How many candidate grasps the search weighed.
    pub candidates: usize,
    /// The tool's lean about its jaw line at the grasp, rad (0: pointing straight down); the
    /// part stands at this angle to the tool while it is held.
    pub tilt_rad: f64,
}

/// The motion of a place: up and over to the bin, down into it, back home.
#[derive(Debug, Clone)]
pub struct PlacePlan {
    /// Straight up with the part (part 0), blended into the move above the bin slot (part 1),
    /// within the grip's carry limit.
    pub carry: JointTrajectory,
    /// Straight down into the slot, within the carry limit.
    pub lower: JointTrajectory,
    /// Straight up (part 0), blended into the move home (part 1), jaws open.
    pub retreat: JointTrajectory,
}

/// Where a carried object is put down: over `xy`, lowered from `above_z` to `place_z` (TCP
/// heights, world, m) in the bin named `bin_name`.
#[derive(Debug, Clone, Copy)]
pub struct PlaceSpot<'a> {
    /// The place's centre, world x and y, m.
    pub xy: [f64; 2],
    /// TCP height where the straight descent starts, m.
    pub above_z: f64,
    /// TCP height where the jaws open, m.
    pub place_z: f64,
    /// The bin's name, for reports.
    pub bin_name: &'a str,
    /// What already lies in the bin, base frame: the carried body let go at `place_z` keeps
    /// 5 mm (`RELEASE_CLEARANCE_M`) from each (empty for the part bins, whose slots are apart).
    pub clear_of: &'a [Obstacle],
    /// Tool yaws to try at the place, deg, in order (`None`: the right angles, then the
    /// diagonals).
    pub yaws_deg: Option<&'a [f64]>,
    /// The tool's lean about the jaw line at the place, rad (0: pointing straight down).
    pub tilt_rad: f64,
}

/// Clearance the carried body keeps, where it is let go, from what already lies in the bin, m.
pub(super) const RELEASE_CLEARANCE_M: f64 = 0.005;
/// Tool yaws tried at a place by default, deg.
pub(super) const PLACE_YAWS_DEG: [f64; 8] = [0.0, 90.0, 180.0, 270.0, 45.0, 135.0, 225.0, 315.0];

/// The robot and the cell as the planner sees them, fixed for a trial.
#[derive(Debug, Clone)]
pub struct PickPlanner {
    /// The arm's kinematic model with the gripper's TCP.
    pub model: ArmModel,
    /// Its inverse kinematics.
    pub ik: AnalyticIk,
    /// The arm's base in the world.
    pub world_from_base: Isometry3<f64>,
    /// The robot's collision shapes.
    pub robot_shapes: Vec<RobotShape>,
    /// Finger offset at which `robot_shapes` were captured, m.
    pub finger_reference_m: f64,
    /// The cell's fixed obstacles, in the arm's base frame.
    pub obstacles: Vec<Obstacle>,
    /// Top of the belt, world z, m.
    pub belt_top_z: f64,
    /// How much wider than the part the jaws open, m.
    pub open_clearance_m: f64,
    /// Share of the joint limits for moves with empty jaws.
    pub speed_fraction: f64,
    /// Share of the joint limits for moves carrying a part (the grip's own limit applies too).
    pub carry_speed_fraction: f64,
    /// Where the arm goes home to.
    pub home_q_rad: JointVector,
}

/// The cell's scenery as the planner's obstacles, in the arm's base frame.
pub fn scenery_obstacles(
    scenery: &[SceneryBox],
    base_from_world: &Isometry3<f64>,
) -> Vec<Obstacle> {
    scenery
        .iter()
        .map(|b| Obstacle {
            name: b.name.clone(),
            base_from_shape: base_from_world * b.world_from_shape,
            shape: b.shape.clone(),
        })
        .collect()
}

impl PickPlanner {
    /// The planner of `model`'s arm in `cell` as built for a trial: the arm's model and IK, its
    /// collision shapes captured at home, the cell's scenery, and the scenario's speeds.
    pub fn for_cell(model: &CellModel, cell: &Cell) -> Self {
        let scenario = model.scenario();
        let arm = model.arm_model().clone();
        let home = scenario.robot.home_q_rad;
        let world_from_base = *cell.arm.world_from_base();
        Self {
            robot_shapes: capture_robot_shapes(&cell.world, &cell.arm, &arm, &home),
            model: arm,
            ik: model.ik().clone(),
            world_from_base,
            finger_reference_m: cell.finger_reference_m,
            obstacles: scenery_obstacles(&cell.scenery, &world_from_base.inverse()),
            belt_top_z: cell.belt_top_z,
            open_clearance_m: scenario.gripper.open_clearance_m,
            speed_fraction: scenario.robot.speed_fraction,
            carry_speed_fraction: scenario.robot.carry_speed_fraction,
            home_q_rad: home,
        }
    }

    /// The collision checker for a pick of `percept`'s part: the cell's obstacles, the part
    /// itself (until the fingers go down around it) and what perception saw near it.
    pub fn checker_for(&self, percept: &Percept) -> CollisionChecker {
        let base_from_world = self.world_from_base.inverse();
        let mut checker = CollisionChecker::new(
            self.model.clone(),
            self.robot_shapes.clone(),
            self.finger_reference_m,
            self.obstacles.clone(),
            PLANNING_MARGIN_M,
        );
        let part_center = Isometry3::from_parts(
            Translation3::new(
                percept.part_xy[0],
                percept.part_xy[1],
                self.belt_top_z + percept.part_height_m / 2.0,
            ),
            UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
        );
        checker.add_obstacle(Obstacle {
            name: PART_OBSTACLE.into(),
            base_from_shape: base_from_world * part_center,
            shape: SharedShape::cylinder(
                (percept.part_height_m / 2.0) as f32,
                percept.part_outer_radius_m as f32,
            ),
        });
        for obstacle in &percept.obstacles {
            checker.add_obstacle(Obstacle {
                name: obstacle.name.into(),
                base_from_shape: base_from_world * obstacle.world_from_shape,
                shape: obstacle.shape.clone(),
            });
        }
        checker
    }

    /// How far the jaws open for `percept`'s part, each pad from the centre line, m.
    pub fn open_offset_m(&self, percept: &Percept) -> f64 {
        percept.part_outer_radius_m + self.open_clearance_m
    }

    /// TCP pose in the arm's base frame: pointing down, fingers along world yaw, at world xyz,
    /// the gripper leaning by `tilt_rad` about its own finger axis (the jaws still close
    /// horizontally; the wrist swings to one side).
    pub(super) fn base_from_tcp(
        &self,
        xyz: Vector3<f64>,
        yaw_rad: f64,
        tilt_rad: f64,
    ) -> Isometry3<f64> {
        let world_from_tcp = Isometry3::from_parts(
            Translation3::from(xyz),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad)
                * UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0)
                * UnitQuaternion::from_euler_angles(tilt_rad, 0.0, 0.0),
        );
        self.world_from_base.inverse() * world_from_tcp
    }

    /// The pick of `percept`'s part from the arm at `q_now` with the most clearance: every
    /// candidate over yaw, lean, approach and IK branch ranked by its smallest clearance to the
    /// obstacles along descent, grasp and lift (see [`GraspSearch`]), the best whose whole
    /// motion passes the planning margin taken.
    pub fn plan_pick(
        &self,
        percept: &Percept,
        checker: &CollisionChecker,
        q_now: &JointVector,
    ) -> Result<PickPlan, Failure> {
        let [x, y] = percept.part_xy;
        let ranking = GraspSearch::new(self, percept, checker, q_now).rank();
        let open = self.open_offset_m(percept);
        self.first_clear_pick(&ranking, checker, open, q_now)
            .map_err(|failure| match failure.reason {
                FailureReason::Unreachable => Failure::new(
                    FailureReason::Unreachable,
                    format!("no IK solution to grasp the part at ({x:.3}, {y:.3})"),
                ),
                _ => failure,
            })
    }

    /// The best of `ranking`'s grasps whose whole approach passes `checker` with the jaws open
    /// `open_m`, from the arm at `q_now`; the object picked is [`PART_OBSTACLE`] in `checker`,
    /// which the fingers may pass on their way down around it. A refusal is `Collision` when
    /// some grasp was reachable, `Unreachable` when none was.
    pub(super) fn first_clear_pick(
        &self,
        ranking: &GraspRanking,
        checker: &CollisionChecker,
        open: f64,
        q_now: &JointVector,
    ) -> Result<PickPlan, Failure> {
        let tried = ranking.candidates;
        let mut last_hit = String::new();
        // Grasps whose blended approach only cut the corner too close to the part, tried
        // again with a stop over the part once no blended one passes.
        let mut corner_cut = Vec::new();
        for grasp in &ranking.grasps {
            if grasp.clearance_m < PLANNING_MARGIN_M {
                if let Some(near) = &grasp.nearest {
                    last_hit = format!(
                        "{} would pass {:.1} mm from {} at yaw {:.0} deg, lean {:.0} deg",
                        near.link,
                        near.distance_m * 1e3,
                        near.obstacle,
                        grasp.pose.yaw_rad.to_degrees(),
                        grasp.pose.tilt_rad.to_degrees(),
                    );
                }
                break;
            }
            let Some(approach) = self.pick_approach(grasp, checker, open, q_now, true) else {
                continue;
            };
            match approach {
                Err(hit) => {
                    if hit.obstacle == PART_OBSTACLE {
                        corner_cut.push(grasp);
                    }
                    last_hit = format!(
                        "{} would hit {} at yaw {:.0} deg",
                        hit.link,
                        hit.obstacle,
                        grasp.pose.yaw_rad.to_degrees()
                    );
                }
                Ok(plan) => {
                    return Ok(PickPlan {
                        candidates: tried,
                        ..plan
                    });
                }
            }
        }
        for grasp in corner_cut {
            if let Some(Ok(plan)) = self.pick_approach(grasp, checker, open, q_now, false) {
                return Ok(PickPlan {
                    candidates: tried,
                    ..plan
                });
            }
        }
        if ranking.reachable {
            fail(
                FailureReason::Collision,
                format!("no grasp clear of the obstacles among {tried} candidates: {last_hit}"),
            )
        } else {
            fail(FailureReason::Unreachable, "no IK solution for any grasp")
        }
    }

    /// `grasp`'s pick from the arm at `q_now`, the move over the part `blended` into the
    /// descent or stopping above it, checked by `checker` with the jaws open `open`: the plan,
    /// or the first hit; `None` when the grasp has no path. The descent starts while a blended
    /// arm still slows down over the part: the fingers leave the straight line only in that
    /// overlap, which is checked against the part too; after it the fingers go down around
    /// the part.
    fn pick_approach(
        &self,
        grasp: &super::ScoredGrasp,
        checker: &CollisionChecker,
        open: f64,
        q_now: &JointVector,
        blended: bool,
    ) -> Option<Result<PickPlan, super::CollisionHit>> {
        let speed = self.speed_fraction;
        let (Some(&q_above), Some(&q_lift)) = (grasp.down.first(), grasp.up.last()) else {
            return None;
        };
        let to_pregrasp = JointTrajectory::through(&self.model, &[*q_now, q_above], speed);
        let descend = JointTrajectory::along(&self.model, grasp.down.clone(), speed);
        let approach = JointTrajectory::join(vec![to_pregrasp, descend], blended);
        let blend_end_s = approach.part_ends_s()[0];
        let down_s = (blend_end_s, approach.duration_s());
        let hit = checker
            .check_span(&approach, down_s, open, None, &[PART_OBSTACLE])
            .or_else(|| checker.check_span(&approach, (0.0, blend_end_s), open, None, &[]));
        Some(match hit {
            Some(hit) => Err(hit),
            None => Ok(PickPlan {
                approach,
                pregrasp: q_above,
                lift_path: grasp.up.clone(),
                lift_end: q_lift,
                clearance_m: grasp.clearance_m,
                candidates: 0,
                tilt_rad: grasp.pose.tilt_rad,
            }),
        })
    }

    /// Height of the TCP above the bottom of a standing tube `part_height_m` tall while the
    /// jaws hold it: [`GRASP_TCP_ABOVE_BOTTOM_M`], or as much higher as keeps the tube's top
    /// [`PALM_CLEARANCE_M`] below the palm. Gripped low, a tube taller than the fingers reach
    /// would be pressed into the belt by the gripper's body (a 100 mm tube under the shipped
    /// gripper, whose palm stands 75 mm above the TCP).
    pub fn grasp_tcp_above_bottom_m(&self, part_height_m: f64) -> f64 {
        let palm_clear = part_height_m + PALM_CLEARANCE_M - self.palm_above_tcp_m();
        GRASP_TCP_ABOVE_BOTTOM_M.max(palm_clear)
    }

    /// `percept`'s part as the jaws carry it: a cylinder standing in the TCP frame, its
    /// bottom the grasp height below the TCP.
    pub fn carried_for(&self, percept: &Percept) -> Carried {
        let above_bottom = self.grasp_tcp_above_bottom_m(percept.part_height_m);
        Carried {
            tcp_from_shape: Isometry3::from_parts(
                Translation3::new(0.0, 0.0, -(percept.part_height_m / 2.0 - above_bottom)),
                UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            ),
            shape: SharedShape::cylinder(
                (percept.part_height_m / 2.0) as f32,
                percept.part_outer_radius_m as f32,
            ),
        }
    }

    /// The first collision-free place of `percept`'s part into `bin`'s next free slot (after
    /// `placed_before` parts), lifted along `pick`'s lift and carried within what the grip on
    /// `payload` holds.
    pub fn plan_place(
        &self,
        percept: &Percept,
        bin: &BinBody,
        placed_before: usize,
        pick: &PickPlan,
        payload: &Payload,
        checker: &CollisionChecker,
    ) -> Result<PlacePlan, Failure> {
        let floor = bin.floor_center + bin_slot(bin, placed_before);
        let above_bottom = self.grasp_tcp_above_bottom_m(percept.part_height_m);
        let place_z = floor.z + 0.012 + above_bottom;
        let above_z = floor.z + bin.wall_height + 0.04 + above_bottom;
        let carried = self.carried_for(percept);
        let spot = PlaceSpot {
            xy: [floor.x, floor.y],
            above_z,
            place_z,
            bin_name: &bin.name,
            clear_of: &[],
            yaws_deg: None,
            tilt_rad: 0.0,
        };
        let grip = percept.part_outer_radius_m;
        let open = self.open_offset_m(percept);
        let limits = payload.tool_limits();
        // A part gripped with the tool leaning stands at that lean to the tool: set down with
        // the tool pointing straight down it meets the floor leaning. A tube leaning further
        // than its diameter over its height lets its centre of mass pass its edge and falls
        // over in the bin (then lies across the next slot): such a part is set down with the
        // same lean, standing, where that place is clear. One that rights itself on the floor
        // is set down as before.
        let tips_over =
            pick.tilt_rad.abs() > (2.0 * percept.part_outer_radius_m).atan2(percept.part_height_m);
        if tips_over {
            let upright = PlaceSpot {
                tilt_rad: pick.tilt_rad,
                ..spot
            };
            let leaning = carried.leaning(pick.tilt_rad);
            let place =
                self.place_carried(&leaning, (grip, open), &upright, pick, &limits, checker);
            if place.is_ok() {
                return place;
            }
        }
        self.place_carried(&carried, (grip, open), &spot, pick, &limits, checker)
    }

    /// The first collision-free place of `carried`, held with the pads `grip_m` from the
    /// centre line and released to `open_m`, down to `spot`, lifted along `pick`'s lift and
    /// carried within `grip_limits` (what the grip holds).
    pub(super) fn place_carried(
        &self,
        carried: &Carried,
        (grip, open): (f64, f64),
        spot: &PlaceSpot<'_>,
        pick: &PickPlan,
        grip_limits: &ToolLimits,
        checker: &CollisionChecker,
    ) -> Result<PlacePlan, Failure> {
        let q_start = &pick.lift_end;
        let grip_limits = *grip_limits;
        let [floor_x, floor_y] = spot.xy;
        let (above_z, place_z) = (spot.above_z, spot.place_z);
        let speed = self.speed_fraction;
        let carry = self.carry_speed_fraction;
        let mut reachable = false;
        let mut last_hit = String::new();
        // The lift off the belt is the same whatever the place: timed once.
        let lift = JointTrajectory::along(&self.model, pick.lift_path.clone(), carry)
            .with_tool_limits(&self.model, &grip_limits);
        for &yaw_deg in spot.yaws_deg.unwrap_or(&PLACE_YAWS_DEG) {
            let yaw = f64::to_radians(yaw_deg);
            let tilt = spot.tilt_rad;
            let above = self.base_from_tcp(Vector3::new(floor_x, floor_y, above_z), yaw, tilt);
            let at = self.base_from_tcp(Vector3::new(floor_x, floor_y, place_z), yaw, tilt);
            if !released_clear(carried, &at, spot.clear_of) {
                last_hit = format!(
                    "the carried body would land on what is in bin {}",
                    spot.bin_name
                );
                continue;
            }
            for q_above in self.ik.solve(&above).by_distance_from(q_start) {
                let Some(down) = straight_line(&self.ik, &above, &at, &q_above, LINE_STEP_M) else {
                    continue;
                };
                let mut up = down.clone();
                up.reverse();
                reachable = true;
                let ignore = [PART_OBSTACLE];
                let lower = JointTrajectory::along(&self.model, down, carry)
                    .with_tool_limits(&self.model, &grip_limits);
                // The way down into the bin first: where it hits, the carry there is not timed.
                let placing_hit = |hit: super::CollisionHit| {
                    format!(
                        "{} would hit {} placing at yaw {yaw_deg} deg",
                        hit.link, hit.obstacle
                    )
                };
                if let Some(hit) = checker.check_trajectory(&lower, grip, Some(carried), &ignore) {
                    last_hit = placing_hit(hit);
                    continue;
                }
                let lift = lift.clone();
                let transport = JointTrajectory::through(&self.model, &[*q_start, q_above], carry)
                    .with_tool_limits(&self.model, &grip_limits);
                // The carry limit holds for the blended whole: the slow-down of the lift and
                // the start over to the bin add up at the TCP.
                let carry_move = JointTrajectory::join(vec![lift, transport], true)
                    .within_tool_limits(&self.model, &grip_limits);
                let retreat = JointTrajectory::join(
                    vec![
                        JointTrajectory::along(&self.model, up, speed),
                        JointTrajectory::through(&self.model, &[q_above, self.home_q_rad], speed),
                    ],
                    true,
                );
                // From where the move over to the bin starts: before that the part rises
                // straight off the belt it stands on.
                let over_s = (carry_move.part_starts_s()[1], carry_move.duration_s());
                let hit = checker
                    .check_span(&carry_move, over_s, grip, Some(carried), &ignore)
                    .or_else(|| checker.check_trajectory(&retreat, open, None, &ignore));
                match hit {
                    Some(hit) => last_hit = placing_hit(hit),
                    None => {
                        return Ok(PlacePlan {
                            carry: carry_move,
                            lower,
                            retreat,
                        });
                    }
                }
            }
        }
        if reachable {
            fail(FailureReason::Collision, last_hit)
        } else {
            fail(
                FailureReason::Unreachable,
                format!("bin {} is out of reach", spot.bin_name),
            )
        }
    }
}

/// Drops from `percept` what can only be its part seen a second time: an "other part" that
/// would pass through the part, its axis nearer the part's than their two radii less
/// `SECOND_LOOK_SLACK_M` (two upright tubes cannot stand inside each other). Such a box,
/// drawn over the part's side or over the part and a bottle beside it from a tilted camera, is
/// placed 20-30 mm off the part with some type's radius and would stand in the jaws' way. A
/// tube beside the part, touching it or a few millimetres into it as placed, is kept.
pub fn drop_second_looks(percept: &mut Percept) {
    let [px, py] = percept.part_xy;
    let part_r = percept.part_outer_radius_m;
    percept.obstacles.retain(|o| {
        let c = o.world_from_shape.translation.vector;
        let other_r = o.shape.as_cylinder().map_or(0.0, |c| f64::from(c.radius));
        o.name != OTHER_PART || (c.x - px).hypot(c.y - py) >= part_r + other_r - SECOND_LOOK_SLACK_M
    });
}

/// How far another tube's box may place it into the part before it is taken for the part seen
/// again, m: a neighbour placed from its box may come this much too near.
const SECOND_LOOK_SLACK_M: f64 = 0.008;

/// Where in a bin the next part goes after `placed_before` others, from the floor's centre: the
/// centre first; then the next free cell of a grid at BIN_SLOT_PITCH_M, nearest the centre
/// first, so parts stand side by side rather than on top of each other.
pub fn bin_slot(bin: &BinBody, placed_before: usize) -> Vector3<f64> {
    if placed_before == 0 {
        return Vector3::zeros();
    }
    let per_side = |size: f64| {
        ((size - BIN_SLOT_PITCH_M) / BIN_SLOT_PITCH_M)
            .floor()
            .max(0.0) as usize
            + 1
    };
    let (nx, ny) = (per_side(bin.size[0]), per_side(bin.size[1]));
    let mut slots: Vec<Vector3<f64>> = (0..nx * ny)
        .map(|k| {
            let offset =
                |i: usize, n: usize| (i as f64 - (n as f64 - 1.0) / 2.0) * BIN_SLOT_PITCH_M;
            Vector3::new(offset(k % nx, nx), offset(k / nx, ny), 0.0)
        })
        .collect();
    slots.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
    slots[placed_before % slots.len()]
}

/// Whether `carried`, let go with the TCP at `base_from_tcp`, keeps [`RELEASE_CLEARANCE_M`]
/// from each of `in_bin`.
fn released_clear(carried: &Carried, base_from_tcp: &Isometry3<f64>, in_bin: &[Obstacle]) -> bool {
    let pose = crate::math::pose_to_physics(&(base_from_tcp * carried.tcp_from_shape));
    in_bin.iter().all(|o| {
        let other = crate::math::pose_to_physics(&o.base_from_shape);
        rapier3d::parry::query::distance(&pose, carried.shape.as_ref(), &other, o.shape.as_ref())
            .is_ok_and(|d| f64::from(d.distance) > RELEASE_CLEARANCE_M)
    })
}
