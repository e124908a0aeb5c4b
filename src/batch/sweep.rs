//! The sweep report (`twincell sweep SCENARIO --set KEY=V1,V2 ...`): one row per point of the
//! grid of overrides, each point a whole batch of the scenario on the same seed.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::suite::{BatchRow, table_header};
use super::{Perception, Shard};
use crate::scenario::{Override, SweepAxis};

/// One axis of the grid: a scenario key and its values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepAxisReport {
    /// The key path, as given to `--set`.
    pub key: String,
    /// Its values, in the order given.
    pub values: Vec<toml::Value>,
}

impl From<&SweepAxis> for SweepAxisReport {
    fn from(axis: &SweepAxis) -> Self {
        Self {
            key: axis.key.clone(),
            values: axis.values.clone(),
        }
    }
}

/// One grid point: its overrides and its batch's figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepPoint {
    /// The point's number, in grid order (the last axis varies fastest).
    pub point: usize,
    /// Key path -> value of every axis at this point.
    pub overrides: BTreeMap<String, toml::Value>,
    /// The batch's figures.
    #[serde(flatten)]
    pub row: BatchRow,
}

impl SweepPoint {
    /// Point `point` of the grid with `overrides`, and its batch's row.
    pub fn new(point: usize, overrides: &[Override], row: BatchRow) -> Self {
        Self {
            point,
            overrides: overrides
                .iter()
                .map(|o| (o.key.clone(), o.value.clone()))
                .collect(),
            row,
        }
    }
}

/// The contents of a sweep's `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepReport {
    /// Scenario name (before overrides).
    pub scenario: String,
    /// The seed every point ran on: points differ only by their overrides.
    pub seed: u64,
    /// Perception mode.
    pub perception: Perception,
    /// What the perception mode means for these numbers.
    pub perception_note: String,
    /// The shard every point ran, if any (merge each point's directory with `twincell merge`).
    pub shard: Option<Shard>,
    /// The grid's axes.
    pub axes: Vec<SweepAxisReport>,
    /// One row per grid point, in grid order.
    pub points: Vec<SweepPoint>,
    /// Whether every point ran to its end and passed its gate.
    pub passed: bool,
}

impl SweepReport {
    /// The report over `points`.
    pub fn new(
        scenario: &str,
        seed: u64,
        perception: Perception,
        shard: Option<Shard>,
        axes: &[SweepAxis],
        points: Vec<SweepPoint>,
    ) -> Self {
        Self {
            scenario: scenario.to_owned(),
            seed,
            perception,
            perception_note: perception.note().to_owned(),
            shard,
            axes: axes.iter().map(SweepAxisReport::from).collect(),
            passed: points.iter().all(|p| p.row.passed()),
            points,
        }
    }

    /// The process exit code of the contract: 0 when every point passed, else 1.
    pub fn exit_code(&self) -> u8 {
        if self.passed { 0 } else { 1 }
    }

    /// A text table, one line per grid point.
    pub fn summary_table(&self) -> String {
        let mut out = format!(
            "sweep of {:?}  seed {}  perception {}\n{}\n",
            self.scenario,
            self.seed,
            self.perception.as_str(),
            table_header("point")
        );
        for point in &self.points {
            let label: Vec<String> = point
                .overrides
                .iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            let _ = writeln!(out, "{}", point.row.table_line(&label.join(" ")));
        }
        out
    }
}
