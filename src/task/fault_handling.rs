//! The controller's answers to the faults a trial injects, each from what its sensors show
//! (the eye's output, the belt's encoder, the jaws' opening, the camera's frames), never from
//! the truth; and the bookkeeping that turns them into the record's fault list.

use super::cell_data::CellData;
use crate::cell::CellModel;
use crate::control::{Backoff, BlackoutFrames, FaultPlan, GripWatch, PhotoEyeSignal};
use crate::kinematics::JointVector;
use crate::outcome::{Failure, FailureReason, FaultAction, FaultKind, FaultRecord, Phase, fail};
use crate::planning::{Carried, CollisionChecker, JointTrajectory, PART_OBSTACLE};
use crate::station::{black_frame, frame_is_blank};

/// A belt this far behind its commands has a fault the controller can see, m.
const BELT_SHORTFALL_M: f64 = 0.01;

/// A trial's faults: the plan, the events they strike by, and the records so far.
#[derive(Debug, Clone)]
pub(crate) struct FaultLog {
    pub(crate) plan: FaultPlan,
    pub(crate) records: Vec<FaultRecord>,
    /// Grasps, looks and pick cycles begun so far.
    pub(crate) grasps: u32,
    pub(crate) looks: u32,
    pub(crate) cycles: u32,
    /// The photo-eye's output, with its planned lies, as of the last step.
    pub(crate) eye: PhotoEyeSignal,
    pub(crate) eye_reports: bool,
    /// When a camera blackout ends, what the camera delivers meanwhile, and when it began.
    blackout: Option<(f64, BlackoutFrames, f64)>,
    /// The collision checker the current cycle was planned with, the jaws' opening for it and
    /// the held part's radius, m.
    pub(crate) checker: Option<CollisionChecker>,
    pub(crate) open_m: f64,
    pub(crate) held_radius_m: f64,
    /// When and in which phase the jaws showed the held part gone, or its grip weak.
    pub(crate) drop_seen: Option<(f64, Phase)>,
    /// The force each jaw reported when the grip was seen weak on the way up or over, N.
    pub(crate) weak_grip_n: Option<f64>,
    /// When and at what force the grip was seen weak over the bin (the place went on).
    pub(crate) weak_in_place: Option<(f64, f64)>,
    /// When and at what force the grip was found weak at the grasp and taken again.
    pub(crate) regripped: Option<(f64, f64)>,
    /// The watch over the jaws' force and opening, armed by a grip fault in the scenario.
    pub(crate) grip_watch: Option<GripWatch>,
    /// The joint angles at which the jaws last closed on the part, and those above it where
    /// the pick's straight descent began.
    pub(crate) grasp_q: Option<JointVector>,
    pub(crate) pregrasp_q: Option<JointVector>,
    /// The part the cycle carries, as its planner saw it.
    pub(crate) carried: Option<Carried>,
    belt_noted: bool,
    /// What the controller did about a trigger with nothing at the station.
    pub(crate) false_trigger_actions: Vec<FaultAction>,
}

impl FaultLog {
    /// The log of a trial whose faults are `plan`.
    pub(crate) fn new(plan: FaultPlan) -> Self {
        Self {
            eye: PhotoEyeSignal::new(plan.photo_eye),
            plan,
            records: Vec::new(),
            grasps: 0,
            looks: 0,
            cycles: 0,
            eye_reports: false,
            blackout: None,
            checker: None,
            open_m: 0.0,
            held_radius_m: 0.0,
            drop_seen: None,
            weak_grip_n: None,
            weak_in_place: None,
            regripped: None,
            grip_watch: None,
            grasp_q: None,
            pregrasp_q: None,
            carried: None,
            belt_noted: false,
            false_trigger_actions: Vec::new(),
        }
    }

    /// Records a fault whose item ended `handled` (sorted, or for a bottle let through) or
    /// not: it was recovered from when the item was handled and nothing was given up.
    pub(crate) fn record(
        &mut self,
        kind: FaultKind,
        at_s: f64,
        detail: String,
        actions: Vec<FaultAction>,
        handled: bool,
    ) {
        self.push(kind, at_s, detail, actions);
        if let Some(record) = self.records.last_mut() {
            record.recovered &= handled;
        }
    }

