//! Where a tracked part is met along the belt and how it is lifted from there and placed
//! (conveyor tracking): the meet on the moving belt (`planning::InterceptProblem`), the pick
//! of a part standing on a held belt, the standing limit (the last place along the window at
//! which a part on a stopped belt can still be picked and placed), and the lift and place
//! planned for where the belt carries the part.

use super::belt_follow::Latched;
use super::cell_data::CellData;
use super::pick_cycle::{GRIP_BUILD_S, decide};
use super::sorter::Sorter;
use crate::cell::BinBody;
use crate::cell::CellModel;
use crate::control::ENCODER_M_PER_COUNT;
use crate::kinematics::JointVector;
use crate::outcome::{Failure, FailureReason};
use crate::planning::{
    InterceptProblem, JointTrajectory, PART_OBSTACLE, Payload, PickPlan, PlacePlan, ToolLimits,
    bin_slot,
};
use crate::scenario::BinId;
use crate::sim::JAW_SPEED_M_S;
use crate::station::{PerceivedObstacle, Percept};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::geometry::SharedShape;

/// Time allowed for the lift when checking that the arm still reaches where the belt will
/// have carried the part by the lift's end, s (a lift takes 0.2-0.3 s).
const LIFT_ALLOWANCE_S: f64 = 0.6;
/// Step of the walk back along the window for the standing limit, m.
const STANDING_STEP_M: f64 = 0.03;
/// The tool's speed cap over to the bin, m/s, at every point of the path (the joints' own
/// limits and the grip's acceleration limit apply too; the hold monitor watches the part). At
/// 1.0 m/s three of the 40 streams of the belt speed and spacing sweep let a part slide 25 mm
/// in the jaws or lose it; at 0.925 none did (docs/conveyor_tracking.md).
const TRACKING_CARRY_SPEED_M_S: f64 = 0.925;
/// The most of the joints' limits the move over to the bin uses: with the tool's cap raised the
/// joints bind, and the simulated servos overshoot a step in acceleration by several per cent
/// (at the scenario's 0.85 a joint was measured at 1.001 of its limit).
const TRACKING_CARRY_JOINT_FRACTION: f64 = 0.8;

/// Where and when the arm meets a part, and the pick planned for it there.
pub(super) struct Meet {
    /// The place along the belt (world x), m.
    pub(super) x_m: f64,
    /// How long the arm waits before it sets off, s.
    pub(super) wait_s: f64,
    /// From the planning to the lift's end (allowing [`LIFT_ALLOWANCE_S`] for the lift), s.
    pub(super) lift_end_s: f64,
    /// The belt's speed the meet is planned for, m/s (0: the part stands on a held belt).
    pub(super) speed_m_s: f64,
    pub(super) pick: PickPlan,
}

/// `percept` moved `dx_m` along the belt, with everything it saw near the part.
fn shifted(percept: &Percept, dx_m: f64) -> Percept {
    let mut moved = percept.clone();
    moved.part_xy[0] += dx_m;
    for obstacle in &mut moved.obstacles {
        obstacle.world_from_shape.translation.vector.x += dx_m;
    }
    moved
}

/// A pick planned at a place along the belt: the arm's time to the start of its descent, the
/// time from there to the lift's end, and the plan.
struct PickAt {
    arrival_s: f64,
    follow_s: f64,
    pick: PickPlan,
}

