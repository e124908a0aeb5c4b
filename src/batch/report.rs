//! `report.json`: the statistics of a batch, built from its trial records alone.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::batch_listing::BatchListing;
use super::tracking_summary::TrackingSummary;
use super::{Outcome, Perception, Shard, TrialRecord, TrialTiming};
use crate::outcome::{FaultKind, FaultTally};
use crate::scenario::UNIDENTIFIED;

/// z for a two-sided 95 % interval.
pub const Z95: f64 = 1.959964;

/// Wilson score interval `[low, high]` for `successes` out of `trials` at normal quantile `z`.
///
/// `[0, 1]` when there are no trials: nothing is known.
pub fn wilson_interval(successes: u32, trials: u32, z: f64) -> [f64; 2] {
    if trials == 0 {
        return [0.0, 1.0];
    }
    let n = f64::from(trials);
    let p = f64::from(successes.min(trials)) / n;
    let z2 = z * z;
    let denom = 1.0 + z2 / n;
    let centre = (p + z2 / (2.0 * n)) / denom;
    let half = z * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt() / denom;
    [(centre - half).max(0.0), (centre + half).min(1.0)]
}

/// Whether `success_rate` passes a `--min-success` gate (always, when there is none).
pub fn passes_gate(success_rate: f64, min_success: Option<f64>) -> bool {
    min_success.is_none_or(|min| success_rate >= min)
}

/// The process exit code for a finished batch: 0 when it completed and passed its gate, else 1.
///
/// An interrupted batch exits 1 even without a gate: its statistics cover only part of the
/// planned trials, so it must not read as a pass to a script or CI job.
pub fn exit_code(report: &BatchReport) -> u8 {
    let gate_ok = report.gate.as_ref().is_none_or(|gate| gate.passed);
    if gate_ok && !report.interrupted { 0 } else { 1 }
}

/// What a report says about its batch besides the records: identity, shard, how it ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReportMeta {
    /// Scenario name.
    pub scenario: String,
    /// Scenario seed.
    pub seed: u64,
    /// Perception mode.
    pub perception: Perception,
    /// Trials of the whole scenario (`--trials`), before sharding.
    pub scenario_trials: u32,
    /// The shard these records are, if any.
    pub shard: Option<Shard>,
    /// Whether the batch stopped early on a cancellation.
    pub interrupted: bool,
    /// The `--min-success` gate, if any.
    pub min_success: Option<f64>,
}

/// Absolute-error statistics of one measured quantity, mm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Trials with both a measured and a true value.
    pub count: u32,
    /// Mean absolute error, mm.
    pub mean_mm: f64,
    /// 95th percentile (nearest rank) of the absolute error, mm.
    pub p95_mm: f64,
    /// Largest absolute error, mm.
    pub max_mm: f64,
}

/// Measured vs true bore geometry over the trials that have both a part and a decision.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrology {
    /// Trials with both a part and a decision.
    pub count: u32,
    /// |measured - true| roundness; `null` when nothing was measured.
    pub roundness_error_mm: Option<ErrorStats>,
    /// |measured - true| mean bore diameter; `null` when nothing was measured.
    pub bore_diameter_error_mm: Option<ErrorStats>,
}

/// Counts of decided verdicts for one true verdict.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct VerdictCounts {
    /// Decided accept.
    pub accept: u32,
    /// Decided reject.
    pub reject: u32,
}

/// Accept/reject confusion matrix: true verdict (outer) vs decided verdict (inner).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AcceptConfusion {
    /// Parts the truth accepts.
    pub truly_accept: VerdictCounts,
    /// Parts the truth rejects.
    pub truly_reject: VerdictCounts,
}

