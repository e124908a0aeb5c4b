//! A stream picked from a belt that never stops (`conveyor.tracking = true`).
//!
//! The belt runs at its set speed from the first tick to the last (no slow-down zone). The
//! photo-eye's edge latches each item's encoder count and the camera looks at it then, while
//! it moves (`belt_follow`). Each part latched is met where the arm can be over it before it
//! gets there (`planning::InterceptProblem`): the arm waits the difference, comes over the
//! place, and goes down with the part, its tool moved with the belt by the encoder through
//! descend, grasp and lift; then carries it to its bin as in stop-and-go. The lift is planned
//! once the jaws hold, for where the belt will have carried the part when it ends, so the move
//! to the bin starts from its plan's own pose. A part the arm cannot meet before it leaves the
//! pick window rides on unpicked (to the collector, when the scenario has one); bottles ride
//! on.

use super::belt_follow::{EyeWatch, Follow, HeldPart, Latched, Play};
use super::cell_data::CellData;
use super::judge::{self, CycleEvidence};
use super::pick_cycle::{GRIP_BUILD_S, OPEN_FORCE_N, RELEASE_MARGIN_S, STOP_SETTLE_S, decide};
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::control::{BeltDrive, HoldMonitor};
use crate::outcome::{
    Failure, FailureReason, GraspRecord, Outcome, PartTracking, Phase, StreamPartRecord,
    StreamRecord, TrialRecord,
};
use crate::planning::{InterceptProblem, Payload, PickPlan, PlacePlan};
use crate::scenario::{BinId, PartTypeId};
use crate::sim::JAW_SPEED_M_S;
use crate::station::Percept;

/// The pick window ends this far before the belt's end, m.
const WINDOW_END_MARGIN_M: f64 = 0.1;
/// Time allowed for the lift when checking that the arm still reaches where the belt will
/// have carried the part by the lift's end, s (a lift takes 0.2-0.3 s).
const LIFT_ALLOWANCE_S: f64 = 0.6;
/// Belt travel after the feeder's last item with nothing latched that ends the stream, m
/// beyond the spawn distance.
const DRAIN_TRAVEL_M: f64 = 0.5;

/// What one tracked pick did.
struct TrackedCycle {
    record: StreamPartRecord,
    placed_bin: Option<BinId>,
    touched: bool,
    picked: bool,
}

