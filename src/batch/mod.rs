//! Batches of sorting trials: the per-trial record, running trials in parallel and
//! deterministically, streaming them to disk, and the reports built from them.

mod trial_record;

pub use trial_record::{
    DecisionRecord, FailureReason, Outcome, PartRecord, Perception, TrialRecord, TrialTiming,
};

/// Runs one trial of a scenario. Implementations must be deterministic in `(index, seed)`.
pub trait TrialRunner: Sync {
    /// Runs trial `index` with its own `seed` and returns what happened. A failure is a record
    /// with a reason, not an error; a panic inside is caught by the batch and recorded.
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord;
}