/// How the sorter's decisions compare with the truth.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sorting {
    /// Trials with both a part and a decision.
    pub count: u32,
    /// True accept/reject vs decided accept/reject.
    pub accept_reject: AcceptConfusion,
    /// True part type -> detected type -> count (`unidentified` for a part no type, or
    /// several, fit by measurement).
    pub part_type: BTreeMap<String, BTreeMap<String, u32>>,
    /// Parts whose type no catalogue type, or more than one, fit by measurement (rejected).
    #[serde(default)]
    pub unidentified: u32,
    /// Parts whose true roundness lies outside the band around the tolerance.
    pub clear_cut: u32,
    /// Of those, the ones judged wrong (accepted out of tolerance or rejected within it).
    pub clear_cut_misjudged: u32,
    /// Parts whose true roundness lies inside the band (the scenario's
    /// `roundness_uncertainty_mm` about the tolerance), where either verdict counts as right.
    #[serde(default)]
    pub in_band: BandCounts,
}

/// Parts inside the uncertainty band around the tolerance, and how the sorter decided them.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BandCounts {
    /// Parts inside the band.
    pub parts: u32,
    /// Of those, the ones the truth accepts (within the tolerance).
    pub truly_acceptable: u32,
    /// Decided accept.
    pub accepted: u32,
    /// Decided reject.
    pub rejected: u32,
}

/// Simulated cycle-time statistics over the sorted parts (a successful single-part trial's
/// part, each sorted part of a stream), s.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CycleTime {
    /// Sorted parts counted.
    pub count: u32,
    /// Mean, s.
    pub mean: f64,
    /// Median (nearest rank), s.
    pub p50: f64,
    /// 95th percentile (nearest rank), s.
    pub p95: f64,
}

/// Wall-clock cost of one stage summed over the trials.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTiming {
    /// Sum over trials, s.
    pub total_s: f64,
    /// Mean per trial, ms.
    pub mean_ms: f64,
}

/// Per-stage wall-clock sums and means from the records' `timing` (not deterministic).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTimings {
    /// Whole trial.
    pub trial: StageTiming,
    /// Physics stepping.
    pub physics: StageTiming,
    /// Camera rendering.
    pub render: StageTiming,
    /// Detector.
    pub detect: StageTiming,
    /// Metrology.
    pub metrology: StageTiming,
    /// IK, trajectories, collision checks.
    pub planning: StageTiming,
}

/// Wall-clock figures: the only part of a report that differs between identical runs.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Per-stage sums and means.
    pub stages: StageTimings,
    /// Elapsed time of the batch itself, s (absent for merged reports).
    pub batch_wall_s: Option<f64>,
    /// Worker threads used (absent for merged reports).
    pub jobs: Option<usize>,
}

/// The `--min-success` gate and its verdict.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gate {
    /// Least success rate that passes.
    pub min_success: f64,
    /// Whether `success_rate >= min_success` (an interrupted batch still fails its exit code).
    pub passed: bool,
}

/// Parts of stream trials, counted part by part.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StreamSummary {
    /// Parts the feeders were to put on the belt.
    pub parts_planned: u32,
    /// Parts that reached the pick station.
    pub parts_reached: u32,
    /// Parts sorted into their correct bins.
    pub parts_sorted: u32,
    /// Failure reason -> parts.
    pub part_failures: BTreeMap<String, u32>,
    /// Bottles let through at the photo-eye.
    pub bottles_passed: u32,
    /// Times a belt stopped at the photo-eye.
    pub belt_stops: u32,
    /// Items the cell took for something they were not (a part for a bottle, a bottle for a
    /// part, or another item for the one at the photo-eye), over all stream trials.
    #[serde(default)]
    pub misidentified_items: u32,
    /// Streams picked from a moving belt (`conveyor.tracking`): their figures; absent when
    /// none was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracking: Option<TrackingSummary>,
}

