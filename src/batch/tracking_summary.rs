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
    /// Parts the arm grasped from the belt (moving, or standing on a held belt).
    pub parts_grasped: u32,
    /// Times the belt was held stopped for a part the busy arm could not otherwise have
    /// picked before it left the pick window.
    #[serde(default)]
    pub belt_holds: u32,
    /// Parts the belt was held for.
    #[serde(default)]
    pub parts_held: u32,
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
        let (mut holds, mut held) = (0u32, 0u32);
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
                    holds += t.belt_holds;
                    held += u32::from(t.belt_holds > 0);
                }
                if let Some(t) = part
                    .tracking
                    .as_ref()
                    .filter(|_| part.outcome != Outcome::Passed)
                {
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
            belt_holds: holds,
            parts_held: held,
            latch_to_grasp_s: MeanMax::of(&latch),
            tracking_error_mm: MeanMax::of(&error),
            jaw_drift_mm: MeanMax::of(&drift),
            joint_limit_margin_rad: margin,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outcome::{FailureReason, PartRecord, PartTracking, StreamPartRecord, StreamRecord};

    fn part(index: u32, outcome: Outcome, tracking: Option<PartTracking>) -> StreamPartRecord {
        StreamPartRecord {
            index,
            outcome,
            failure: None,
            detail: None,
            part: PartRecord {
                part_type: "axle_a20".into(),
                true_roundness_mm: 0.1,
                true_bore_diameter_mm: 20.0,
                truly_acceptable: true,
                clear_cut: true,
                correct_bin: "group_a".into(),
            },
            decision: None,
            placed_bin: None,
            cycle_time_s: 0.0,
            grasp: None,
            track: None,
            tracking,
        }
    }

    fn stream(tracking: bool, parts: Vec<StreamPartRecord>, margin: f64) -> TrialRecord {
        let mut record = TrialRecord::failed(0, 1, FailureReason::Timeout, "");
        record.motion.joint_limit_margin_rad = margin;
        let sorted = parts
            .iter()
            .filter(|p| p.outcome == Outcome::Success)
            .count();
        record.stream = Some(StreamRecord {
            parts_planned: 4,
            parts_sorted: sorted as u32,
            bottles_passed: 0,
            belt_stops: 0,
            parts,
            misidentified: None,
            tracks_opened: 0,
            passed_tracks: Vec::new(),
            collected: Vec::new(),
            tracking,
        });
        record
    }

    #[test]
    fn only_tracking_streams_count_and_their_figures_are_means_and_maxima() {
        let met = |latch, error, drift| {
            Some(PartTracking {
                latch_to_grasp_s: latch,
                tracking_error_mm: error,
                jaw_drift_mm: drift,
                ..PartTracking::default()
            })
        };
        // Held for and picked standing; held for and then not pickable where it stood.
        let held = Some(PartTracking {
            latch_to_grasp_s: 2.0,
            tracking_error_mm: 1.5,
            jaw_drift_mm: 0.4,
            belt_holds: 2,
            belt_hold_s: 3.0,
        });
        let held_passed = Some(PartTracking {
            belt_holds: 1,
            belt_hold_s: 1.0,
            ..PartTracking::default()
        });
        let tracked = stream(
            true,
            vec![
                part(0, Outcome::Success, met(1.0, 0.5, 0.2)),
                part(1, Outcome::Passed, None),
                part(2, Outcome::Success, held),
                part(3, Outcome::Passed, held_passed),
            ],
            0.3,
        );
        let stop_and_go = stream(false, vec![part(0, Outcome::Success, None)], -0.5);
        assert_eq!(
            TrackingSummary::of(std::slice::from_ref(&stop_and_go)),
            None
        );
        let Some(summary) = TrackingSummary::of(&[tracked, stop_and_go]) else {
            panic!("no summary");
        };
        assert_eq!(summary.sorted_share, 0.5);
        assert_eq!(summary.parts_unpicked, 2);
        assert_eq!(summary.parts_grasped, 2);
        assert_eq!((summary.belt_holds, summary.parts_held), (3, 2));
        assert_eq!(
            summary.latch_to_grasp_s,
            MeanMax {
                mean: 1.5,
                max: 2.0
            }
        );
        assert_eq!(
            summary.tracking_error_mm,
            MeanMax {
                mean: 1.0,
                max: 1.5
            }
        );
        assert!((summary.jaw_drift_mm.max - 0.4).abs() < 1e-12);
        // The stop-and-go trial's margin is not the tracking streams'.
        assert_eq!(summary.joint_limit_margin_rad, 0.3);
    }
}
