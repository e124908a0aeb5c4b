//! One pick cycle on the part at the photo-eye, as a state machine over [`Phase`]: perceive,
//! plan, approach, descend, grasp, lift, transport, place, release, retreat; then judged.

use std::time::Instant;

use super::cell_data::CellData;
use super::judge;
use super::motion_stages::Held;
use super::sorter::Sorter;
use super::tracking::BeltTracking;
use crate::cell::CellModel;
use crate::control::HoldMonitor;
use crate::outcome::{
    DecisionRecord, Failure, FailureReason, GraspRecord, PartRecord, PassedRecord, Phase, fail,
};
use crate::planning::{JointTrajectory, Payload, PickPlan, PlacePlan, drop_second_looks};
use crate::scenario::{BinId, UNIDENTIFIED};
use crate::sim::JAW_SPEED_M_S;
use crate::station::{Percept, Sighting};

/// Time for the grip force to build once the drive reaches its end, s.
pub(crate) const GRIP_BUILD_S: f64 = 0.1;
/// Force with which the jaws open, N.
pub(crate) const OPEN_FORCE_N: f64 = 40.0;
/// Rest after a motion that ends where the jaws act (at the grasp, in the bin), s: the stiff
/// servos (1000 rad/s) close their last tracking error within a few steps.
pub(super) const STOP_SETTLE_S: f64 = 0.02;
/// Extra opening time once the pads have cleared the part, s.
pub(crate) const RELEASE_MARGIN_S: f64 = 0.02;

/// What one pick cycle did to its part.
pub(crate) struct Cycle {
    pub(crate) part: PartRecord,
    pub(crate) decision: Option<DecisionRecord>,
    pub(crate) placed_bin: Option<String>,
    pub(crate) placed_bin_id: Option<BinId>,
    pub(crate) failure: Option<Failure>,
    pub(crate) touched: bool,
    pub(crate) picked: bool,
    pub(crate) displacement_m: f64,
    pub(crate) cycle_time_s: f64,
    pub(crate) grasp: Option<GraspRecord>,
    /// Why the part was let through to the collector, when it was.
    pub(crate) passed: Option<PassedRecord>,
}

/// What the cycle carries from one phase to the next.
#[derive(Default)]
struct CycleState {
    percept: Option<Percept>,
    bin: Option<BinId>,
    pick: Option<PickPlan>,
    place: Option<PlacePlan>,
    hold: Option<HoldMonitor>,
}

