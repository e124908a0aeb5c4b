//! Where a tracked part is met along the belt and how it is lifted from there and placed
//! (conveyor tracking): the intercept's pick, the standing limit past which a part held on a
//! stopped belt could no longer be picked, and the lift and place planned for where the belt
//! carries the part.

use super::belt_follow::Latched;
use super::cell_data::CellData;
use super::pick_cycle::{GRIP_BUILD_S, decide};
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::outcome::{Failure, FailureReason};
use crate::planning::{InterceptProblem, Payload, PickPlan, PlacePlan};
use crate::scenario::BinId;
use crate::sim::JAW_SPEED_M_S;
use crate::station::Percept;

/// Time allowed for the lift when checking that the arm still reaches where the belt will
/// have carried the part by the lift's end, s (a lift takes 0.2-0.3 s).
const LIFT_ALLOWANCE_S: f64 = 0.6;

/// Where and when the arm meets a part, and the pick planned for it there.
pub(super) struct Meet {
    /// The place along the belt (world x), m.
    pub(super) x_m: f64,
    /// When the part gets there, s from the planning.
    pub(super) meet_s: f64,
    /// How long the arm waits before it sets off, s.
    pub(super) wait_s: f64,
    /// The belt's speed the meet is planned for, m/s (0: the part stands on a held belt).
    pub(super) speed_m_s: f64,
    pub(super) pick: PickPlan,
}

/// `percept` moved `dx_m` along the belt, with everything it saw near the part.
pub(super) fn shifted(percept: &Percept, dx_m: f64) -> Percept {
    let mut moved = percept.clone();
    moved.part_xy[0] += dx_m;
    for obstacle in &mut moved.obstacles {
        obstacle.world_from_shape.translation.vector.x += dx_m;
    }
    moved
}

impl Sorter<'_> {
    /// Where to meet `item`'s part: the place along the belt, how long the arm waits before
    /// it sets off, and the pick planned for the part there. `None`: it cannot be met.
    /// `speed_m_s` is the belt's (0: it stands held).
    pub(super) fn plan_intercept(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        window: (f64, f64),
        speed_m_s: f64,
    ) -> Option<Meet> {
        let pick_at = |x: f64| self.tracked_pick_at(model, data, item, x, speed_m_s);
        let problem = InterceptProblem {
            part_now_m: item.x_at(data.belt.encoder_counts()),
            speed_m_s,
            window_m: window,
        };
        let meet = problem.solve(|x| pick_at(x).map(|(t, _)| t))?;
        let (_, pick) = pick_at(meet.at_m)?;
        Some(Meet {
            x_m: meet.at_m,
            meet_s: meet.meet_s,
            wait_s: (meet.meet_s - meet.arrival_s).max(0.0),
            speed_m_s,
            pick,
        })
    }

    /// The standing limit of `item`'s part: the last place in `window` at which the arm can
    /// pick it from a stopped belt (a held belt must stop it there or before), or `None` where
    /// it can nowhere.
    pub(super) fn standing_limit(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        window: (f64, f64),
    ) -> Option<f64> {
        let reachable = |x: f64| self.tracked_pick_at(model, data, item, x, 0.0).is_some();
        crate::planning::last_reachable(window, reachable)
    }

    /// The pick of `item`'s part met at `x` along the belt running at `speed`, with the arm's
    /// time to be ready over it, when the whole pick (the lift's end, then the place into its
    /// bin) can be planned.
    fn tracked_pick_at(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        x: f64,
        speed: f64,
    ) -> Option<(f64, PickPlan)> {
        let bin = decide(model, &item.percept).1;
        let planner = &self.planner;
        let x_latch = item.percept.part_xy[0];
        {
            let percept = shifted(&item.percept, x - x_latch);
            let checker = planner.checker_for(&percept);
            let pick = planner.plan_pick(&percept, &checker, &data.q).ok()?;
            let split = pick.approach.part_starts_s().get(1).copied()?;
            // The arm must still reach where the belt carries the part by the lift's end: the
            // whole lift (from the grasp pose up), moved by the travel during the descent,
            // the jaws' closing and the lift.
            let close_s = planner.open_offset_m(&percept) / JAW_SPEED_M_S + GRIP_BUILD_S;
            let follow_s = pick.approach.duration_s() - split + close_s + LIFT_ALLOWANCE_S;
            match bin {
                Some(bin) => {
                    let lift_x = x + speed * follow_s;
                    self.place_at(model, data, item, (&pick, x), lift_x, bin)
                        .ok()?;
                }
                None => {
                    let mut near = pick.lift_path.first().copied()?;
                    for q in &pick.lift_path {
                        near = self.shifted_ik(q, speed * follow_s, &near).ok()?;
                    }
                }
            }
            Some((split, pick))
        }
    }

    /// The lift from the grasp, planned for the part where the belt will have carried it when
    /// the lift ends (found in two rounds: the lift's time depends a little on where it is),
    /// with the place that follows: the lift's place along the belt, and the place plan.
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
        let mut lift_s = 0.5;
        let mut planned = None;
        for _ in 0..3 {
            let lift_x = x_now + speed * lift_s;
            let place = self.place_at(model, data, item, (pick, meet_x), lift_x, bin)?;
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
    fn place_at(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        (pick, meet_x): (&PickPlan, f64),
        lift_x: f64,
        bin: BinId,
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
        };
        let percept = shifted(&item.percept, lift_x - item.percept.part_xy[0]);
        let checker = planner.checker_for(&percept);
        let payload = Payload {
            mass_kg: model.catalogue().part(percept.part_type).mass_kg(),
            grip_force_n: self.grip_recipe_n,
            pad_friction: model.scenario().gripper.pad_friction,
        };
        let bin_body = &data.cell.bins[bin.0];
        let placed_before = data.bin_fill[bin.0];
        planner.plan_place(
            &percept,
            bin_body,
            placed_before,
            &lifted,
            &payload,
            &checker,
        )
    }
}