    fn push(&mut self, kind: FaultKind, at_s: f64, detail: String, actions: Vec<FaultAction>) {
        let recovered = !actions.iter().any(|a| {
            matches!(
                a,
                FaultAction::CountedLost
                    | FaultAction::LetThrough
                    | FaultAction::AbandonedMotion
                    | FaultAction::TimedOutFeed
            )
        });
        let lost_parts = u32::from(actions.contains(&FaultAction::CountedLost));
        self.records.push(FaultRecord {
            kind,
            at_s,
            detail,
            actions,
            recovered,
            lost_parts,
            saw_lying_part: None,
        });
    }
}

impl FaultLog {
    /// Whether the last fault recorded ended with its part counted lost.
    pub(crate) fn counted_lost_last(&self) -> bool {
        self.records
            .last()
            .is_some_and(|r| r.actions.contains(&FaultAction::CountedLost))
    }
}

impl CellData {
    /// What the photo-eye reports now.
    pub(crate) fn photo_eye_reports(&self) -> bool {
        if self.faults.plan.photo_eye_lies() {
            self.faults.eye_reports
        } else {
            self.cell.photo_eye_blocked()
        }
    }

    /// A wait that ran out: the encoder says whether the belt moved as commanded, and so why
    /// nothing reached the eye.
    pub(crate) fn timed_out_feed(
        &mut self,
        model: &CellModel,
        failure: Failure,
        (commanded_before_m, encoder_before_m): (f64, f64),
    ) -> Failure {
        let commanded_m = self.belt.commanded_travel_m() - commanded_before_m;
        let moved_m = self.belt.encoder_travel_m() - encoder_before_m;
        let feed_m = model.scenario().conveyor.spawn_upstream_m;
        let now = self.cell.world.time_s();
        let reason = if commanded_m - moved_m > BELT_SHORTFALL_M {
            if !self.faults.belt_noted {
                self.faults.belt_noted = true;
                let detail = format!(
                    "the belt's encoder counted {moved_m:.3} m of the {commanded_m:.3} m commanded"
                );
                let actions = vec![FaultAction::SawBeltShortfall, FaultAction::TimedOutFeed];
                self.faults.push(FaultKind::Belt, now, detail, actions);
            }
            format!(
                "the belt fell behind its commands: its encoder counted {moved_m:.3} m of the \
                 {commanded_m:.3} m commanded, short of the {feed_m:.2} m feed"
            )
        } else if moved_m > feed_m {
            if let Some(at_s) = self.faults.eye.missed_trigger_struck_s() {
                let detail = format!("no trigger after {moved_m:.3} m of belt travel");
                let actions = vec![FaultAction::TimedOutFeed, FaultAction::CountedLost];
                self.faults.push(FaultKind::PhotoEye, at_s, detail, actions);
            }
            format!(
                "the belt ran {moved_m:.3} m, past the {feed_m:.2} m feed, with no trigger: an \
                 item may have passed the photo-eye unseen"
            )
        } else {
            format!("the belt ran {moved_m:.3} m of the {feed_m:.2} m feed")
        };
        Failure::new(failure.reason, format!("{}; {reason}", failure.detail))
    }

    /// A feed that arrived: when the encoder shows the belt behind its commands, the wait
    /// rode out a belt fault.
    pub(crate) fn note_belt_arrival(&mut self, commanded_before_m: f64, encoder_before_m: f64) {
        let commanded_m = self.belt.commanded_travel_m() - commanded_before_m;
        let moved_m = self.belt.encoder_travel_m() - encoder_before_m;
        if commanded_m - moved_m > BELT_SHORTFALL_M && !self.faults.belt_noted {
            self.faults.belt_noted = true;
            let detail = format!(
                "the belt's encoder counted {moved_m:.3} m of the {commanded_m:.3} m commanded; \
                 the feed arrived late"
            );
            let actions = vec![FaultAction::SawBeltShortfall, FaultAction::WaitedForBelt];
            let now = self.cell.world.time_s();
            self.faults.push(FaultKind::Belt, now, detail, actions);
        }
    }

