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
use super::belt_hold::NextPick;
use super::cell_data::CellData;
use super::judge::{self, CycleEvidence};
use super::pick_cycle::{GRIP_BUILD_S, OPEN_FORCE_N, RELEASE_MARGIN_S, STOP_SETTLE_S, decide};
use super::sorter::Sorter;
use super::stream::{StreamEnd, stream_trial_record};
use super::tracking_plan::Meet;
use crate::cell::CellModel;
use crate::control::{BeltDrive, HoldMonitor};
use crate::outcome::{
    Failure, FailureReason, GraspRecord, Outcome, PartTracking, Phase, StreamPartRecord,
    StreamRecord, TrialRecord,
};
use crate::planning::JointTrajectory;
use crate::scenario::{BinId, PartTypeId};
use crate::sim::JAW_SPEED_M_S;
use nalgebra::Vector3;

/// The pick window ends this far before the belt's end, m.
const WINDOW_END_MARGIN_M: f64 = 0.1;
/// From over a bin, the arm rises this far straight up before it goes home, m, in steps.
const RISE_M: f64 = 0.15;
const RISE_STEPS: u32 = 15;
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
        watch.window = window;
        let mut parts: Vec<StreamPartRecord> = Vec::new();
        let (mut touched, mut picked) = (false, false);
        let mut halt: Option<Failure> = None;
        let mut passed_tracks = Vec::new();
        let mut fed = (data.feeder.remaining().count(), data.belt.encoder_counts());
        while halt.is_none() {
            let count = data.belt.encoder_counts();
            if !watch.parts.is_empty() || watch.belt.held {
                if let Err(f) = self.look_at_stand(model, data, &mut watch.belt) {
                    halt = Some(f);
                    continue;
                }
                let next = self.next_pick(model, data, &mut watch, window, belt.speed_m_s);
                let to_pass = match next {
                    NextPick::Pick(chosen) => {
                        let (item, meet) = *chosen;
                        let part_no = parts.len() as u32;
                        let cycle =
                            self.tracked_pick(model, data, &mut watch, &item, part_no, Some(meet));
                        touched |= cycle.touched;
                        picked |= cycle.picked;
                        if let Some(bin) = cycle.placed_bin {
                            data.bin_fill[bin.0] += 1;
                        }
                        match cycle.record.outcome {
                            Outcome::Success => self.close_picked(item.track),
                            Outcome::Passed => passed_tracks.extend(item.track),
                            Outcome::Failure => {
                                halt = Some(Failure::new(FailureReason::Panic, ""));
                            }
                        }
                        parts.push(cycle.record);
                        continue;
                    }
                    NextPick::Pass(items) if !items.is_empty() => items,
                    NextPick::Again => continue,
                    NextPick::Home => {
                        if let Err(f) = self.go_home(model, data, &mut watch) {
                            halt = Some(f);
                        }
                        continue;
                    }
                    NextPick::Pass(_) | NextPick::Tick => Vec::new(),
                };
                if !to_pass.is_empty() {
                    for item in to_pass {
                        let part_no = parts.len() as u32;
                        let cycle =
                            self.tracked_pick(model, data, &mut watch, &item, part_no, None);
                        passed_tracks.extend(item.track);
                        parts.push(cycle.record);
                    }
                    continue;
                }
                data.hold();
                if let Err(f) = self.tick_watching(model, data, &mut watch) {
                    halt = Some(f);
                }
                continue;
            }
            if watch.parked
                && let Err(f) = self.go_home(model, data, &mut watch)
            {
                halt = Some(f);
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
        let end = StreamEnd {
            outcome,
            failure,
            detail,
            touched,
            picked,
            displacement_mm: 0.0,
            since_s: watch.first_latch_s,
        };
        let stream = StreamRecord {
            parts_planned: planned,
            parts_sorted: sorted,
            bottles_passed: watch.bottles,
            belt_stops: watch.belt.count(),
            parts,
            misidentified: self.misidentified.take(),
            tracks_opened: self.tracking.as_ref().map_or(0, |t| t.opened()),
            passed_tracks: passed_tracks.iter().map(|t| t.0).collect(),
            collected,
            tracking: true,
        };
        stream_trial_record(data, index, end, stream)
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
            let (holds, hold_s) = watch.belt.of_part(item.part, data.cell.world.time_s());
            if holds > 0 {
                // Held for, then not pickable where it stood.
                record.tracking = Some(PartTracking {
                    belt_holds: holds,
                    belt_hold_s: hold_s,
                    ..PartTracking::default()
                });
            }
            return TrackedCycle {
                record,
                placed_bin: None,
                touched: false,
                picked: false,
            };
        };
        let result = self.run_tracked(model, data, watch, item, meet, bin, &mut tracking);
        let result = result.map(|grasp| record.grasp = Some(grasp));
        (tracking.belt_holds, tracking.belt_hold_s) =
            watch.belt.of_part(item.part, data.cell.world.time_s());
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
        let Meet {
            x_m: meet_x,
            wait_s,
            speed_m_s: speed,
            pick,
            ..
        } = meet;
        // A part met on the moving belt is followed, and the belt is not held until it is
        // lifted off; one standing on a held belt is picked as planned.
        let moving = speed > 0.0;
        watch.belt.armed = !moving;
        watch.parked = false;
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
        let follow = moving.then_some(Follow {
            part: item,
            plan_x_m: meet_x,
            speed_m_s: speed,
        });
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
        if !super::pick_cycle::jaws_hold(gap[0] + gap[1], radius_m, data.cell.arm.closed_gap_m()) {
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
        let (lift_x, place) =
            self.plan_lift_and_place(model, data, item, &pick, meet_x, bin, speed)?;
        let lift_follow = moving.then_some(Follow {
            part: item,
            plan_x_m: lift_x,
            speed_m_s: speed,
        });
        let carry = &place.carry;
        let split_s = carry.part_starts_s().get(1).copied().unwrap_or(0.0);
        let over = (split_s, carry.duration_s());
        let lower = (0.0, place.lower.duration_s());
        let plays = [
            Play::span(Phase::Lift, carry, (0.0, split_s)).follow(lift_follow),
            Play::span(Phase::Transport, carry, over).settle(STOP_SETTLE_S),
            Play::span(Phase::Place, &place.lower, lower).settle(STOP_SETTLE_S),
        ];
        for (k, play) in plays.into_iter().enumerate() {
            let played = self.play_watching(model, data, watch, play, Some(&mut held));
            tracking.jaw_drift_mm = held.drift_mm;
            played?;
            if k == 0 {
                // The part is off the belt: a held belt runs again, and from here on a part
                // queued that would leave the window while the arm is away holds it.
                watch
                    .belt
                    .release(data, model.scenario().conveyor.speed_m_s);
                watch.belt.armed = true;
            }
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
        let parked = !watch.parts.is_empty() || watch.belt.held;
        let rest_s = if parked { STOP_SETTLE_S } else { 0.0 };
        let play = Play::span(Phase::Retreat, retreat, (0.0, up_s)).settle(rest_s);
        self.play_watching(model, data, watch, play, None)?;
        if parked {
            // Waits over the bin, risen clear of it: from just over the bin the way to the
            // belt seldom clears what stands in it, and every pick weighed from there was
            // planned in vain. Home from up there when no part can be reached from it.
            watch.parked = true;
            self.rise_over_bin(model, data, watch)?;
        } else {
            let home = (up_s, retreat.duration_s());
            let play = Play::span(Phase::Retreat, retreat, home);
            self.play_watching(model, data, watch, play, None)?;
        }
        Ok(grasp_record)
    }

    /// From where the arm waits over a bin (at rest), straight up clear of what stands in the
    /// bin; it stays parked there, as the next part may be reached from up there.
    fn rise_over_bin(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
    ) -> Result<(), Failure> {
        let mut up = vec![data.q];
        for k in 1..=RISE_STEPS {
            let rise = Vector3::new(0.0, 0.0, RISE_M * f64::from(k) / f64::from(RISE_STEPS));
            let Some(q) = self.moved_ik(&data.q, &rise, &up[up.len() - 1]) else {
                break;
            };
            up.push(q);
        }
        let motion = JointTrajectory::along(&self.planner.model, up, self.planner.speed_fraction);
        let play = Play::span(Phase::Retreat, &motion, (0.0, motion.duration_s()));
        self.play_watching(model, data, watch, play, None)
    }

    /// From where the parked arm waits, risen over a bin (at rest), home along the joint path
    /// the retreat's plan checked, timed from rest.
    pub(super) fn go_home(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
    ) -> Result<(), Failure> {
        watch.parked = false;
        let planner = &self.planner;
        let motion = JointTrajectory::through(
            &planner.model,
            &[data.q, planner.home_q_rad],
            planner.speed_fraction,
        );
        let play = Play::span(Phase::Retreat, &motion, (0.0, motion.duration_s()));
        self.play_watching(model, data, watch, play, None)
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
