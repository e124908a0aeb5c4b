//! Batches of sorting trials: the per-trial record, running trials in parallel and
//! deterministically, streaming them to disk, and the reports built from them.

mod batch_manifest;
mod batch_plan;
mod batch_runner;
mod error;
mod interrupt;
mod junit;
mod merge;
mod progress_bar;
mod report;
mod resume;
mod trial_record;

pub use batch_manifest::{BatchManifest, MANIFEST_FILE};
pub use batch_plan::{BatchPlan, Shard, ShardError, trial_seed};
pub use batch_runner::{
    BatchOptions, BatchSummary, JUNIT_FILE, REPORT_FILE, TRIALS_FILE, run_batch, run_batch_with,
    write_reports,
};
pub use error::BatchError;
pub use interrupt::cancel_on_signals;
pub use junit::{junit_xml, testcase_name, xml_escape};
pub use merge::{MergeError, MergeSummary, merge_shards};
pub use report::{
    AcceptConfusion, BatchReport, CycleTime, ErrorStats, Gate, Metrology, ReportMeta, Sorting,
    StageTiming, StageTimings, StreamSummary, Timing, VerdictCounts, Z95, exit_code, passes_gate,
    wilson_interval,
};
pub use resume::{
    ResumeError, TrialLine, TrialLines, check_prefix, parse_trial_lines, read_manifest,
    read_trial_lines,
};
pub use trial_record::{
    CLEAR_CUT_BAND_MM, DecisionRecord, FailureReason, Outcome, PartRecord, Perception,
    StreamPartRecord, StreamRecord, TrialRecord, TrialTiming,
};

/// Runs one trial of a scenario. Implementations must be deterministic in `(index, seed)`.
pub trait TrialRunner: Sync {
    /// Runs trial `index` with its own `seed` and returns what happened. A failure is a record
    /// with a reason, not an error; a panic inside is caught by the batch and recorded.
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord;
}
