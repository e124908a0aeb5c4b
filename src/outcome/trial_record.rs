//! One line of `trials.jsonl`.

use serde::{Deserialize, Serialize};

use super::{FaultRecord, MotionRecord};

/// Where perception's answers came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Perception {
    /// The rendered camera image through detector and metrology (the product).
    Camera,
    /// Ground truth read from the world: for diagnosis only, labelled in every report.
    Oracle,
}

/// How a trial ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// The part ended at rest in the bin the truth calls for, the bottle untouched.
    Success,
    /// Anything else; see the failure reason.
    Failure,
    /// The part was judged unpickable (no safe grasp) and the belt carried it, untouched, into
    /// the collector at its end: safe, but not sorted.
    Passed,
}

impl Outcome {
    /// Success when nothing failed.
    pub fn from_failed(failed: bool) -> Self {
        if failed { Self::Failure } else { Self::Success }
    }

    /// The outcome's name as written in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Success => "success",
            Self::Failure => "failure",
            Self::Passed => "passed",
        }
    }
}

/// A part let through as unpickable: why the cell would not pick it, and where it ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PassedRecord {
    /// The planner's refusal that made the part unpickable.
    pub reason: FailureReason,
    /// The refusal's detail.
    pub detail: String,
    /// The collector the belt carried the part into.
    pub collector: String,
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// Every way a trial can fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureReason {
    /// Perception found no part at the pick station.
    NotDetected,
    /// A grasp or place pose lies outside the arm's workspace.
    Unreachable,
    /// A pose is in the workspace but no joint solution is within limits.
    NoIkSolution,
    /// The planned motion would hit (or did hit) the cell or the bottle.
    Collision,
    /// The part slid out of the fingers while lifted or carried.
    Slipped,
    /// The part fell before reaching a bin.
    Dropped,
    /// The part came to rest in the wrong bin, or outside any bin.
    WrongBin,
    /// The arm or gripper touched or moved the bottle beyond the tolerance.
    DistractorTouched,
    /// The bottle was picked instead of the part.
    DistractorPicked,
    /// A state ran past its time-out.
    Timeout,
    /// The physics state became non-finite.
    PhysicsBlowUp,
    /// The trial's code panicked.
    Panic,
    /// The camera pipeline could not run (no renderer, a detector error).
    PerceptionError,
    /// Perception took a part for a bottle or a bottle for a part at the photo-eye.
    Misidentified,
    /// The cell found no place for the trial's items that the scenario allows (bottles that
    /// fit nowhere on the belt near the part).
    Placement,
}

impl FailureReason {
    /// The reason's name as written in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::NotDetected => "not_detected",
            Self::Unreachable => "unreachable",
            Self::NoIkSolution => "no_ik_solution",
            Self::Collision => "collision",
            Self::Slipped => "slipped",
            Self::Dropped => "dropped",
            Self::WrongBin => "wrong_bin",
            Self::DistractorTouched => "distractor_touched",
            Self::DistractorPicked => "distractor_picked",
            Self::Timeout => "timeout",
            Self::PhysicsBlowUp => "physics_blow_up",
            Self::Panic => "panic",
            Self::PerceptionError => "perception_error",
            Self::Misidentified => "misidentified",
            Self::Placement => "placement",
        }
    }
}

/// The truth about the trial's part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartRecord {
    /// Part type name from the scenario's table.
    pub part_type: String,
    /// True bore out-of-roundness (Rmax - Rmin), mm.
    pub true_roundness_mm: f64,
    /// True mean bore diameter, mm.
    pub true_bore_diameter_mm: f64,
    /// Whether the truth says accept (roundness within tolerance).
    pub truly_acceptable: bool,
    /// Whether the true roundness lies further from the tolerance than the scenario's
    /// `roundness_uncertainty_mm`: a part the sorter must always judge right (closer to the
    /// limit, measurement noise may decide).
    #[serde(default)]
    pub clear_cut: bool,
    /// The bin the truth calls for.
    pub correct_bin: String,
}

/// What perception and the sorter decided.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DecisionRecord {
    /// The detected part type.
    pub detected_type: String,
    /// Measured roundness, mm (None when not measured).
    pub measured_roundness_mm: Option<f64>,
    /// Measured bore diameter, mm.
    pub measured_bore_diameter_mm: Option<f64>,
    /// Accept or reject.
    pub accept: bool,
    /// The bin chosen.
    pub bin: String,
    /// Why perception's answers were overruled (a measured bore that contradicts the detected
    /// type sends the part to the reject bin).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// Wall-clock costs of a trial: the only fields that differ between identical runs.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TrialTiming {
    /// Whole trial, ms.
    pub wall_ms: f64,
    /// Physics stepping, ms.
    pub physics_ms: f64,
    /// Camera rendering, ms.
    pub render_ms: f64,
    /// Detector, ms.
    pub detect_ms: f64,
    /// Metrology, ms.
    pub metrology_ms: f64,
    /// IK, trajectory and collision checks, ms.
    pub planning_ms: f64,
}