impl Sorter<'_> {
    /// The truth about the part being handled.
    pub(crate) fn part_record(&self, model: &CellModel, data: &CellData) -> PartRecord {
        let part = &data.cell.items.parts()[self.current].instance;
        judge::part_record(model.scenario(), model.catalogue(), part)
    }

    /// A part that never reached the pick station.
    pub(crate) fn unreached(&self, model: &CellModel, data: &CellData, failure: Failure) -> Cycle {
        Cycle {
            part: self.part_record(model, data),
            decision: None,
            placed_bin: None,
            placed_bin_id: None,
            failure: Some(failure),
            touched: false,
            picked: false,
            displacement_m: 0.0,
            cycle_time_s: 0.0,
            grasp: None,
            passed: None,
        }
    }

    /// One pick cycle on the part at the photo-eye (the belt stopped), then judged against the
    /// truth. `seen` is the camera's look at the station when one was already taken.
    pub(crate) fn pick_cycle(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        seen: Option<Sighting>,
    ) -> Cycle {
        let (scenario, catalogue) = (model.scenario(), model.catalogue());
        data.touch_phase = None;
        data.faults.cycles += 1;
        let part = self.part_record(model, data);
        let (mut decision, mut grasp) = (None, None);
        let result = self.run_cycle(model, data, seen, &mut decision, &mut grasp);
        let (result, let_through) = self.let_through_if_refused(model, data, result);
        let (passed, moved_before_m) = let_through.unzip();
        let evidence = data.cycle_evidence(self.current);
        let placed_bin_id = evidence.placed_bin;
        let (failure, touched) = match &passed {
            // The belt carried the bottles on with the part: only the robot's touch counts.
            Some(_) => (
                judge::judge_pass(result, &evidence),
                evidence.touch_phase.is_some(),
            ),
            None => (
                judge::judge_cycle(scenario, catalogue, &part, result, &evidence),
                evidence.bottle_disturbed(scenario),
            ),
        };
        let picked = evidence.bottle_lifted;
        // A part let through: the bottles' move before the belt carried them on with it.
        let displacement_m = moved_before_m.unwrap_or(evidence.bottle_displacement_m);
        Cycle {
            part,
            decision,
            placed_bin: placed_bin_id.map(|b| catalogue.bin_name(b).to_owned()),
            placed_bin_id,
            failure,
            touched,
            picked,
            displacement_m,
            cycle_time_s: self
                .pick_time_s
                .map_or(0.0, |t| data.cell.world.time_s() - t),
            grasp,
            passed,
        }
    }

    /// Steps the cycle's phases in order until the arm is home or one fails; `decision` is filled
    /// once perception has decided, `chosen` once the pick is planned.
    fn run_cycle(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        seen: Option<Sighting>,
        decision: &mut Option<DecisionRecord>,
        chosen: &mut Option<GraspRecord>,
    ) -> Result<(), Failure> {
        let catalogue = model.catalogue();
        let mut state = CycleState::default();
        let mut seen = seen;
        let mut phase = Phase::Perceive;
        let mut removals = 0;
        loop {
            data.phase = phase;
            match phase {
                Phase::Perceive => {
                    let mut percept = self.perceive(model, data, seen.take())?;
                    // The part detected twice is no obstacle to its own pick.
                    drop_second_looks(&mut percept);
                    // A stream's bottles carried on out of the view are still on the belt.
                    if let Some(tracking) = &self.tracking {
                        let count = BeltTracking::count(data);
                        tracking.add_tracked_bottles(model, count, &mut percept);
                    }
                    let (recorded, bin) = decide(model, &percept);
                    *decision = Some(recorded);
                    self.grip_recipe_n = catalogue.part(percept.part_type).grip_force_n;
                    state.bin = bin;
                    state.percept = Some(percept);
                }
                Phase::Plan => {
                    let started = Instant::now();
                    let planned = self.plan(model, data, &state);
                    data.timing.planning_ms += started.elapsed().as_secs_f64() * 1e3;
                    let (pick, place) = match (planned, &state.percept) {
                        (Err(refusal), Some(percept))
                            if Self::may_remove(model, &refusal, removals) =>
                        {
                            if !self.remove_blocker(model, data, percept)? {
                                // The arm is home again: the refusal stands, from planning.
                                data.phase = Phase::Plan;
                                return Err(refusal);
                            }
                            // A fresh look at the station once the bottle is gone.
                            removals += 1;
                            phase = Phase::Perceive;
                            continue;
                        }
                        (planned, _) => planned?,
                    };
                    *chosen = Some(GraspRecord {
                        clearance_mm: pick.clearance_m * 1e3,
                        candidates: u32::try_from(pick.candidates).unwrap_or(u32::MAX),
                    });
                    if !model.scenario().faults.is_empty()
                        && let Some(percept) = &state.percept
                    {
                        // Kept for checking the motions again after a fault.
                        data.faults.checker = Some(self.planner.checker_for(percept));
                        data.faults.carried = Some(self.planner.carried_for(percept));
                        data.faults.pregrasp_q = Some(pick.pregrasp);
                    }
                    state.pick = Some(pick);
                    state.place = Some(place);
                }
                Phase::Approach | Phase::Descend => {
                    let (Some(percept), Some(pick)) = (&state.percept, &state.pick) else {
                        return fail(FailureReason::Panic, "approach without a plan");
                    };
                    let open = self.planner.open_offset_m(percept);
                    data.gripper.set(open, OPEN_FORCE_N);
                    data.faults.open_m = open;
                    play_part(model, data, phase, &pick.approach, Phase::Approach, None)?;
                }
                Phase::Grasp => {
                    let Some(percept) = &state.percept else {
                        return fail(FailureReason::Panic, "grasp without a percept");
                    };
                    // A part whose type no measurement named is handled as the tube that fills
                    // its box, a guess: the jaws then hold it if they stop short of the
                    // catalogue's slimmest tube.
                    let radius_m = match percept.unidentified {
                        Some(_) => slimmest_radius_m(model).min(percept.part_outer_radius_m),
                        None => percept.part_outer_radius_m,
                    };
                    grasp(model, data, self.grip_recipe_n, radius_m)?;
                    state.hold = Some(HoldMonitor {
                        tcp_from_part: data.tcp_from_part(model.arm_model(), self.current)?,
                        slip_tolerance_m: model.scenario().task.slip_tolerance_m,
                    });
                }
                Phase::Lift | Phase::Transport | Phase::Place => {
                    let (Some(place), Some(hold)) = (&state.place, &state.hold) else {
                        return fail(FailureReason::Panic, "carrying without a plan or a grip");
                    };
                    let held = Some(Held {
                        part: self.current,
                        monitor: hold,
                    });
                    if phase == Phase::Place {
                        let trajectory = &place.lower;
                        let span = (0.0, trajectory.duration_s());
                        data.execute(model, phase, trajectory, span, STOP_SETTLE_S, held)?;
                    } else {
                        play_part(model, data, phase, &place.carry, Phase::Lift, held)?;
                    }
                }
                Phase::Release => {
                    let Some(percept) = &state.percept else {
                        return fail(FailureReason::Panic, "release without a percept");
                    };
                    data.release_jaws(model, self.planner.open_offset_m(percept))?;
                }
                Phase::Retreat => {
                    let Some(place) = &state.place else {
                        return fail(FailureReason::Panic, "retreat without a plan");
                    };
                    let trajectory = &place.retreat;
                    let span = (0.0, trajectory.duration_s());
                    data.execute(model, Phase::Retreat, trajectory, span, 0.0, None)?;
                    return Ok(());
                }
                Phase::Wait | Phase::Pass => {
                    return fail(FailureReason::Panic, "a pick cycle cannot wait");
                }
            }
            phase = phase.next();
        }
    }

    /// The pick and the place, both planned before the arm moves.
    fn plan(
        &self,
        model: &CellModel,
        data: &CellData,
        state: &CycleState,
    ) -> Result<(PickPlan, PlacePlan), Failure> {
        let Some(percept) = &state.percept else {
            return fail(FailureReason::Panic, "planning without a percept");
        };
        let checker = self.planner.checker_for(percept);
        let pick = self.planner.plan_pick(percept, &checker, &data.q)?;
        let Some(bin_id) = state.bin else {
            return fail(FailureReason::WrongBin, "no bin named ");
        };
        let bin = &data.cell.bins[bin_id.0];
        let placed_before = data.bin_fill[bin_id.0];
        let payload = payload(model, percept, self.grip_recipe_n);
        let place =
            self.planner
                .plan_place(percept, bin, placed_before, &pick, &payload, &checker)?;
        Ok((pick, place))
    }
}

