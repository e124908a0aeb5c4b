//! A failure as a stage reports it: the reason a report counts, and the detail a person reads.

use super::FailureReason;

/// Why a step of a trial failed, with its detail.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    /// The reason, as counted in reports.
    pub reason: FailureReason,
    /// What happened, with the values involved.
    pub detail: String,
}

impl Failure {
    /// A failure for `reason` with `detail`.
    pub fn new(reason: FailureReason, detail: impl Into<String>) -> Self {
        Self {
            reason,
            detail: detail.into(),
        }
    }
}

/// `Err` of a [`Failure`] for `reason` with `detail`.
pub fn fail<T>(reason: FailureReason, detail: impl Into<String>) -> Result<T, Failure> {
    Err(Failure::new(reason, detail))
}