    /// Before a look: the camera's frames, waited for with back-off through a blackout. `Err`
    /// when the last retry still gets none (the item is then let through).
    pub(crate) fn await_frames(&mut self, model: &CellModel) -> Result<(), Failure> {
        let look = self.faults.looks;
        self.faults.looks += 1;
        let now = self.cell.world.time_s();
        if let Some(blackout) = self.faults.plan.blackout_at(look) {
            self.faults.blackout = Some((now + blackout.duration_s, blackout.frames, now));
        }
        let Some((until_s, frames, began_s)) = self.faults.blackout else {
            return Ok(());
        };
        let mut actions = Vec::new();
        let mut waits = Backoff::CAMERA.waits_s().collect::<Vec<_>>().into_iter();
        loop {
            let now = self.cell.world.time_s();
            // What the camera delivers: nothing, or a frame the controller checks and finds
            // blank; either way it does not run its detector on it.
            let frame_ok = now >= until_s
                || match frames {
                    BlackoutFrames::None => false,
                    BlackoutFrames::Black => {
                        let [w, h] = model.scenario().camera.resolution_px;
                        !frame_is_blank(&black_frame(w, h))
                    }
                };
            if frame_ok {
                self.faults.blackout = None;
                if !actions.is_empty() {
                    let detail = blackout_detail(frames, until_s - began_s, "frames came back");
                    self.faults
                        .push(FaultKind::Camera, began_s, detail, actions);
                }
                return Ok(());
            }
            let Some(wait_s) = waits.next() else {
                actions.push(FaultAction::LetThrough);
                self.faults.blackout = None;
                let detail = blackout_detail(frames, until_s - began_s, "the item let through");
                self.faults
                    .push(FaultKind::Camera, began_s, detail, actions);
                return fail(
                    FailureReason::NotDetected,
                    format!(
                        "the camera gave no usable frame through {:.2} s of retries; the item \
                         was let through",
                        Backoff::CAMERA.patience_s()
                    ),
                );
            };
            actions.push(FaultAction::RetriedCamera);
            self.settle(model, wait_s)?;
        }
    }

    /// After an arm stop, before the servos release: the rest of the motion, from where the
    /// arm stands, checked for collisions again against what the cycle was planned with.
    pub(crate) fn resume_after_stop(
        &mut self,
        phase: Phase,
        trajectory: &JointTrajectory,
        (at_s, to_s): (f64, f64),
        began_s: f64,
        holding: bool,
    ) -> Result<(), Failure> {
        let q_now = self.cell.arm.joint_positions(&self.cell.world);
        let finger_m = if holding {
            self.faults.held_radius_m
        } else {
            self.gripper.target_m()
        };
        let ignore = [PART_OBSTACLE];
        // The carried part counts as the planner counted it: from where the move over to the
        // bin starts; on the way up it rises straight off the belt it stood on.
        let carried = self
            .faults
            .carried
            .as_ref()
            .filter(|_| holding && phase != Phase::Lift);
        let hit = self.faults.checker.as_ref().and_then(|checker| {
            checker
                .check_configuration(&q_now, finger_m, carried, &ignore)
                .or_else(|| {
                    checker
                        .check_span(trajectory, (at_s, to_s), finger_m, carried, &ignore)
                        .map(|hit| (hit.link, hit.obstacle))
                })
        });
        let held_s = self.cell.world.time_s() - began_s;
        let mut actions = vec![FaultAction::HeldThroughStop];
        let detail = format!("the arm stood {held_s:.2} s during {phase}");
        match hit {
            None => {
                actions.push(FaultAction::RecheckedMotion);
                self.faults.push(FaultKind::Arm, began_s, detail, actions);
                Ok(())
            }
            Some((link, obstacle)) => {
                actions.push(FaultAction::AbandonedMotion);
                self.faults.push(FaultKind::Arm, began_s, detail, actions);
                fail(
                    FailureReason::Collision,
                    format!(
                        "after an arm stop the rest of {phase} would bring {link} onto {obstacle}"
                    ),
                )
            }
        }
    }

