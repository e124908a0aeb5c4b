//! Reports over several batches: a row of headline figures per batch (`BatchRow`), and the
//! suite report (`twincell suite DIR`), one row per scenario file.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{BatchError, BatchReport, CycleTime, Gate, Perception, StreamSummary};
use crate::outcome::{FaultKind, FaultTally};

/// One batch's headline figures, as a row of a suite or sweep report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatchRow {
    /// Scenario name.
    pub scenario: String,
    /// Scenario seed.
    pub seed: u64,
    /// The batch's own output directory (its trials.jsonl, report.json, junit.xml), relative
    /// to the directory of the report that holds this row.
    pub dir: String,
    /// Trials recorded.
    pub trials: u32,
    /// Successful trials.
    pub successes: u32,
    /// `successes / trials`.
    pub success_rate: f64,
    /// Wilson score 95 % interval of the success rate, `[low, high]`.
    pub wilson95: [f64; 2],
    /// Failure reason -> count.
    pub failures: BTreeMap<String, u32>,
    /// Successes with every part in the very bin its true roundness calls for.
    pub strict_successes: u32,
    /// `strict_successes / trials`.
    pub strict_success_rate: f64,
    /// Trials whose part was let through to the collector as unpickable.
    #[serde(default)]
    pub passed: u32,
    /// Trials sorted or passed with no bottle touched, over trials.
    #[serde(default)]
    pub safe_rate: f64,
    /// Bottles removed into the waste bin.
    #[serde(default)]
    pub removals: u32,
    /// Trials in which the robot touched a bottle.
    pub distractor_touches: u32,
    /// Simulated cycle time of the successful trials; `null` when none succeeded.
    pub cycle_time_s: Option<CycleTime>,
    /// Successful parts per minute of simulated cycle time.
    pub parts_per_minute: Option<f64>,
    /// Per-part figures of stream trials; absent for single-part scenarios.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream: Option<StreamSummary>,
    /// Per fault kind that struck: injected, recovered, lost; absent when none struck.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub faults: BTreeMap<FaultKind, FaultTally>,
    /// The `--min-success` gate and its verdict, if any.
    pub gate: Option<Gate>,
    /// Whether the batch stopped early.
    pub interrupted: bool,
}

impl BatchRow {
    /// The row of `report`, whose files lie in `dir` (relative to the holding report).
    pub fn from_report(report: &BatchReport, dir: &str) -> Self {
        Self {
            scenario: report.scenario.clone(),
            seed: report.seed,
            dir: dir.to_owned(),
            trials: report.trials,
            successes: report.successes,
            success_rate: report.success_rate,
            wilson95: report.wilson95,
            failures: report.failures.clone(),
            strict_successes: report.strict_successes,
            strict_success_rate: report.strict_success_rate,
            passed: report.passed,
            safe_rate: report.safe_rate,
            removals: report.removals,
            distractor_touches: report.distractor_touches,
            cycle_time_s: report.cycle_time_s.clone(),
            parts_per_minute: report.parts_per_minute,
            stream: report.stream.clone(),
            faults: report.faults.clone(),
            gate: report.gate.clone(),
            interrupted: report.interrupted,
        }
    }

    /// Whether the batch ran to its end and passed its gate (always, without one).
    pub fn passed(&self) -> bool {
        !self.interrupted && self.gate.as_ref().is_none_or(|g| g.passed)
    }

    /// `label` and the row's figures as one line of a text table.
    pub(super) fn table_line(&self, label: &str) -> String {
        let failures: Vec<String> = self
            .failures
            .iter()
            .map(|(reason, n)| format!("{reason} {n}"))
            .collect();
        let cycle = self
            .cycle_time_s
            .as_ref()
            .map_or("-".to_owned(), |c| format!("{:.2}", c.mean));
        // The gate as ">=0.85" and its verdict; "-" without one.
        let verdict = match (&self.gate, self.interrupted) {
            (_, true) => "INTERRUPTED".to_owned(),
            (Some(g), false) => {
                format!(
                    ">={} {}",
                    g.min_success,
                    if g.passed { "ok" } else { "FAIL" }
                )
            }
            (None, false) => "-".to_owned(),
        };
        format!(
            "{label:<34} {:>4}/{:<4} {:>6.3} [{:.3}, {:.3}] {:>6} {verdict:<10} {}",
            self.successes,
            self.trials,
            self.success_rate,
            self.wilson95[0],
            self.wilson95[1],
            cycle,
            failures.join(", ")
        )
    }
}