/// The contents of `report.json`, and the listing of trials and parts that `junit.xml` and
/// `report.html` show with it: the one source every report of a batch is rendered from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatchReport {
    /// Scenario name.
    pub scenario: String,
    /// Scenario seed.
    pub seed: u64,
    /// Perception mode: `camera` is the product, `oracle` is ground truth for diagnosis.
    pub perception: Perception,
    /// What the perception mode means for these numbers, in words.
    pub perception_note: String,
    /// Trials of the whole scenario (`--trials`), before sharding.
    pub scenario_trials: u32,
    /// The shard these records are, or `null` for a whole or merged batch.
    pub shard: Option<Shard>,
    /// Whether the batch stopped early; the statistics then cover the finished trials only.
    pub interrupted: bool,
    /// Trials recorded.
    pub trials: u32,
    /// Successful trials.
    pub successes: u32,
    /// `successes / trials` (0 when there are no trials).
    pub success_rate: f64,
    /// Wilson score 95 % interval of the success rate, `[low, high]`.
    pub wilson95: [f64; 2],
    /// Successful trials whose every part also reached the very bin its true roundness calls
    /// for: success judged against the truth with no uncertainty band.
    #[serde(default)]
    pub strict_successes: u32,
    /// `strict_successes / trials`.
    #[serde(default)]
    pub strict_success_rate: f64,
    /// Trials whose part was let through to the collector as unpickable (neither a success
    /// nor a failure).
    #[serde(default)]
    pub passed: u32,
    /// `passed / trials`.
    #[serde(default)]
    pub passed_rate: f64,
    /// Trials that ended safe: sorted or passed, with no collision, nothing dropped and no
    /// bottle touched except by a planned removal.
    #[serde(default)]
    pub safe: u32,
    /// `safe / trials`.
    #[serde(default)]
    pub safe_rate: f64,
    /// Bottles removed into the waste bin, over all trials.
    #[serde(default)]
    pub removals: u32,
    /// Failure reason -> count.
    pub failures: BTreeMap<String, u32>,
    /// Trials in which the bottle was picked.
    pub distractor_picks: u32,
    /// Trials in which the robot touched the bottle.
    pub distractor_touches: u32,
    /// Largest bottle displacement over the trials, mm.
    pub distractor_max_displacement_mm: f64,
    /// Measured vs true bore geometry.
    pub metrology: Metrology,
    /// Decisions vs truth.
    pub sorting: Sorting,
    /// Simulated pick cycle of the sorted parts; `null` when none was sorted.
    pub cycle_time_s: Option<CycleTime>,
    /// Sorted parts per minute of simulated cycle time: `sorted parts / (sum over all
    /// recorded trials of cycle_time_s / 60)`, a trial's `cycle_time_s` being a stream's whole
    /// run. Failed trials count in the denominator
    /// because they occupy the cell too; `null` when the summed cycle time is 0.
    pub parts_per_minute: Option<f64>,
    /// Per-part figures of stream trials; absent when no trial was a stream.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream: Option<StreamSummary>,
    /// Per fault kind that struck: faults injected, recovered from, and parts lost to them;
    /// absent when no fault struck.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub faults: BTreeMap<FaultKind, FaultTally>,
    /// The `--min-success` gate, if any.
    pub gate: Option<Gate>,
    /// Wall-clock figures (not deterministic).
    pub timing: Timing,
    /// The trials and parts behind the figures, for `junit.xml` and `report.html`; not part
    /// of `report.json` (empty in a report read back from one).
    #[serde(skip)]
    pub listing: BatchListing,
}

/// Nearest-rank percentile `q` in (0, 1] of ascending `sorted`; `None` when empty.
pub(super) fn percentile(sorted: &[f64], q: f64) -> Option<f64> {
    let n = sorted.len();
    if n == 0 {
        return None;
    }
    let rank = (q * n as f64).ceil() as usize;
    sorted.get(rank.clamp(1, n) - 1).copied()
}

fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        0.0
    } else {
        values.iter().sum::<f64>() / values.len() as f64
    }
}

fn error_stats(mut errors: Vec<f64>) -> Option<ErrorStats> {
    errors.sort_by(f64::total_cmp);
    Some(ErrorStats {
        count: u32::try_from(errors.len()).unwrap_or(u32::MAX),
        mean_mm: mean(&errors),
        p95_mm: percentile(&errors, 0.95)?,
        max_mm: *errors.last()?,
    })
}