/// Plays `phase`'s part of a trajectory of two blended parts, the first played as `first`: the
/// first part up to where the second starts, then the second to the end and a short rest.
pub(super) fn play_part(
    model: &CellModel,
    data: &mut CellData,
    phase: Phase,
    trajectory: &JointTrajectory,
    first: Phase,
    held: Option<Held<'_>>,
) -> Result<(), Failure> {
    let split_s = trajectory.part_starts_s().get(1).copied().unwrap_or(0.0);
    if phase == first {
        data.execute(model, phase, trajectory, (0.0, split_s), 0.0, held)
    } else {
        let span = (split_s, trajectory.duration_s());
        data.execute(model, phase, trajectory, span, STOP_SETTLE_S, held)
    }
}

/// What the jaws will hold: the detected type's tube, the grip force chosen for it and the pads'
/// friction.
fn payload(model: &CellModel, percept: &Percept, grip_force_n: f64) -> Payload {
    Payload {
        mass_kg: model.catalogue().part(percept.part_type).mass_kg(),
        grip_force_n,
        pad_friction: model.scenario().gripper.pad_friction,
    }
}

/// The sorting rule: accept only a part whose bore was measured within tolerance and whose
/// measurement agrees with the detected type. Returns the decision and its bin.
pub(super) fn decide(model: &CellModel, percept: &Percept) -> (DecisionRecord, Option<BinId>) {
    let catalogue = model.catalogue();
    let accept = percept.inconsistency.is_none()
        && percept.unidentified.is_none()
        && percept
            .roundness_mm
            .is_some_and(|r| r <= model.scenario().roundness_tolerance_mm);
    let bin = catalogue.bin_for(percept.part_type, accept);
    let detected_type = match percept.unidentified {
        Some(_) => UNIDENTIFIED.to_owned(),
        None => catalogue.part(percept.part_type).name.clone(),
    };
    let decision = DecisionRecord {
        detected_type,
        measured_roundness_mm: percept.roundness_mm,
        measured_bore_diameter_mm: percept.bore_diameter_mm,
        accept,
        bin: judge::bin_name(catalogue, bin),
        note: percept
            .unidentified
            .clone()
            .or_else(|| percept.inconsistency.clone()),
    };
    (decision, bin)
}