/// The header of [`BatchRow::table_line`]'s table.
pub(super) fn table_header(label: &str) -> String {
    format!(
        "{label:<34} {:>9} {:>6} {:<16} {:>6} {:<10} failures",
        "success", "rate", "wilson95", "cycle", "gate"
    )
}

/// The contents of a suite's `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SuiteReport {
    /// The suite's directory, as given.
    pub suite: String,
    /// Perception mode of every scenario.
    pub perception: Perception,
    /// What the perception mode means for these numbers.
    pub perception_note: String,
    /// The `--min-success` rate each scenario must reach, if any.
    pub min_success: Option<f64>,
    /// One row per scenario file, in file-name order.
    pub scenarios: Vec<BatchRow>,
    /// Whether every scenario ran to its end and passed its gate.
    pub passed: bool,
}

impl SuiteReport {
    /// The report over `rows`.
    pub fn new(
        suite: &str,
        perception: Perception,
        min_success: Option<f64>,
        scenarios: Vec<BatchRow>,
    ) -> Self {
        Self {
            suite: suite.to_owned(),
            perception,
            perception_note: perception.note().to_owned(),
            min_success,
            passed: scenarios.iter().all(BatchRow::passed),
            scenarios,
        }
    }

    /// The process exit code of the contract: 0 when every scenario passed, else 1.
    pub fn exit_code(&self) -> u8 {
        if self.passed { 0 } else { 1 }
    }

    /// A text table, one line per scenario.
    pub fn summary_table(&self) -> String {
        let mut out = format!(
            "suite {}  perception {}\n{}\n",
            self.suite,
            self.perception.as_str(),
            table_header("scenario")
        );
        for row in &self.scenarios {
            let _ = writeln!(out, "{}", row.table_line(&row.scenario));
        }
        out
    }
}

/// Writes `value` as pretty JSON to `dir/report.json` (`dir` created if missing); returns the
/// path.
pub fn write_json_report(dir: &Path, value: &impl Serialize) -> Result<PathBuf, BatchError> {
    fs::create_dir_all(dir).map_err(|source| BatchError::CreateDir {
        path: dir.to_path_buf(),
        source,
    })?;
    let path = dir.join(super::REPORT_FILE);
    let mut json = serde_json::to_string_pretty(value).map_err(|source| BatchError::Json {
        path: path.clone(),
        source,
    })?;
    json.push('\n');
    fs::write(&path, json).map_err(|source| BatchError::Write {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::super::{ReportMeta, TrialRecord};
    use super::*;
    use crate::outcome::FailureReason;

    fn report(successes: u32, failures: u32, min_success: Option<f64>) -> BatchReport {
        let mut records = Vec::new();
        for i in 0..successes + failures {
            let mut record = TrialRecord::failed(i, u64::from(i), FailureReason::Collision, "x");
            if i < successes {
                record.outcome = super::super::Outcome::Success;
                record.failure = None;
            }
            records.push(record);
        }
        let meta = ReportMeta {
            scenario: "s".into(),
            seed: 3,
            perception: Perception::Oracle,
            scenario_trials: successes + failures,
            shard: None,
            interrupted: false,
            min_success,
        };
        BatchReport::from_records(&meta, &records)
    }

    #[test]
    fn a_row_carries_the_batch_figures_and_its_gate() {
        let report = report(9, 1, Some(0.95));
        let row = BatchRow::from_report(&report, "s");
        assert_eq!((row.trials, row.successes), (10, 9));
        assert_eq!(row.success_rate, 0.9);
        assert_eq!(row.wilson95, report.wilson95);
        assert_eq!(row.failures.get("collision"), Some(&1));
        assert!(!row.passed());
        assert!(BatchRow::from_report(&self::report(10, 0, Some(0.95)), "s").passed());
    }

    #[test]
    fn a_suite_passes_only_when_every_scenario_does() {
        let good = BatchRow::from_report(&report(5, 0, Some(0.9)), "a");
        let bad = BatchRow::from_report(&report(4, 1, Some(0.9)), "b");
        let suite = SuiteReport::new("d", Perception::Oracle, Some(0.9), vec![good.clone()]);
        assert_eq!(suite.exit_code(), 0);
        let suite = SuiteReport::new("d", Perception::Oracle, Some(0.9), vec![good, bad]);
        assert_eq!(suite.exit_code(), 1);
        let table = suite.summary_table();
        assert_eq!(table.lines().count(), 4, "{table}");
        assert!(table.contains(">=0.9 FAIL"), "{table}");
        assert!(table.contains(">=0.9 ok"), "{table}");
        let ungated = BatchRow::from_report(&report(5, 0, None), "c");
        assert!(
            ungated.table_line("c").contains(" - "),
            "{}",
            ungated.table_line("c")
        );
    }
}
