//! Rerun recordings of trials (`twincell run --record FILE.rrd` or `--connect`): a
//! [`crate::task::TrialObserver`] that logs what the cell does, for the Rerun viewer of the
//! matching version (0.36).
//!
//! One recording holds a whole batch. Every trial lives under its own entity path, so trials
//! that ran at the same time on different threads do not mix, and the recording holds the same
//! data whatever `--jobs` was (only the order of its messages differs):
//!
//! - `trials/NNNN/cell`: the cell in 3D (z up): every collider's mesh, the part's true bore, the
//!   bottle; the arm's links, the jaws, parts and bottles move on the `sim_time` timeline.
//! - `trials/NNNN/cell/camera`: the scenario's camera (pose and intrinsics) and, when perception
//!   reports, its `image` with `detections`, `bore_contours`, `bore_circles` (labelled measured
//!   against true roundness and diameter) and `bore_centres`.
//! - `trials/NNNN/joints_rad`: the six measured joint angles; `trials/NNNN/gripper/opening_mm`,
//!   `grip_force_n` (each jaw's contact force on parts) and `force_limit_n` (the drive's limit).
//! - `trials/NNNN/log`: the phases, the parts fed, and the trial's outcome.
//! - `outcomes`: every trial's outcome, on the `trial` timeline.
//! - `metrology/roundness_mm/{measured,true}` and `metrology/bore_diameter_mm/{measured,true}`:
//!   per part, on the `part` timeline (trial index times parts per trial, plus the part's index).
//!
//! Timelines: `sim_time` (each trial's simulated time from its start), `trial` (the trial's
//! index) and `part`. The wall-clock `log_time` timeline is left out.

mod convert;
mod recorder;
mod trial_recording;

pub use recorder::{APPLICATION_ID, DEFAULT_VIEWER_ADDR, RecordError, RerunRecorder};
pub use trial_recording::TrialRecording;

/// The timeline of each trial's simulated time.
pub const SIM_TIME: &str = "sim_time";
/// The timeline of trial indices.
pub const TRIAL_TIMELINE: &str = "trial";
/// The timeline of part indices (for metrology across trials).
pub const PART_TIMELINE: &str = "part";
/// Entity of the trials' outcomes.
pub const OUTCOMES: &str = "outcomes";
/// Entity under which measured and true metrology is logged.
pub const METROLOGY: &str = "metrology";

/// The entity path under which trial `trial_index` is recorded.
pub fn trial_root(trial_index: u32) -> String {
    format!("trials/{trial_index:04}")
}