/// One trial's result: a line of `trials.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialRecord {
    /// Trial index within the scenario, from 0.
    pub trial: u32,
    /// The trial's own seed (derived from the scenario seed and the index).
    pub seed: u64,
    /// Success or failure.
    pub outcome: Outcome,
    /// Why it failed, when it did.
    pub failure: Option<FailureReason>,
    /// Human-readable detail of the failure (state, values).
    pub detail: Option<String>,
    /// The truth about the part.
    pub part: Option<PartRecord>,
    /// What perception decided.
    pub decision: Option<DecisionRecord>,
    /// The bin the part came to rest in, if any.
    pub placed_bin: Option<String>,
    /// Whether anything of the robot touched the bottle.
    pub distractor_touched: bool,
    /// Whether the bottle was lifted by the gripper.
    pub distractor_picked: bool,
    /// How far the bottle moved, mm.
    pub distractor_displacement_mm: f64,
    /// Simulated time from the part's arrival at the pick station to the arm's retreat, s;
    /// for a stream, from the first stop at the photo-eye to the end of the last cycle.
    pub cycle_time_s: f64,
    /// Simulated time of the whole trial, s.
    pub sim_time_s: f64,
    /// How the arm moved: simulated seconds per phase, measured joint motion, grip drift.
    #[serde(default)]
    pub motion: MotionRecord,
    /// Wall-clock costs (excluded from determinism comparisons).
    pub timing: TrialTiming,
    /// A stream trial's per-part results (absent for single-part trials, whose part is
    /// described by `part`, `decision` and `placed_bin`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream: Option<StreamRecord>,
    /// The grasp planned for a single-part trial's part (absent when none was planned).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grasp: Option<GraspRecord>,
    /// The faults injected into the trial that struck, in the order they struck, with what
    /// the controller did and whether the cell recovered (absent when none struck).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<FaultRecord>,
    /// Bottles the cell removed from the belt into the waste bin to free the part (absent when
    /// none).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub removals: u32,
    /// Why the part was let through to the collector, when it was (the outcome is then
    /// `passed`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passed: Option<PassedRecord>,
}

/// The grasp the planner chose for a part.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspRecord {
    /// Smallest clearance of the robot to the obstacles along descent, grasp and lift, mm; the
    /// search counts every grasp past 20 mm as equally clear, so 20 is its most.
    pub clearance_mm: f64,
    /// How many candidate grasps the search weighed.
    pub candidates: u32,
}

/// What happened to one part of a stream.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StreamPartRecord {
    /// The part's place in the stream, from 0.
    pub index: u32,
    /// Success (sorted into its correct bin) or failure.
    pub outcome: Outcome,
    /// Why it failed, when it did.
    pub failure: Option<FailureReason>,
    /// Human-readable detail of the failure.
    pub detail: Option<String>,
    /// The truth about the part.
    pub part: PartRecord,
    /// What perception decided.
    pub decision: Option<DecisionRecord>,
    /// The bin the part came to rest in, if any.
    pub placed_bin: Option<String>,
    /// Simulated time from the belt's stop for this part to the arm's return home, s.
    pub cycle_time_s: f64,
    /// The grasp planned for it (absent when none was planned).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grasp: Option<GraspRecord>,
    /// The track by which the cell knew it at the pick station (absent when it had none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub track: Option<u32>,
    /// How the arm met it on the moving belt (conveyor tracking only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracking: Option<PartTracking>,
}

/// A part picked from the moving belt (`conveyor.tracking`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PartTracking {
    /// From the photo-eye's latch of the part to the jaws closed on it, s.
    pub latch_to_grasp_s: f64,
    /// The TCP's distance across the belt's top from the part's true axis when the jaws began
    /// to close, mm.
    pub tracking_error_mm: f64,
    /// The largest move of the part in the jaws from where they closed on it, through lift,
    /// transport and place, mm.
    pub jaw_drift_mm: f64,
    /// Times the belt was held stopped for this part: the busy arm could not have met it
    /// before it left the pick window.
    #[serde(default)]
    pub belt_holds: u32,
    /// How long the belt stood held (braking included) for this part, s.
    #[serde(default)]
    pub belt_hold_s: f64,
}