/// The outer radius of the catalogue's slimmest tube, m.
fn slimmest_radius_m(model: &CellModel) -> f64 {
    model
        .scenario()
        .part_types
        .iter()
        .map(|t| t.outer_diameter_mm / 2e3)
        .fold(f64::INFINITY, f64::min)
}

/// How much narrower than a held body the pads may read, over both, m. The rubber pads give
/// under the squeeze (the solver's soft contacts): a held tube reads 4-6 mm narrower at 60-100 N
/// (a 74 mm tube at 100 N: 68.0-68.3 mm; a 14 mm one at 60 N: 9.2-10.0 mm).
const SQUEEZE_ALLOWANCE_M: f64 = 0.010;
/// How far past their closed stop jaws that hold something must have stopped, m: jaws that close
/// on nothing read their stop, 7.8-8.0 mm with the shipped gripper's 8.0 mm.
const STOP_MARGIN_M: f64 = 0.0008;

/// Whether jaws that closed to `gap_m` (the pads' separation) hold a body `2 * radius_m` wide:
/// they stopped clear of `closed_gap_m`, where they stop on nothing, and no more than the pads'
/// squeeze short of the body's width. (A fixed allowance of 6 mm called held 62-74 mm tubes
/// missed; a rule half way between the stop and the width called held 14-18 mm ones missed.)
pub(super) fn jaws_hold(gap_m: f64, radius_m: f64, closed_gap_m: f64) -> bool {
    gap_m > closed_gap_m + STOP_MARGIN_M && gap_m > 2.0 * radius_m - SQUEEZE_ALLOWANCE_M
}

/// Closes the jaws with `grip_force_n`: the drive runs its stroke to fully closed, then holds; a
/// part between the jaws stops them short, which is how the grasp is detected ([`jaws_hold`]).
pub(super) fn grasp(
    model: &CellModel,
    data: &mut CellData,
    grip_force_n: f64,
    part_radius_m: f64,
) -> Result<(), Failure> {
    if let Some(fault) = data.faults.plan.grip_fault_at(data.faults.grasps) {
        data.gripper.inject(&fault);
    }
    data.faults.grasps += 1;
    data.faults.held_radius_m = part_radius_m;
    data.gripper.set(0.0, grip_force_n);
    let stroke_s = data.gripper.target_m() / JAW_SPEED_M_S;
    data.settle(model, stroke_s + GRIP_BUILD_S)?;
    data.regrip_if_weak(model, grip_force_n)?;
    let gap = data.cell.arm.finger_positions_m(&data.cell.world);
    if !jaws_hold(gap[0] + gap[1], part_radius_m, data.cell.arm.closed_gap_m()) {
        return fail(
            FailureReason::Slipped,
            format!(
                "jaws closed to {:.1} mm: nothing between them",
                (gap[0] + gap[1]) * 1e3
            ),
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::jaws_hold;

    /// Held: a 74 mm tube squeezed to 68.0 mm, a 34 mm one to 29.4 mm, a 14 mm one to 9.2 mm.
    /// Missed: jaws at their 8 mm stop, a pinch of a wall far narrower than the part, a part
    /// too thin to stop the jaws clear of their stop.
    #[test]
    fn jaws_hold_what_stops_them_clear_of_their_stop_and_near_its_width() {
        assert!(jaws_hold(0.0680, 0.037, 0.008));
        assert!(jaws_hold(0.0294, 0.017, 0.008));
        assert!(jaws_hold(0.0092, 0.007, 0.008));
        assert!(!jaws_hold(0.0079, 0.017, 0.008));
        assert!(!jaws_hold(0.0080, 0.005, 0.008));
        assert!(!jaws_hold(0.0120, 0.019, 0.008));
        assert!(!jaws_hold(0.0300, 0.037, 0.008));
    }
}