/// Whether `record` ended safe: sorted or let through, the robot clear of every bottle.
fn ended_safe(record: &TrialRecord) -> bool {
    matches!(record.outcome, Outcome::Success | Outcome::Passed) && !record.distractor_touched
}

/// Whether `record` succeeded with every part in the bin its truth calls for.
fn strictly_right(record: &TrialRecord) -> bool {
    if record.outcome != Outcome::Success {
        return false;
    }
    let parts = record.parts();
    !parts.is_empty() && parts.iter().all(|p| p.in_correct_bin())
}

pub(crate) fn count(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

fn stage(records: &[TrialRecord], ms: impl Fn(&TrialTiming) -> f64) -> StageTiming {
    let values: Vec<f64> = records.iter().map(|r| ms(&r.timing)).collect();
    StageTiming {
        total_s: values.iter().sum::<f64>() / 1000.0,
        mean_ms: mean(&values),
    }
}

impl Perception {
    /// The mode's name as written in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Camera => "camera",
            Self::Oracle => "oracle",
        }
    }

    /// What the mode means for a report's numbers.
    pub fn note(self) -> &'static str {
        match self {
            Self::Camera => "camera: rendered images through detector and metrology",
            Self::Oracle => {
                "ORACLE: perception read from the simulated world's ground truth; \
                 for diagnosing control failures only, not a measure of the product"
            }
        }
    }
}