impl Sorter<'_> {
    /// Where to meet `item`'s part on the belt running at `speed_m_s`: the place along the
    /// belt, how long the arm waits before it sets off, and the pick planned for the part
    /// there. `None`: it cannot be met in `window`.
    pub(super) fn plan_intercept(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        window: (f64, f64),
        speed_m_s: f64,
    ) -> Option<Meet> {
        let problem = InterceptProblem {
            part_now_m: item.x_at(data.belt.encoder_counts()),
            speed_m_s,
            window_m: window,
        };
        // A place the arm gets to after the part needs no lift and place planned there: it is
        // late whatever they are. The last place found in time is kept for the meet.
        let mut in_time: Option<(f64, PickAt)> = None;
        let meet = problem.solve(|x| {
            let deadline_s = problem.part_at_s(x);
            let at = self.tracked_pick_at(model, data, item, x, speed_m_s, &data.q, deadline_s)?;
            let arrival_s = at.arrival_s;
            if arrival_s <= deadline_s {
                in_time = Some((x, at));
            }
            Some(arrival_s)
        })?;
        let at = match in_time {
            Some((x, at)) if x == meet.at_m => at,
            _ => {
                let q = &data.q;
                self.tracked_pick_at(model, data, item, meet.at_m, speed_m_s, q, f64::INFINITY)?
            }
        };
        Some(Meet {
            x_m: meet.at_m,
            wait_s: (meet.meet_s - meet.arrival_s).max(0.0),
            lift_end_s: meet.meet_s.max(at.arrival_s) + at.follow_s,
            speed_m_s,
            pick: at.pick,
        })
    }

    /// The pick of `item`'s part where it stands on the stopped belt, when it has not passed
    /// `window`'s end and the whole pick (with the place into its bin) can be planned there.
    pub(super) fn plan_standing(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        window: (f64, f64),
    ) -> Option<Meet> {
        // (A part just latched may stand a little short of the eye: picked there all the same.)
        let x = item.x_at(data.belt.encoder_counts());
        if x > window.1 {
            return None;
        }
        let at = self.tracked_pick_at(model, data, item, x, 0.0, &data.q, f64::INFINITY)?;
        Some(Meet {
            x_m: x,
            wait_s: 0.0,
            lift_end_s: at.arrival_s + at.follow_s,
            speed_m_s: 0.0,
            pick: at.pick,
        })
    }

    /// The standing limit of `item`'s part: the last place in `window`, walking back from its
    /// end a grid step at a time, at which the arm can pick the part from a stopped belt and
    /// place it (a belt held for the part must stop it there or before); `None` where it can
    /// nowhere downstream of where the part is now. The pick is planned from home, where the
    /// arm can always go first.
    pub(super) fn standing_limit(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        window: (f64, f64),
    ) -> Option<f64> {
        let from = window.0.max(item.x_at(data.belt.encoder_counts()));
        // From home: the arm, wherever it is now, can go there first.
        let home = &self.planner.home_q_rad;
        let mut x = window.1;
        while x >= from {
            if self
                .tracked_pick_at(model, data, item, x, 0.0, home, f64::INFINITY)
                .is_some()
            {
                return Some(x);
            }
            x -= STANDING_STEP_M;
        }
        None
    }

    /// The pick of `item`'s part met at `x` along the belt running at `speed`, the arm setting
    /// off from `q_from`, when the whole pick can be planned: the lift's end moved with the
    /// belt, then the place into its bin (or, for a part with no bin, the whole lift within
    /// reach). An arm that gets over `x` later than `deadline_s` is late there whatever comes
    /// after: the pick is given without the lift and place checked.
    #[allow(clippy::too_many_arguments)]
    fn tracked_pick_at(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        x: f64,
        speed: f64,
        q_from: &JointVector,
        deadline_s: f64,
    ) -> Option<PickAt> {
        let bin = decide(model, &item.percept).1;
        let planner = &self.planner;
        let mut percept = shifted(&item.percept, x - item.percept.part_xy[0]);
        self.add_tracked(model, data, item, x, &mut percept);
        // The way over from a bin must not sweep through what the arm placed there.
        for (bin_body, &placed) in data.cell.bins.iter().zip(&data.bin_fill) {
            percept.obstacles.extend(placed_in(model, bin_body, placed));
        }
        let checker = planner.checker_for(&percept);
        let pick = planner.plan_pick(&percept, &checker, q_from).ok()?;
        let split = pick.approach.part_starts_s().get(1).copied()?;
        // The arm must still reach where the belt carries the part by the lift's end: the
        // whole lift (from the grasp pose up), moved by the travel during the descent, the
        // jaws' closing and the lift.
        let close_s = planner.open_offset_m(&percept) / JAW_SPEED_M_S + GRIP_BUILD_S;
        let follow_s = pick.approach.duration_s() - split + close_s + LIFT_ALLOWANCE_S;
        if split > deadline_s {
            return Some(PickAt {
                arrival_s: split,
                follow_s,
                pick,
            });
        }
        let mut near = pick.lift_path.first().copied()?;
        for q in &pick.lift_path {
            near = self.shifted_ik(q, speed * follow_s, &near).ok()?;
        }
        if let Some(bin) = bin {
            // The lift and place as they will be planned once the jaws hold, from where the
            // belt will have carried the part by then.
            let grasped_x = x + speed * (follow_s - LIFT_ALLOWANCE_S);
            let from = (&pick, x);
            self.lift_and_place_from(model, data, item, from, grasped_x, bin, speed, false)
                .ok()?;
        }
        Some(PickAt {
            arrival_s: split,
            follow_s,
            pick,
        })
    }

    /// Adds to `percept` (`item`'s part met at `x` along the belt) what the tracks hold on the
    /// belt that it does not, where the encoder will have carried it by the meet: the latch's
    /// look saw the part's neighbours then, not what came into view since, and the arm's way
    /// down to a part near the window's start passes over the belt behind it (a 100 mm tube
    /// there was knocked over). They join the part's neighbours: the pick is checked against
    /// them, and its approach and lift clear their tops (`planning::GraspSearch`). Checked
    /// against alone, with the approach as low as the part's own neighbours allow, the planner
    /// found no way down to more parts (a user's stream, 13 of 16 streams whole against 16).
    fn add_tracked(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        x: f64,
        percept: &mut Percept,
    ) {
        let Some(tracking) = &self.tracking else {
            return;
        };
        let now = data.belt.encoder_counts();
        let meet = now + ((x - item.x_at(now)) / ENCODER_M_PER_COUNT).round() as i64;
        tracking.add_tracked_bottles(model, meet, percept);
        tracking.add_tracked_parts(model, meet, percept, item.track);
    }

    /// The lift from the grasp, planned for the part where the belt (at `speed`) will have
    /// carried it when the lift ends (found in rounds: the lift's time depends a little on
    /// where it is), with the place that follows: the lift's place along the belt, and the
    /// place plan.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn plan_lift_and_place(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        pick: &PickPlan,
        meet_x: f64,
        bin: BinId,
        speed: f64,
    ) -> Result<(f64, PlacePlan), Failure> {
        let x_now = item.x_at(data.belt.encoder_counts());
        self.lift_and_place_from(model, data, item, (pick, meet_x), x_now, bin, speed, true)
    }

    /// [`Self::plan_lift_and_place`] for the part at `x_now` along the belt; `fast`: the
    /// transport timed with the tool's speed cap along its path (see [`Self::place_at`]).
    #[allow(clippy::too_many_arguments)]
    fn lift_and_place_from(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        (pick, meet_x): (&PickPlan, f64),
        x_now: f64,
        bin: BinId,
        speed: f64,
        fast: bool,
    ) -> Result<(f64, PlacePlan), Failure> {
        let mut lift_s = 0.5;
        let mut planned = None;
        for _ in 0..3 {
            let lift_x = x_now + speed * lift_s;
            let place = self.place_at(model, data, item, (pick, meet_x), lift_x, bin, fast)?;
            let new_lift_s = place.carry.part_starts_s().get(1).copied().unwrap_or(0.0);
            let settled = (new_lift_s - lift_s).abs() * speed < 0.000_2;
            lift_s = new_lift_s;
            planned = Some((lift_x, place));
            if settled {
                break;
            }
        }
        planned.ok_or_else(|| Failure::new(FailureReason::Panic, "no lift planned"))
    }

    /// The place of `item`'s part into `bin` after a lift from the grasp of `pick` (planned
    /// for the part at `meet_x`) moved to where the part stands at `lift_x` along the belt.
    /// `fast`: the move over to the bin timed with the carry's tool speed cap at every point of
    /// its path rather than at its peak (`JointTrajectory::along_tool_speed`; the same joint
    /// path, checked again with the part in the jaws), when that is quicker and clear.
    #[allow(clippy::too_many_arguments)]
    fn place_at(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        (pick, meet_x): (&PickPlan, f64),
        lift_x: f64,
        bin: BinId,
        fast: bool,
    ) -> Result<PlacePlan, Failure> {
        let planner = &self.planner;
        let dx = lift_x - meet_x;
        let mut path = Vec::with_capacity(pick.lift_path.len());
        let mut near = pick.lift_path.first().copied().unwrap_or(pick.lift_end);
        for q in &pick.lift_path {
            near = self.shifted_ik(q, dx, &near)?;
            path.push(near);
        }
        let lifted = PickPlan {
            approach: pick.approach.clone(),
            pregrasp: pick.pregrasp,
            lift_end: path.last().copied().unwrap_or(near),
            lift_path: path,
            clearance_m: pick.clearance_m,
            candidates: pick.candidates,
            tilt_rad: pick.tilt_rad,
        };
        let mut percept = shifted(&item.percept, lift_x - item.percept.part_xy[0]);
        let bin_body = &data.cell.bins[bin.0];
        let placed_before = data.bin_fill[bin.0];
        percept
            .obstacles
            .extend(placed_in(model, bin_body, placed_before));
        let checker = planner.checker_for(&percept);
        let payload = Payload {
            mass_kg: model.catalogue().part(percept.part_type).mass_kg(),
            grip_force_n: model.catalogue().part(percept.part_type).grip_force_n,
            pad_friction: model.scenario().gripper.pad_friction,
        };
        let mut place = planner.plan_place(
            &percept,
            bin_body,
            placed_before,
            &lifted,
            &payload,
            &checker,
        )?;
        if fast && let Some(q_above) = place.lower.start() {
            let limits = ToolLimits {
                speed_m_s: TRACKING_CARRY_SPEED_M_S,
                ..payload.tool_limits()
            };
            let (arm, fraction) = (&planner.model, planner.carry_speed_fraction);
            let lift = JointTrajectory::along(arm, lifted.lift_path.clone(), fraction)
                .with_tool_limits(arm, &limits);
            let path = vec![lifted.lift_end, q_above];
            let joints = fraction.min(TRACKING_CARRY_JOINT_FRACTION);
            let transport = JointTrajectory::along_tool_speed(arm, path, joints, &limits);
            let carry =
                JointTrajectory::join(vec![lift, transport], true).within_tool_limits(arm, &limits);
            let over_s = (carry.part_starts_s()[1], carry.duration_s());
            let carried = planner.carried_for(&percept).leaning(lifted.tilt_rad);
            let grip = percept.part_outer_radius_m;
            let hit = checker.check_span(&carry, over_s, grip, Some(&carried), &[PART_OBSTACLE]);
            if hit.is_none() && carry.duration_s() < place.carry.duration_s() {
                place.carry = carry;
            }
        }
        Ok(place)
    }
}

/// The parts this stream has placed in `bin` (`placed` of them), where the cell put them: each
/// a standing cylinder in its slot, as large as the scenario's largest part type (the cell
/// places by the slot; what it placed may have settled a little).
fn placed_in(model: &CellModel, bin: &BinBody, placed: usize) -> Vec<PerceivedObstacle> {
    let types = &model.scenario().part_types;
    let radius_m = types
        .iter()
        .map(|t| t.outer_diameter_mm / 2000.0)
        .fold(0.0, f64::max);
    let height_m = types
        .iter()
        .map(|t| t.height_mm / 1000.0)
        .fold(0.0, f64::max);
    (0..placed)
        .map(|i| {
            let at = bin.floor_center + bin_slot(bin, i) + Vector3::new(0.0, 0.0, height_m / 2.0);
            PerceivedObstacle {
                name: "part placed before",
                world_from_shape: Isometry3::from_parts(
                    Translation3::from(at),
                    UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
                ),
                shape: SharedShape::cylinder((height_m / 2.0) as f32, radius_m as f32),
                top_z: at.z + height_m / 2.0,
            }
        })
        .collect()
}
