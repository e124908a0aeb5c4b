//! Running a trial: the paper's single part, or a stream in which the feeder puts parts and
//! bottles on the belt, the belt stops at the photo-eye for each, parts are sorted and bottles
//! let through. What stops at the photo-eye is identified by perception: in camera mode from the
//! image alone, in oracle mode from the world.

use super::at_eye::{AtEye, stream_tracking};
use super::cell_data::CellData;
use super::pick_cycle::Cycle;
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::outcome::{
    Failure, FailureReason, FaultAction, Outcome, StreamPartRecord, StreamRecord, TrialRecord,
};
use crate::station::TrackEnd;

fn count_u32(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

impl Sorter<'_> {
    /// The paper's trial: one part (and its bottle) from the belt into its bin.
    pub(crate) fn run_single(
        mut self,
        model: &CellModel,
        data: &mut CellData,
        index: u32,
    ) -> TrialRecord {
        let cycle = self.single_part(model, data);
        let faults = data.take_fault_records(cycle.failure.is_none());
        let (failure, detail) = split(cycle.failure);
        let sim_time_s = data.cell.world.time_s();
        let (outcome, detail) = match (&cycle.passed, failure) {
            (Some(passed), None) => (Outcome::Passed, Some(passed.detail.clone())),
            _ => (Outcome::from_failed(failure.is_some()), detail),
        };
        TrialRecord {
            trial: index,
            seed: data.seed,
            outcome,
            failure,
            detail,
            part: Some(cycle.part),
            decision: cycle.decision,
            placed_bin: cycle.placed_bin,
            distractor_touched: cycle.touched,
            distractor_picked: cycle.picked,
            distractor_displacement_mm: cycle.displacement_m * 1e3,
            cycle_time_s: cycle.cycle_time_s,
            sim_time_s,
            motion: data.motion,
            timing: data.timing.clone(),
            stream: None,
            grasp: cycle.grasp,
            faults,
            removals: data.removals,
            passed: cycle.passed,
        }
    }

    /// The belt run to the photo-eye and the part picked (`Err` when none arrives).
    fn wait_and_pick(&mut self, model: &CellModel, data: &mut CellData) -> Cycle {
        match data.wait_for_part(model) {
            Ok(stopped_s) => {
                self.pick_time_s = Some(stopped_s);
                self.pick_cycle(model, data, None)
            }
            Err(failure) => self.unreached(model, data, failure),
        }
    }

    /// The single part from the belt into its bin, through the faults the controller can
    /// recover from: a trigger with nothing there is run past, and a part the jaws show
    /// dropped is looked for and picked again.
    fn single_part(&mut self, model: &CellModel, data: &mut CellData) -> Cycle {
        let mut cycle = self.wait_and_pick(model, data);
        let nothing_seen = cycle
            .failure
            .as_ref()
            .is_some_and(|f| f.reason == FailureReason::NotDetected);
        // Nothing seen and the beam clear again: the eye's trigger was false.
        if model.scenario().faults.photo_eye.is_some() && nothing_seen && !data.photo_eye_reports()
        {
            data.faults
                .false_trigger_actions
                .push(FaultAction::IgnoredFalseTrigger);
            cycle = self.wait_and_pick(model, data);
        }
        let cycle = self.index_to_part(model, data, cycle);
        self.recover_grip(model, data, cycle)
    }

    /// A stream trial. A part the jaws dropped is looked for and picked again as in a single
    /// trial; one counted lost is recorded so and the stream goes on with the next item. Any
    /// other failure halts the stream, as a cell does.
    pub(crate) fn run_stream(
        mut self,
        model: &CellModel,
        data: &mut CellData,
        index: u32,
    ) -> TrialRecord {
        let planned = model.scenario().parts_per_trial;
        let mut parts: Vec<StreamPartRecord> = Vec::new();
        let (mut bottles_passed, mut belt_stops) = (0u32, 0u32);
        let (mut touched, mut picked, mut displacement_m) = (false, false, 0.0f64);
        let mut first_stop_s = None;
        let mut halt: Option<Failure> = None;
        let mut passed_tracks = Vec::new();
        self.tracking = Some(stream_tracking(model, data));
        while parts.len() < planned as usize {
            match data.wait_for_part(model) {
                Ok(stopped_s) => self.pick_time_s = Some(stopped_s),
                Err(failure) => {
                    halt = Some(failure);
                    break;
                }
            }
            belt_stops += 1;
            first_stop_s.get_or_insert(self.pick_time_s.unwrap_or(0.0));
            match self.identify_at_eye(model, data) {
                Ok(AtEye::Part(seen)) => {
                    let cycle = self.pick_cycle(model, data, seen.map(|s| *s));
                    // A drop the jaws showed: looked for and picked again, standing or lying;
                    // a part not to be found or picked is counted lost and the stream goes on.
                    let dropped = data.faults.drop_seen.is_some();
                    let cycle = self.recover_grip(model, data, cycle);
                    let lost = dropped && data.faults.counted_lost_last();
                    touched |= cycle.touched;
                    picked |= cycle.picked;
                    displacement_m = displacement_m.max(cycle.displacement_m);
                    if let Some(bin) = cycle.placed_bin_id {
                        data.bin_fill[bin.0] += 1;
                    }
                    let failed = cycle.failure.is_some();
                    let track = self.station_track.take();
                    if let (Some(tracking), Some(track)) = (self.tracking.as_mut(), track) {
                        tracking.tracks.close(track, TrackEnd::Picked);
                    }
                    let mut part = stream_part(count_u32(parts.len()), cycle);
                    part.track = track.map(|t| t.0);
                    parts.push(part);
                    if lost {
                        // What still blocks the eye (the lost part, lying at the station) is
                        // run past it before the next item is waited for.
                        if let Err(failure) = data.let_pass(model) {
                            halt = Some(failure);
                            break;
                        }
                    } else if failed {
                        break;
                    }
                }
                Ok(AtEye::Bottle) => {
                    bottles_passed += 1;
                    passed_tracks.extend(self.station_track.take());
                    if let Err(failure) = data.let_pass(model) {
                        halt = Some(failure);
                        break;
                    }
                }
                Err(failure) => {
                    halt = Some(failure);
                    break;
                }
            }
        }
        let mut collected = Vec::new();
        if halt.is_none()
            && parts.iter().all(|p| p.outcome != Outcome::Failure)
            && let Some(tracking) = &self.tracking
        {
            match tracking.collect(model, data, &passed_tracks) {
                Ok(records) => collected = records,
                Err(failure) => halt = Some(failure),
            }
        }
        let parts_sorted = count_u32(
            parts
                .iter()
                .filter(|p| p.outcome == Outcome::Success)
                .count(),
        );
        let part_fault = parts
            .iter()
            .find(|p| p.outcome == Outcome::Failure)
            .map(|p| {
                (
                    p.failure,
                    format!(
                        "part {} ({}): {}",
                        p.index,
                        p.part.part_type,
                        p.detail.as_deref().unwrap_or("failed")
                    ),
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
        let end = StreamEnd {
            outcome: Outcome::from_failed(failure.is_some()),
            failure,
            detail: detail.map(|d| format!("{parts_sorted}/{planned} parts sorted; {d}")),
            touched,
            picked,
            displacement_mm: displacement_m * 1e3,
            since_s: first_stop_s,
        };
        let stream = StreamRecord {
            parts_planned: planned,
            parts_sorted,
            bottles_passed,
            belt_stops,
            parts,
            misidentified: self.misidentified.take(),
            tracks_opened: self.tracking.as_ref().map_or(0, |t| t.opened()),
            passed_tracks: passed_tracks.iter().map(|t| t.0).collect(),
            collected,
            tracking: false,
        };
        stream_trial_record(data, index, end, stream)
    }
}

/// A failure's reason and detail, as the record keeps them.
fn split(failure: Option<Failure>) -> (Option<FailureReason>, Option<String>) {
    match failure {
        Some(f) => (Some(f.reason), Some(f.detail)),
        None => (None, None),
    }
}

/// One part's line in a stream's record.
fn stream_part(index: u32, cycle: Cycle) -> StreamPartRecord {
    let failed = cycle.failure.is_some();
    let (failure, detail) = split(cycle.failure);
    StreamPartRecord {
        index,
        outcome: Outcome::from_failed(failed),
        failure,
        detail,
        part: cycle.part,
        decision: cycle.decision,
        placed_bin: cycle.placed_bin,
        cycle_time_s: cycle.cycle_time_s,
        grasp: cycle.grasp,
        track: None,
        tracking: None,
    }
}

/// How a stream trial ended, as either stream runner (stop-and-go, tracked) judged it.
pub(super) struct StreamEnd {
    pub(super) outcome: Outcome,
    pub(super) failure: Option<FailureReason>,
    pub(super) detail: Option<String>,
    /// Whether the robot touched, or picked, a bottle.
    pub(super) touched: bool,
    pub(super) picked: bool,
    /// How far the bottles were moved, mm.
    pub(super) displacement_mm: f64,
    /// When the stream's first item stopped or was latched, simulated s (`None`: none was).
    pub(super) since_s: Option<f64>,
}

/// The record of a stream trial that ended as `end`, with its `stream` record; the fault log is
/// closed here.
pub(super) fn stream_trial_record(
    data: &mut CellData,
    index: u32,
    end: StreamEnd,
    stream: StreamRecord,
) -> TrialRecord {
    let faults = data.take_fault_records(end.failure.is_none());
    let sim_time_s = data.cell.world.time_s();
    TrialRecord {
        trial: index,
        seed: data.seed,
        outcome: end.outcome,
        failure: end.failure,
        detail: end.detail,
        part: None,
        decision: None,
        placed_bin: None,
        distractor_touched: end.touched,
        distractor_picked: end.picked,
        distractor_displacement_mm: end.displacement_mm,
        cycle_time_s: end.since_s.map_or(0.0, |t| sim_time_s - t),
        sim_time_s,
        motion: data.motion,
        timing: data.timing.clone(),
        stream: Some(stream),
        grasp: None,
        faults,
        removals: 0,
        passed: None,
    }
}