/// Where and when the arm meets a part, and the pick planned for it there.
struct Meet {
    /// The place along the belt (world x), m.
    x_m: f64,
    /// When the part gets there, s from the planning.
    meet_s: f64,
    /// How long the arm waits before it sets off, s.
    wait_s: f64,
    pick: PickPlan,
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

impl Sorter<'_> {
    /// A tracking stream trial: the belt never stops; it halts at the first failed part.
    pub(crate) fn run_tracking_stream(
        mut self,
        model: &CellModel,
        data: &mut CellData,
        index: u32,
    ) -> TrialRecord {
        let scenario = model.scenario();
        let belt = &scenario.conveyor;
        let planned = scenario.parts_per_trial;
        let items = planned + scenario.stream.bottles;
        let window = (
            belt.photo_eye_x_m,
            belt.belt_center_m[0] + belt.length_m / 2.0 - WINDOW_END_MARGIN_M,
        );
        // The line never stops: no slow-down zone, the belt at its speed throughout.
        data.belt = BeltDrive::default();
        data.belt.run_at(belt.speed_m_s);
        self.tracking = Some(super::at_eye::stream_tracking(model, data));
        let mut watch = EyeWatch::default();
        let mut parts: Vec<StreamPartRecord> = Vec::new();
        let (mut touched, mut picked) = (false, false);
        let mut halt: Option<Failure> = None;
        let mut passed_tracks = Vec::new();
        let mut fed = (data.feeder.remaining().count(), data.belt.encoder_counts());
        while halt.is_none() {
            let count = data.belt.encoder_counts();
            if !watch.parts.is_empty() {
                let started = std::time::Instant::now();
                // Every part queued, met where it can be; the earliest meet is picked, those
                // that can no longer be met ride on, the rest wait for the next round.
                let mut met: Vec<(Latched, Option<Meet>)> = watch
                    .parts
                    .drain(..)
                    .map(|item| {
                        let meet = self.plan_intercept(model, data, &item, window);
                        (item, meet)
                    })
                    .collect();
                data.timing.planning_ms += started.elapsed().as_secs_f64() * 1e3;
                let first = met
                    .iter()
                    .enumerate()
                    .filter_map(|(i, (_, m))| m.as_ref().map(|m| (i, m.meet_s)))
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(i, _)| i);
                let chosen = first.map(|i| met.remove(i));
                for (item, meet) in met {
                    match meet {
                        Some(_) => watch.parts.push_back(item),
                        None => {
                            let part_no = parts.len() as u32;
                            let cycle =
                                self.tracked_pick(model, data, &mut watch, &item, part_no, None);
                            passed_tracks.extend(item.track);
                            parts.push(cycle.record);
                        }
                    }
                }
                if let Some((item, meet)) = chosen {
                    let part_no = parts.len() as u32;
                    let cycle = self.tracked_pick(model, data, &mut watch, &item, part_no, meet);
                    touched |= cycle.touched;
                    picked |= cycle.picked;
                    if let Some(bin) = cycle.placed_bin {
                        data.bin_fill[bin.0] += 1;
                    }
                    match cycle.record.outcome {
                        Outcome::Success => self.close_picked(item.track),
                        Outcome::Passed => passed_tracks.extend(item.track),
                        Outcome::Failure => halt = Some(Failure::new(FailureReason::Panic, "")),
                    }
                    parts.push(cycle.record);
                }
                continue;
            }
            let remaining = data.feeder.remaining().count();
            if remaining != fed.0 {
                fed = (remaining, count);
            }
            let drained = (count - fed.1) as f64 * crate::control::ENCODER_M_PER_COUNT
                > belt.spawn_upstream_m + DRAIN_TRAVEL_M;
            if remaining == 0 && (watch.latched >= items || drained) {
                break;
            }
            data.hold();
            if let Err(f) = self.tick_watching(model, data, &mut watch) {
                halt = Some(f);
            }
        }
        // The stream's own halt is the failed part's; only a halt outside a part stands alone.
        let part_failed = parts.iter().any(|p| p.outcome == Outcome::Failure);
        if part_failed {
            halt = None;
        }
        passed_tracks.extend(watch.bottle_tracks.iter().copied());
        let mut collected = Vec::new();
        if halt.is_none()
            && !part_failed
            && let Some(tracking) = &self.tracking
        {
            match tracking.collect(model, data, &passed_tracks) {
                Ok(records) => collected = records,
                Err(failure) => halt = Some(failure),
            }
        }
        let sorted = parts
            .iter()
            .filter(|p| p.outcome == Outcome::Success)
            .count() as u32;
        let unpicked = parts
            .iter()
            .filter(|p| p.outcome == Outcome::Passed)
            .count();
        let part_fault = parts
            .iter()
            .find(|p| p.outcome == Outcome::Failure)
            .map(|p| {
                let detail = p.detail.as_deref().unwrap_or("failed");
                (
                    p.failure,
                    format!("part {} ({}): {detail}", p.index, p.part.part_type),
                )
            });
        let (failure, detail) = match (part_fault, halt) {
            (Some((reason, detail)), _) => (reason, Some(detail)),
            (None, Some(f)) => (
                Some(f.reason),
                Some(format!("after {} parts: {}", parts.len(), f.detail)),
            ),
            (None, None) => (None, None),
        };
        let outcome = match (&failure, sorted < planned) {
            (Some(_), _) => Outcome::Failure,
            (None, true) => Outcome::Passed,
            (None, false) => Outcome::Success,
        };
        let detail = match (detail, outcome) {
            (Some(d), _) => Some(format!("{sorted}/{planned} parts sorted; {d}")),
            (None, Outcome::Passed) => Some(format!(
                "{sorted}/{planned} parts sorted; {unpicked} rode on unpicked, {} not made out",
                watch.unseen.len()
            )),
            (None, _) => None,
        };
        let faults = data.take_fault_records(failure.is_none());
        let sim_time_s = data.cell.world.time_s();
        TrialRecord {
            trial: index,
            seed: data.seed,
            outcome,
            failure,
            detail,
            part: None,
            decision: None,
            placed_bin: None,
            distractor_touched: touched,
            distractor_picked: picked,
            distractor_displacement_mm: 0.0,
            cycle_time_s: watch.first_latch_s.map_or(0.0, |t| sim_time_s - t),
            sim_time_s,
            motion: data.motion,
            timing: data.timing.clone(),
            stream: Some(StreamRecord {
                parts_planned: planned,
                parts_sorted: sorted,
                bottles_passed: watch.bottles,
                belt_stops: 0,
                parts,
                misidentified: self.misidentified.take(),
                tracks_opened: self.tracking.as_ref().map_or(0, |t| t.opened()),
                passed_tracks: passed_tracks.iter().map(|t| t.0).collect(),
                collected,
                tracking: true,
            }),
            grasp: None,
            faults,
            removals: 0,
            passed: None,
        }
    }

    /// One part met on the moving belt, or let ride on when it cannot be met; judged.
    fn tracked_pick(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
        item: &Latched,
        index: u32,
        meet: Option<Meet>,
    ) -> TrackedCycle {
        self.current = item.part;
        data.touch_phase = None;
        let part = self.part_record(model, data);
        let (decision, bin) = decide(model, &item.percept);
        let mut record = StreamPartRecord {
            index,
            outcome: Outcome::Success,
            failure: None,
            detail: None,
            part,
            decision: Some(decision),
            placed_bin: None,
            cycle_time_s: 0.0,
            grasp: None,
            track: item.track.map(|t| t.0),
            tracking: None,
        };
        self.grip_recipe_n = model.catalogue().part(item.percept.part_type).grip_force_n;
        let mut tracking = PartTracking::default();
        let Some(meet) = meet else {
            record.outcome = Outcome::Passed;
            record.detail = Some("left the pick window unpicked: the arm could not meet it".into());
            return TrackedCycle {
                record,
                placed_bin: None,
                touched: false,
                picked: false,
            };
        };
        let result = self.run_tracked(model, data, watch, item, meet, bin, &mut tracking);
        let result = result.map(|grasp| record.grasp = Some(grasp));
        record.tracking = Some(tracking);
        let placed_bin = data.bin_holding(self.current);
        let evidence = CycleEvidence {
            part_type: PartTypeId(data.cell.items.parts()[self.current].instance.type_index),
            placed_bin,
            bottle_lifted: bottle_lifted(model, data),
            touch_phase: data.touch_phase,
            // The belt carries the bottles on: only the robot's touch counts.
            bottle_displacement_m: 0.0,
        };
        let failure = judge::judge_cycle(
            model.scenario(),
            model.catalogue(),
            &record.part,
            result,
            &evidence,
        );
        record.placed_bin = placed_bin.map(|b| model.catalogue().bin_name(b).to_owned());
        record.cycle_time_s = data.cell.world.time_s() - item.time_s;
        if let Some(f) = failure {
            record.outcome = Outcome::Failure;
            record.failure = Some(f.reason);
            record.detail = Some(f.detail);
        }
        TrackedCycle {
            record,
            placed_bin,
            touched: evidence.touch_phase.is_some(),
            picked: evidence.bottle_lifted,
        }
    }

    /// Meets, grasps, lifts and places `item`'s part; `Ok(None)` when it cannot be met.
    #[allow(clippy::too_many_arguments)]
    fn run_tracked(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
        item: &Latched,
        meet: Meet,
        bin: Option<BinId>,
        tracking: &mut PartTracking,
    ) -> Result<GraspRecord, Failure> {
        let speed = model.scenario().conveyor.speed_m_s;
        let Meet {
            x_m: meet_x,
            meet_s,
            wait_s,
            pick,
        } = meet;
        let _ = meet_s;
        let Some(bin) = bin else {
            return Err(Failure::new(FailureReason::WrongBin, "no bin named "));
        };
        let grasp_record = GraspRecord {
            clearance_mm: pick.clearance_m * 1e3,
            candidates: u32::try_from(pick.candidates).unwrap_or(u32::MAX),
        };
        let open = self.planner.open_offset_m(&item.percept);
        data.gripper.set(open, OPEN_FORCE_N);
        self.wait_watching(model, data, watch, wait_s)?;
        let approach = &pick.approach;
        let split_s = approach.part_starts_s().get(1).copied().unwrap_or(0.0);
        let end_s = approach.duration_s();
        let play = Play::span(Phase::Approach, approach, (0.0, split_s));
        self.play_watching(model, data, watch, play, None)?;
        let follow = Follow {
            part: item,
            plan_x_m: meet_x,
            speed_m_s: speed,
        };
        let descend = (split_s, end_s);
        let play = Play::span(Phase::Descend, approach, descend).follow(follow);
        self.play_watching(model, data, watch, play, None)?;
        // The grasp, the tool still moving with the part.
        let arm = model.arm_model();
        let tcp = data.world_from_tcp(arm).translation.vector;
        let part_body = data.cell.items.parts()[self.current].body;
        if let Some(pose) = data.cell.body_pose(part_body) {
            let d = tcp - pose.translation.vector;
            tracking.tracking_error_mm = d.x.hypot(d.y) * 1e3;
        }
        let grip_n = self.grip_recipe_n;
        data.gripper.set(0.0, grip_n);
        let close_s = data.gripper.target_m() / JAW_SPEED_M_S + GRIP_BUILD_S;
        let play = Play::span(Phase::Grasp, approach, (end_s, end_s))
            .settle(close_s)
            .follow(follow);
        self.play_watching(model, data, watch, play, None)?;
        tracking.latch_to_grasp_s = data.cell.world.time_s() - item.time_s;
        let radius_m = item.percept.part_outer_radius_m;
        let gap = data.cell.arm.finger_positions_m(&data.cell.world);
        if gap[0] + gap[1] <= 2.0 * radius_m - 0.006 {
            return Err(Failure::new(
                FailureReason::Slipped,
                format!(
                    "jaws closed to {:.1} mm: nothing between them",
                    (gap[0] + gap[1]) * 1e3
                ),
            ));
        }
        let mut held = HeldPart {
            part: self.current,
            monitor: HoldMonitor {
                tcp_from_part: data.tcp_from_part(arm, self.current)?,
                slip_tolerance_m: model.scenario().task.slip_tolerance_m,
            },
            drift_mm: 0.0,
        };
        // The lift, planned for where the belt will have carried the part when it ends.
        let (lift_x, place) = self.plan_lift_and_place(model, data, item, &pick, meet_x, bin)?;
        let lift_follow = Follow {
            part: item,
            plan_x_m: lift_x,
            speed_m_s: speed,
        };
        let carry = &place.carry;
        let split_s = carry.part_starts_s().get(1).copied().unwrap_or(0.0);
        let over = (split_s, carry.duration_s());
        let lower = (0.0, place.lower.duration_s());
        let plays = [
            Play::span(Phase::Lift, carry, (0.0, split_s)).follow(lift_follow),
            Play::span(Phase::Transport, carry, over).settle(STOP_SETTLE_S),
            Play::span(Phase::Place, &place.lower, lower).settle(STOP_SETTLE_S),
        ];
        for play in plays {
            let played = self.play_watching(model, data, watch, play, Some(&mut held));
            tracking.jaw_drift_mm = held.drift_mm;
            played?;
        }
        data.phase = Phase::Release;
        let pads = data.cell.arm.finger_positions_m(&data.cell.world);
        data.gripper
            .open_from(pads[0].min(pads[1]), open, OPEN_FORCE_N);
        let travel_m = (open - data.gripper.target_m()).max(0.0);
        data.phase = Phase::Release;
        self.wait_watching(
            model,
            data,
            watch,
            travel_m / JAW_SPEED_M_S + RELEASE_MARGIN_S,
        )?;
        // Up out of the bin; home only when no part waits to be met (the next approach
        // starts from where the arm is).
        let retreat = &place.retreat;
        let up_s = retreat
            .part_starts_s()
            .get(1)
            .copied()
            .unwrap_or(retreat.duration_s());
        let parked = !watch.parts.is_empty();
        let rest_s = if parked { STOP_SETTLE_S } else { 0.0 };
        let play = Play::span(Phase::Retreat, retreat, (0.0, up_s)).settle(rest_s);
        self.play_watching(model, data, watch, play, None)?;
        if !parked {
            let home = (up_s, retreat.duration_s());
            let play = Play::span(Phase::Retreat, retreat, home);
            self.play_watching(model, data, watch, play, None)?;
        }
        Ok(grasp_record)
    }

    /// Where to meet `item`'s part: the place along the belt, how long the arm waits before
    /// it sets off, and the pick planned for the part there. `None`: it cannot be met.
    fn plan_intercept(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        window: (f64, f64),
    ) -> Option<Meet> {
        let speed = model.scenario().conveyor.speed_m_s;
        let bin = decide(model, &item.percept).1;
        let planner = &self.planner;
        let x_latch = item.percept.part_xy[0];
        let pick_at = |x: f64| {
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
        };
        let problem = InterceptProblem {
            part_now_m: item.x_at(data.belt.encoder_counts()),
            speed_m_s: speed,
            window_m: window,
        };
        let meet = problem.solve(|x| pick_at(x).map(|(t, _)| t))?;
        let (_, pick) = pick_at(meet.at_m)?;
        Some(Meet {
            x_m: meet.at_m,
            meet_s: meet.meet_s,
            wait_s: (meet.meet_s - meet.arrival_s).max(0.0),
            pick,
        })
    }

    /// The lift from the grasp, planned for the part where the belt will have carried it when
    /// the lift ends (found in two rounds: the lift's time depends a little on where it is),
    /// with the place that follows: the lift's place along the belt, and the place plan.
    fn plan_lift_and_place(
        &self,
        model: &CellModel,
        data: &CellData,
        item: &Latched,
        pick: &PickPlan,
        meet_x: f64,
        bin: BinId,
    ) -> Result<(f64, PlacePlan), Failure> {
        let speed = model.scenario().conveyor.speed_m_s;
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

/// Whether a bottle stands higher over the belt than it could on it: lifted by the robot.
fn bottle_lifted(model: &CellModel, data: &CellData) -> bool {
    let bottle = &model.scenario().bottle;
    let top = data.cell.belt_top_z;
    data.cell.items.bottles().iter().any(|b| {
        data.cell
            .body_pose(b.body)
            .is_some_and(|pose| pose.translation.z - top > bottle.height_m / 2.0 + 0.02)
    })
}