    /// Where the handled part truly rests, in words, for a lost part's record (the judge's
    /// view, never the controller's).
    pub(crate) fn part_resting_place(&self, model: &CellModel, current: usize) -> &'static str {
        let part = &self.cell.items.parts()[current];
        let Some(pose) = self.cell.body_pose(part.body) else {
            return "gone from the world";
        };
        let belt = &model.scenario().conveyor;
        let on_belt = (pose.translation.x - belt.belt_center_m[0]).abs() < belt.length_m / 2.0
            && (pose.translation.y - belt.belt_center_m[1]).abs() < belt.width_m / 2.0
            && (pose.translation.z - self.cell.belt_top_z).abs() < part.instance.height_m;
        let upright = (pose.rotation * nalgebra::Vector3::z()).z > 0.9;
        match (self.bin_holding(current).is_some(), on_belt, upright) {
            (true, _, _) => "in a bin",
            (false, true, true) => "standing on the belt away from the station",
            (false, true, false) => "lying on the belt",
            (false, false, _) => "off the belt",
        }
    }

    /// The fault records of the trial, completed with the faults whose outcome shows only at
    /// its end; `handled` says whether the trial's item reached its end state.
    pub(crate) fn take_fault_records(&mut self, handled: bool) -> Vec<FaultRecord> {
        let now = self.cell.world.time_s();
        // A drop no recovery took up.
        if let Some((at_s, phase)) = self.faults.drop_seen.take() {
            let (detail, action) = match self.faults.weak_grip_n.take() {
                Some(force_n) => (
                    format!(
                        "the grip weakened to {force_n:.1} N during {phase}; no recovery followed"
                    ),
                    FaultAction::SawWeakGrip,
                ),
                None => (
                    format!(
                        "the grip weakened and the part fell during {phase}; no recovery followed"
                    ),
                    FaultAction::SawDrop,
                ),
            };
            self.faults
                .record(FaultKind::Gripper, at_s, detail, vec![action], false);
        }
        if let Some((at_s, force_n)) = self.faults.regripped.take() {
            let detail = format!(
                "the grip was {force_n:.1} N when the jaws closed; they opened and closed again"
            );
            let actions = vec![FaultAction::SawWeakGrip, FaultAction::Regripped];
            self.faults
                .record(FaultKind::Gripper, at_s, detail, actions, handled);
        }
        if let Some((at_s, force_n)) = self.faults.weak_in_place.take()
            && !self
                .faults
                .records
                .iter()
                .any(|r| r.kind == FaultKind::Gripper)
        {
            let detail =
                format!("the grip weakened to {force_n:.1} N over the bin; the place went on");
            let actions = vec![FaultAction::SawWeakGrip];
            self.faults
                .record(FaultKind::Gripper, at_s, detail, actions, handled);
        }
        if self.gripper.fault_struck()
            && !self
                .faults
                .records
                .iter()
                .any(|r| r.kind == FaultKind::Gripper)
        {
            // Noted at the trial's end: the drive does not say when its force fell.
            let detail = "the grip weakened while the part was held; it stayed in the jaws".into();
            let actions = vec![FaultAction::NoneNeeded];
            self.faults.push(FaultKind::Gripper, now, detail, actions);
        }
        if let Some(fault) = self.belt.fault().filter(|_| self.belt.fault_struck())
            && !self.faults.belt_noted
        {
            let detail = "the belt misbehaved while it was not feeding".into();
            let actions = vec![FaultAction::NoneNeeded];
            self.faults
                .push(FaultKind::Belt, fault.onset_s, detail, actions);
        }
        if let Some(at_s) = self.faults.eye.false_trigger_struck_s() {
            let mut actions = std::mem::take(&mut self.faults.false_trigger_actions);
            if actions.is_empty() {
                actions.push(FaultAction::NoneNeeded);
            }
            let detail = "the photo-eye triggered with nothing in its beam".into();
            self.faults.push(FaultKind::PhotoEye, at_s, detail, actions);
            if !handled && let Some(record) = self.faults.records.last_mut() {
                record.recovered = false;
            }
        }
        let lost_to_eye = self
            .faults
            .records
            .iter()
            .any(|r| r.kind == FaultKind::PhotoEye && r.lost_parts > 0);
        if let Some(at_s) = self.faults.eye.missed_trigger_struck_s()
            && !lost_to_eye
        {
            let detail =
                "an item crossed the photo-eye unreported; a later crossing stopped the belt"
                    .into();
            let actions = vec![FaultAction::NoneNeeded];
            self.faults.push(FaultKind::PhotoEye, at_s, detail, actions);
            if !handled && let Some(record) = self.faults.records.last_mut() {
                record.recovered = false;
            }
        }
        let mut records = std::mem::take(&mut self.faults.records);
        records.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
        records
    }
}

fn blackout_detail(frames: BlackoutFrames, duration_s: f64, end: &str) -> String {
    let what = match frames {
        BlackoutFrames::None => "no frame",
        BlackoutFrames::Black => "black frames",
    };
    format!("the camera gave {what} for {duration_s:.2} s; {end}")
}
