//! When an episode ends, and the judge's record of it: the part at rest in a bin (or fallen
//! outside every bin) and clear of the jaws, a failure of the trial's monitors (time-out,
//! blow-up), or the controller giving up.

use crate::cell::CellModel;
use crate::outcome::{Failure, Outcome, Phase, TrialRecord};
use crate::sim::Tag;
use crate::task::CellData;
use crate::task::judge;

/// A part slower than this counts as at rest, m/s.
const REST_SPEED_M_S: f64 = 0.02;
/// How long the part must rest, clear of the robot, before the trial is judged, s.
const SETTLED_S: f64 = 0.3;
/// A robot collider this close to the part touches it, m.
const TOUCH_DISTANCE_M: f64 = 0.0005;
/// A part this far below the belt's top, outside every bin, has fallen, m.
const FALLEN_BELOW_BELT_M: f64 = 0.05;

/// How an episode ended.
pub(super) enum Ending {
    /// The part came to rest where the judge can look at it.
    Rested,
    /// A monitor of the trial failed it (time-out, non-finite state).
    Failed(Failure),
    /// The controller ended the episode.
    GaveUp,
}

/// Watches a running episode for its end.
#[derive(Default)]
pub(super) struct Watch {
    /// How long the part has rested clear of the robot, s.
    settled_s: f64,
    /// When the belt first stopped with something at the photo-eye, s.
    first_stop_s: Option<f64>,
    /// Whether the bottles' rest poses were noted since the belt last stopped.
    rest_noted: bool,
}

impl Watch {
    /// The phase the records book the coming period to: waiting while the belt runs,
    /// transporting while the robot holds the part off the belt, approaching otherwise.
    pub(super) fn phase(&self, data: &CellData, belt_run: bool) -> Phase {
        if belt_run {
            return Phase::Wait;
        }
        let part = &data.cell.items.parts()[0];
        let lifted = data.cell.body_pose(part.body).is_some_and(|pose| {
            pose.translation.z - part.instance.height_m / 2.0 > data.cell.belt_top_z + 0.005
        });
        if lifted
            && data
                .cell
                .world
                .touches(part.body, Tag::Robot, TOUCH_DISTANCE_M)
        {
            Phase::Transport
        } else {
            Phase::Approach
        }
    }

    /// After a period of `period_s`: notes where the bottles stand once the belt has stopped
    /// (the judge measures their moves from there), and says whether the trial is over.
    pub(super) fn update(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        period_s: f64,
    ) -> Option<Ending> {
        let belt_still = data.belt.target_m_s() == 0.0 && data.cell.conveyor.speed_m_s() == 0.0;
        if !belt_still {
            self.rest_noted = false;
        } else if !self.rest_noted {
            self.rest_noted = true;
            if data.photo_eye_reports() {
                self.first_stop_s.get_or_insert(data.cell.world.time_s());
            }
            data.note_bottle_rest(model);
        }
        let part = &data.cell.items.parts()[0];
        let body = part.body;
        let pose = data.cell.body_pose(body)?;
        let speed_m_s = data
            .cell
            .world
            .physics
            .bodies
            .get(body)
            .map_or(f64::INFINITY, |b| f64::from(b.linvel().length()));
        let clear = !data.cell.world.touches(body, Tag::Robot, TOUCH_DISTANCE_M);
        let fallen = pose.translation.z < data.cell.belt_top_z - FALLEN_BELOW_BELT_M;
        let placed = data.bin_holding(0).is_some();
        if speed_m_s < REST_SPEED_M_S && clear && (placed || fallen) {
            self.settled_s += period_s;
        } else {
            self.settled_s = 0.0;
        }
        (self.settled_s >= SETTLED_S).then_some(Ending::Rested)
    }

    /// The trial's record: the judge's verdict on where the part rests and what happened to
    /// the bottles, as `twincell run` records a single-part trial (without a decision: the
    /// controller's reasons are its own).
    pub(super) fn record(
        &self,
        model: &CellModel,
        data: &mut CellData,
        trial: u32,
        ending: Ending,
    ) -> TrialRecord {
        let (scenario, catalogue) = (model.scenario(), model.catalogue());
        let instance = &data.cell.items.parts()[0].instance;
        let part = judge::part_record(scenario, catalogue, instance);
        let evidence = data.cycle_evidence(0);
        let placed_bin = evidence.placed_bin;
        let controller = match ending {
            Ending::Failed(failure) => Err(failure),
            Ending::Rested | Ending::GaveUp => Ok(()),
        };
        let failure = judge::judge_cycle(scenario, catalogue, &part, controller, &evidence);
        let faults = data.take_fault_records(failure.is_none());
        let sim_time_s = data.cell.world.time_s();
        let (reason, detail) = match failure {
            Some(f) => (Some(f.reason), Some(f.detail)),
            None => (None, None),
        };
        TrialRecord {
            trial,
            seed: data.seed,
            outcome: Outcome::from_failed(reason.is_some()),
            failure: reason,
            detail,
            part: Some(part),
            decision: None,
            placed_bin: placed_bin.map(|b| catalogue.bin_name(b).to_owned()),
            distractor_touched: evidence.bottle_disturbed(scenario),
            distractor_picked: evidence.bottle_lifted,
            distractor_displacement_mm: evidence.bottle_displacement_m * 1e3,
            cycle_time_s: self.first_stop_s.map_or(0.0, |t| sim_time_s - t),
            sim_time_s,
            motion: data.motion,
            timing: data.timing.clone(),
            stream: None,
            grasp: None,
            faults,
            removals: 0,
            passed: None,
        }
    }
}
