//! Batches of sorting trials: running trials in parallel and deterministically, streaming their
//! records (`crate::outcome`) to disk, and the reports built from them.

mod batch_listing;
mod batch_manifest;
mod batch_plan;
mod batch_runner;
mod error;
mod html;
mod html_faults;
mod html_plots;
mod html_trials;
mod interrupt;
mod junit;
mod merge;
mod progress_bar;
mod report;
#[cfg(test)]
mod report_tests;
mod resume;
mod suite;
mod summary_table;
mod sweep;
mod trial_images;
mod tracking_summary;
mod trial_summary;

pub use crate::outcome::{
    DecisionRecord, FailureReason, Misidentification, Outcome, PartRecord, Perception,
    StreamPartRecord, StreamRecord, TrialRecord, TrialRunner, TrialTiming,
};

pub use batch_listing::{BOTTLE, BatchListing, NOT_DETECTED};
pub use batch_manifest::{BatchManifest, MANIFEST_FILE};
pub use batch_plan::{BatchPlan, Shard, ShardError, trial_seed};
pub use batch_runner::{
    BatchOptions, BatchSummary, JUNIT_FILE, REPORT_FILE, TRIALS_FILE, run_batch, run_batch_with,
    write_reports,
};
pub use error::BatchError;
pub use html::{HTML_FILE, HtmlError, HtmlPage, PageBatch, RoundnessLimits};
pub use html_trials::{CardImage, PageSorting, TrialCard};
pub use interrupt::cancel_on_signals;
pub use junit::{junit_xml, testcase_name, xml_escape};
pub use merge::{MergeError, MergeSummary, merge_shards};
pub use report::{
    AcceptConfusion, BandCounts, BatchReport, CycleTime, ErrorStats, Gate, Metrology, ReportMeta,
    Sorting, StageTiming, StageTimings, StreamSummary, Timing, VerdictCounts, Z95, exit_code,
    passes_gate, wilson_interval,
};
pub use resume::{
    ResumeError, TrialLine, TrialLines, check_prefix, parse_trial_lines, read_manifest,
    read_trial_lines,
};
pub use suite::{BatchRow, SuiteReport, write_json_report};
pub use sweep::{SweepAxisReport, SweepPoint, SweepReport};
pub use tracking_summary::{MeanMax, TrackingSummary};
pub use trial_images::{
    IMAGES_DIR, THUMBNAIL_WIDTH_PX, TrialImages, annotated_thumbnail, copy_trial_images,
    decision_misjudged, remove_trial_images, trial_image_path, wants_image,
};
pub use trial_summary::TrialSummary;
