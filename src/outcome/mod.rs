//! What a trial produces: its record (a line of `trials.jsonl`) and the runner that makes one.
//! Below the cell, the task layer and the batch driver, which all speak these types.

mod failure;
mod fault_record;
mod motion_record;
mod phase;
mod trial_record;

pub use failure::{Failure, fail};
pub use fault_record::{FaultAction, FaultKind, FaultRecord, FaultTally, LyingPartRecord};
pub use motion_record::MotionRecord;
pub use phase::{PHASE_COUNT, Phase, PhaseSeconds};
pub use trial_record::{
    CollectedRecord, DecisionRecord, FailureReason, GraspRecord, Misidentification, Outcome,
    PartOutcome, PartRecord, PartTracking, PassedRecord, Perception, StreamPartRecord,
    StreamRecord, TrialRecord, TrialTiming,
};

/// Runs one trial of a scenario. Implementations must be deterministic in `(index, seed)`.
pub trait TrialRunner: Sync {
    /// Runs trial `index` with its own `seed` and returns what happened. A failure is a record
    /// with a reason, not an error; a panic inside is caught by the batch and recorded.
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord;
}
