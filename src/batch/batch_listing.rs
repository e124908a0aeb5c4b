//! What `junit.xml` and `report.html` show of a batch beyond `report.json`'s figures: built
//! from the records together with those figures, and kept in the [`BatchReport`] but not
//! written into `report.json`.
//!
//! [`BatchReport`]: super::BatchReport

use std::collections::BTreeMap;

use super::trial_summary::TrialSummary;
use super::{FailureReason, Outcome, TrialRecord};

/// The label of an item nothing was detected for, in the type matrix.
pub const NOT_DETECTED: &str = "not detected";
/// The label of the bottle, a true item and a detector class.
pub const BOTTLE: &str = "bottle";

/// A batch's trials and parts as the JUnit file and the report page list them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BatchListing {
    /// Every trial, in the records' order.
    pub trials: Vec<TrialSummary>,
    /// The pick cycle of every sorted part (a successful single-part trial's part, each
    /// sorted part of a stream), ascending, s: the values `report.json`'s `cycle_time_s`
    /// summarises.
    pub sorted_cycle_times_s: Vec<f64>,
    /// True item (part type or `bottle`) -> what perception took it for (a part type,
    /// `bottle`, or `not detected`) -> count: every decided part, a single part not detected,
    /// a stream's bottles let through and its item taken for something else.
    pub identified: BTreeMap<String, BTreeMap<String, u32>>,
    /// `[true, measured]` roundness of every measured part, mm, with whether its verdict was
    /// the true one; in the records' order.
    pub roundness_mm: Vec<([f64; 2], bool)>,
}

impl BatchListing {
    /// The listing of `records`.
    pub fn of(records: &[TrialRecord]) -> Self {
        let mut listing = Self {
            trials: records.iter().map(TrialSummary::of).collect(),
            ..Self::default()
        };
        for record in records {
            listing.add(record);
        }
        listing.sorted_cycle_times_s.sort_by(f64::total_cmp);
        listing
    }

    fn add(&mut self, record: &TrialRecord) {
        for p in record.parts() {
            if p.outcome == Outcome::Success {
                self.sorted_cycle_times_s.push(p.cycle_time_s);
            }
            let Some(decision) = p.decision else {
                continue;
            };
            self.add_identified(&p.part.part_type, &decision.detected_type, 1);
            if let Some(measured) = decision.measured_roundness_mm {
                let right = decision.accept == p.part.truly_acceptable;
                self.roundness_mm
                    .push(([p.part.true_roundness_mm, measured], right));
            }
        }
        if let (Some(part), None, Some(FailureReason::NotDetected)) =
            (&record.part, &record.decision, record.failure)
        {
            self.add_identified(&part.part_type, NOT_DETECTED, 1);
        }
        if let Some(stream) = &record.stream {
            self.add_identified(BOTTLE, BOTTLE, stream.bottles_passed);
            if let Some(m) = &stream.misidentified {
                self.add_identified(&m.truth, &m.identified, 1);
            }
        }
    }

    fn add_identified(&mut self, truth: &str, identified: &str, n: u32) {
        if n > 0 {
            *self
                .identified
                .entry(truth.to_owned())
                .or_default()
                .entry(identified.to_owned())
                .or_default() += n;
        }
    }
}