/// A stream trial: the parts fed, what became of each, and the belt's stops.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StreamRecord {
    /// Parts the feeder was to put on the belt.
    pub parts_planned: u32,
    /// Parts sorted into their correct bins.
    pub parts_sorted: u32,
    /// Bottles that reached the photo-eye and were let through.
    pub bottles_passed: u32,
    /// Times the belt stopped at the photo-eye (a tracking stream: times it was held for a part).
    pub belt_stops: u32,
    /// Every part that reached the pick station, in order (a stream halts at its first fault,
    /// as a cell stops on a fault, so later parts are not listed).
    pub parts: Vec<StreamPartRecord>,
    /// The item at the photo-eye that the camera took for something else (the stream halts
    /// there); absent when there was none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub misidentified: Option<Misidentification>,
    /// Tracks the cell opened on the belt: every item it saw, each once.
    #[serde(default)]
    pub tracks_opened: u32,
    /// The tracks of the bottles let through at the photo-eye, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub passed_tracks: Vec<u32>,
    /// What reached the scenario's collector at the belt's end, each with the track the cell
    /// matched it to (absent without a collector, or when nothing reached it).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub collected: Vec<CollectedRecord>,
    /// Picked from a belt that never stopped (`conveyor.tracking`).
    #[serde(default, skip_serializing_if = "is_false")]
    pub tracking: bool,
}

fn is_false(flag: &bool) -> bool {
    !*flag
}

impl StreamRecord {
    /// Items the cell took for something they were not: the one at the photo-eye that halted
    /// the stream, and each item in the collector that no track of the cell's expected there,
    /// or that its track had been seen as something else.
    pub fn misidentified_items(&self) -> u32 {
        let collected = self.collected.iter().filter(|c| {
            let kind = if c.truth == "bottle" {
                "bottle"
            } else {
                "part"
            };
            c.truth != "none" && c.seen_as.as_deref() != Some(kind)
        });
        u32::from(self.misidentified.is_some())
            + u32::try_from(collected.count()).unwrap_or(u32::MAX)
    }
}

/// An item that reached the collector, and the track the cell matched it to by the encoder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CollectedRecord {
    /// What it was: a part type's name or `bottle`.
    pub truth: String,
    /// The track whose prediction had carried it off the belt's end when it was found there,
    /// nearest first (absent when no track had).
    pub track: Option<u32>,
    /// What that track had been seen as: `part` or `bottle`.
    pub seen_as: Option<String>,
}

/// An item at the photo-eye taken for something it is not.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Misidentification {
    /// What stood there: a part type's name or `bottle`.
    pub truth: String,
    /// What the camera took it for: a part type's name or `bottle`.
    pub identified: String,
    /// The track the cell took for the item at the photo-eye (absent when it had none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub track: Option<u32>,
}

/// One part of a trial as every reader of records sees it: a single-part trial is a list of
/// one, a stream lists each part that reached the pick station.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartOutcome<'a> {
    /// The part's place in the trial, from 0.
    pub index: u32,
    /// Success (sorted into its correct bin) or failure.
    pub outcome: Outcome,
    /// Why it failed, when it did.
    pub failure: Option<FailureReason>,
    /// The truth about the part.
    pub part: &'a PartRecord,
    /// What perception decided.
    pub decision: Option<&'a DecisionRecord>,
    /// The bin the part came to rest in, if any.
    pub placed_bin: Option<&'a str>,
    /// Simulated time of the part's pick cycle, s.
    pub cycle_time_s: f64,
}

impl PartOutcome<'_> {
    /// Whether the part came to rest in the bin the truth calls for.
    pub fn in_correct_bin(&self) -> bool {
        self.placed_bin == Some(self.part.correct_bin.as_str())
    }
}

impl TrialRecord {
    /// The trial's parts, in order: one for a single-part trial that got as far as drawing its
    /// part, each part that reached the pick station for a stream.
    pub fn parts(&self) -> Vec<PartOutcome<'_>> {
        match (&self.stream, &self.part) {
            (Some(stream), _) => stream
                .parts
                .iter()
                .map(|p| PartOutcome {
                    index: p.index,
                    outcome: p.outcome,
                    failure: p.failure,
                    part: &p.part,
                    decision: p.decision.as_ref(),
                    placed_bin: p.placed_bin.as_deref(),
                    cycle_time_s: p.cycle_time_s,
                })
                .collect(),
            (None, Some(part)) => vec![PartOutcome {
                index: 0,
                outcome: self.outcome,
                failure: self.failure,
                part,
                decision: self.decision.as_ref(),
                placed_bin: self.placed_bin.as_deref(),
                cycle_time_s: self.cycle_time_s,
            }],
            (None, None) => Vec::new(),
        }
    }

    /// A failed trial that got no further than `reason`.
    pub fn failed(index: u32, seed: u64, reason: FailureReason, detail: impl Into<String>) -> Self {
        Self {
            trial: index,
            seed,
            outcome: Outcome::Failure,
            failure: Some(reason),
            detail: Some(detail.into()),
            part: None,
            decision: None,
            placed_bin: None,
            distractor_touched: false,
            distractor_picked: false,
            distractor_displacement_mm: 0.0,
            cycle_time_s: 0.0,
            sim_time_s: 0.0,
            motion: MotionRecord::default(),
            timing: TrialTiming::default(),
            stream: None,
            grasp: None,
            faults: Vec::new(),
            removals: 0,
            passed: None,
        }
    }
}