impl BatchReport {
    /// The report of `records` (in any order), described by `meta`.
    pub fn from_records(meta: &ReportMeta, records: &[TrialRecord]) -> Self {
        let trials = count(records.len());
        let successes = count(
            records
                .iter()
                .filter(|r| r.outcome == Outcome::Success)
                .count(),
        );
        let success_rate = if trials == 0 {
            0.0
        } else {
            f64::from(successes) / f64::from(trials)
        };
        let strict_successes = count(records.iter().filter(|r| strictly_right(r)).count());
        let strict_success_rate = if trials == 0 {
            0.0
        } else {
            f64::from(strict_successes) / f64::from(trials)
        };
        let rate = |n: u32| {
            if trials == 0 {
                0.0
            } else {
                f64::from(n) / f64::from(trials)
            }
        };
        let passed = count(
            records
                .iter()
                .filter(|r| r.outcome == Outcome::Passed)
                .count(),
        );
        let safe = count(records.iter().filter(|r| ended_safe(r)).count());
        let removals = records.iter().map(|r| r.removals).sum();
        let mut failures = BTreeMap::new();
        for record in records.iter().filter(|r| r.outcome == Outcome::Failure) {
            let reason = record.failure.map_or("unspecified", |f| f.as_str());
            *failures.entry(reason.to_owned()).or_insert(0) += 1;
        }

        let mut roundness_errors = Vec::new();
        let mut bore_errors = Vec::new();
        let mut sorting = Sorting::default();
        // Every part with a decision, of single-part trials and streams alike.
        let decided: Vec<_> = records
            .iter()
            .flat_map(|record| record.parts())
            .filter_map(|p| p.decision.map(|d| (p.part, d)))
            .collect();
        for (part, decision) in decided {
            sorting.count += 1;
            if let Some(measured) = decision.measured_roundness_mm {
                roundness_errors.push((measured - part.true_roundness_mm).abs());
            }
            if let Some(measured) = decision.measured_bore_diameter_mm {
                bore_errors.push((measured - part.true_bore_diameter_mm).abs());
            }
            let truth = if part.truly_acceptable {
                &mut sorting.accept_reject.truly_accept
            } else {
                &mut sorting.accept_reject.truly_reject
            };
            if decision.accept {
                truth.accept += 1;
            } else {
                truth.reject += 1;
            }
            if part.clear_cut {
                sorting.clear_cut += 1;
                if decision.accept != part.truly_acceptable {
                    sorting.clear_cut_misjudged += 1;
                }
            } else {
                let band = &mut sorting.in_band;
                band.parts += 1;
                band.truly_acceptable += u32::from(part.truly_acceptable);
                band.accepted += u32::from(decision.accept);
                band.rejected += u32::from(!decision.accept);
            }
            sorting.unidentified += u32::from(decision.detected_type == UNIDENTIFIED);
            *sorting
                .part_type
                .entry(part.part_type.clone())
                .or_default()
                .entry(decision.detected_type.clone())
                .or_insert(0) += 1;
        }

        let listing = BatchListing::of(records);
        let cycle_times = &listing.sorted_cycle_times_s;
        let cycle_time_s = match (percentile(cycle_times, 0.5), percentile(cycle_times, 0.95)) {
            (Some(p50), Some(p95)) => Some(CycleTime {
                count: count(cycle_times.len()),
                mean: mean(cycle_times),
                p50,
                p95,
            }),
            _ => None,
        };
        let total_cycle_min = records.iter().map(|r| r.cycle_time_s).sum::<f64>() / 60.0;
        let sorted_parts = count(cycle_times.len());
        let parts_per_minute =
            (total_cycle_min > 0.0).then(|| f64::from(sorted_parts) / total_cycle_min);
        let stream = records.iter().any(|r| r.stream.is_some()).then(|| {
            let mut summary = StreamSummary::default();
            for s in records.iter().filter_map(|r| r.stream.as_ref()) {
                summary.parts_planned += s.parts_planned;
                summary.parts_reached += count(s.parts.len());
                summary.parts_sorted += s.parts_sorted;
                summary.bottles_passed += s.bottles_passed;
                summary.belt_stops += s.belt_stops;
                summary.misidentified_items += s.misidentified_items();
                for part in s.parts.iter().filter(|p| p.outcome == Outcome::Failure) {
                    let reason = part.failure.map_or("unspecified", |f| f.as_str());
                    *summary.part_failures.entry(reason.to_owned()).or_insert(0) += 1;
                }
            }
            summary.tracking = TrackingSummary::of(records);
            summary
        });

        Self {
            scenario: meta.scenario.clone(),
            seed: meta.seed,
            perception: meta.perception,
            perception_note: meta.perception.note().to_owned(),
            scenario_trials: meta.scenario_trials,
            shard: meta.shard,
            interrupted: meta.interrupted,
            trials,
            successes,
            success_rate,
            wilson95: wilson_interval(successes, trials, Z95),
            strict_successes,
            strict_success_rate,
            passed,
            passed_rate: rate(passed),
            safe,
            safe_rate: rate(safe),
            removals,
            failures,
            distractor_picks: count(records.iter().filter(|r| r.distractor_picked).count()),
            distractor_touches: count(records.iter().filter(|r| r.distractor_touched).count()),
            distractor_max_displacement_mm: records
                .iter()
                .map(|r| r.distractor_displacement_mm)
                .fold(0.0, f64::max),
            metrology: Metrology {
                count: sorting.count,
                roundness_error_mm: error_stats(roundness_errors),
                bore_diameter_error_mm: error_stats(bore_errors),
            },
            sorting,
            cycle_time_s,
            parts_per_minute,
            stream,
            faults: FaultTally::by_kind(records.iter().flat_map(|r| &r.faults)),
            gate: meta.min_success.map(|min_success| Gate {
                min_success,
                passed: passes_gate(success_rate, Some(min_success)),
            }),
            timing: Timing {
                stages: StageTimings {
                    trial: stage(records, |t| t.wall_ms),
                    physics: stage(records, |t| t.physics_ms),
                    render: stage(records, |t| t.render_ms),
                    detect: stage(records, |t| t.detect_ms),
                    metrology: stage(records, |t| t.metrology_ms),
                    planning: stage(records, |t| t.planning_ms),
                },
                batch_wall_s: None,
                jobs: None,
            },
            listing,
        }
    }
}
