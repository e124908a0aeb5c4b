//! The figures of streams picked from a moving belt (`conveyor.tracking`), over a batch's
//! records: the share of the parts fed that were sorted, the parts that rode on unpicked, and
//! per part picked the latch-to-grasp time, the tracking error at the grasp and the drift in
//! the jaws; and the least joint-limit margin over every tracking trial.

use serde::{Deserialize, Serialize};

use super::{Outcome, TrialRecord};

/// Mean and largest of a per-part figure.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct MeanMax {
    /// Mean over the parts picked.
    pub mean: f64,
    /// Largest.
    pub max: f64,
}

impl MeanMax {
    fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        Self {
            mean: values.iter().sum::<f64>() / values.len() as f64,
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

/// A batch's conveyor-tracking figures.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackingSummary {
    /// Parts sorted into their correct bins over parts fed.
    pub sorted_share: f64,
    /// Parts that rode on unpicked: the arm could not meet them in the pick window.
    pub parts_unpicked: u32,
    /// Parts the arm grasped on the moving belt.
    pub parts_grasped: u32,
    /// From the photo-eye's latch to the jaws closed, s.
    pub latch_to_grasp_s: MeanMax,
    /// The TCP's distance from the part's axis as the jaws began to close, mm.
    pub tracking_error_mm: MeanMax,
    /// The part's largest move in the jaws, mm.
    pub jaw_drift_mm: MeanMax,
    /// The least margin of any joint to its limit, measured over every tracking trial, rad
    /// (negative: a joint went past its limit).
    pub joint_limit_margin_rad: f64,
}

impl TrackingSummary {
    /// The figures of `records`' tracking streams; `None` when none tracked.
    pub fn of(records: &[TrialRecord]) -> Option<Self> {
        let tracked: Vec<&TrialRecord> = records
            .iter()
            .filter(|r| r.stream.as_ref().is_some_and(|s| s.tracking))
            .collect();
        if tracked.is_empty() {
            return None;
        }
        let (mut planned, mut sorted, mut unpicked) = (0u32, 0u32, 0u32);
        let (mut latch, mut error, mut drift) = (Vec::new(), Vec::new(), Vec::new());
        let mut margin = f64::INFINITY;
        for record in &tracked {
            let Some(stream) = &record.stream else {
                continue;
            };
            planned += stream.parts_planned;
            sorted += stream.parts_sorted;
            for part in &stream.parts {
                if part.outcome == Outcome::Passed {
                    unpicked += 1;
                }
                if let Some(t) = &part.tracking {
                    latch.push(t.latch_to_grasp_s);
                    error.push(t.tracking_error_mm);
                    drift.push(t.jaw_drift_mm);
                }
            }
            margin = margin.min(record.motion.joint_limit_margin_rad);
        }
        Some(Self {
            sorted_share: if planned > 0 {
                f64::from(sorted) / f64::from(planned)
            } else {
                0.0
            },
            parts_unpicked: unpicked,
            parts_grasped: u32::try_from(latch.len()).unwrap_or(u32::MAX),
            latch_to_grasp_s: MeanMax::of(&latch),
            tracking_error_mm: MeanMax::of(&error),
            jaw_drift_mm: MeanMax::of(&drift),
            joint_limit_margin_rad: margin,
        })
    }
}
