//! What a batch runs: which scenario, which trials, on how many threads.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::Perception;
use crate::rng::SimRng;

/// The seed of trial `index` of a scenario seeded with `scenario_seed`.
///
/// Every trial's seed depends only on these two numbers, so a trial gives the same record
/// whether it runs alone, in a parallel batch or in any shard.
pub fn trial_seed(scenario_seed: u64, index: u32) -> u64 {
    SimRng::derive(scenario_seed, u64::from(index)).next_u64()
}

/// One slice of a scenario's trials: the trials with `trial % count == index`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "ShardFields")]
pub struct Shard {
    /// This shard's number, `0..count`.
    pub index: u32,
    /// How many shards the scenario is split into.
    pub count: u32,
}

/// A shard as read from JSON, before its range is checked.
#[derive(Deserialize)]
struct ShardFields {
    index: u32,
    count: u32,
}

impl TryFrom<ShardFields> for Shard {
    type Error = ShardError;

    fn try_from(fields: ShardFields) -> Result<Self, Self::Error> {
        Self::new(fields.index, fields.count)
    }
}

/// Why a `--shard I/N` value was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShardError {
    /// Not of the form `I/N` with two unsigned integers.
    #[error("shard {text:?}: expected I/N with unsigned integers, e.g. 0/4")]
    Syntax {
        /// The text given.
        text: String,
    },
    /// N is zero or I is not below N.
    #[error("shard {index}/{count}: need 0 <= I < N")]
    OutOfRange {
        /// The shard number given.
        index: u32,
        /// The shard count given.
        count: u32,
    },
}

impl Shard {
    /// Shard `index` of `count`, checked.
    pub fn new(index: u32, count: u32) -> Result<Self, ShardError> {
        if count == 0 || index >= count {
            return Err(ShardError::OutOfRange { index, count });
        }
        Ok(Self { index, count })
    }

    /// Whether trial `trial` belongs to this shard.
    pub fn contains(self, trial: u32) -> bool {
        trial % self.count == self.index
    }
}

impl FromStr for Shard {
    type Err = ShardError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let syntax = || ShardError::Syntax {
            text: text.to_owned(),
        };
        let (index, count) = text.trim().split_once('/').ok_or_else(syntax)?;
        let index = index.trim().parse().map_err(|_| syntax())?;
        let count = count.trim().parse().map_err(|_| syntax())?;
        Self::new(index, count)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Everything `run_batch` needs to know besides the trial runner and the output directory.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchPlan {
    /// Scenario name, as written in reports (report `scenario`, JUnit `classname`).
    pub scenario_name: String,
    /// The scenario seed all trial seeds derive from.
    pub scenario_seed: u64,
    /// Where perception's answers come from; written into every report.
    pub perception: Perception,
    /// Trials of the whole scenario (`--trials N`): indices `0..trials`, before sharding.
    pub trials: u32,
    /// Worker threads; `None` (or 0) means the available cores.
    pub jobs: Option<usize>,
    /// Run only this shard's trials (`--shard I/N`).
    pub shard: Option<Shard>,
    /// Least success rate that passes (`--min-success RATE`), in [0, 1].
    pub min_success: Option<f64>,
}

impl BatchPlan {
    /// The trial indices this plan runs, in order.
    pub fn trial_indices(&self) -> Vec<u32> {
        let shard = self.shard;
        (0..self.trials)
            .filter(|&trial| shard.is_none_or(|s| s.contains(trial)))
            .collect()
    }

    /// Worker threads to start for `pending` trials: `jobs` or the available cores, at least 1.
    pub fn worker_count(&self, pending: usize) -> usize {
        let wanted = match self.jobs {
            Some(jobs) if jobs > 0 => jobs,
            _ => std::thread::available_parallelism().map_or(1, usize::from),
        };
        wanted.min(pending).max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_parses_and_checks_range() {
        assert_eq!("1/4".parse::<Shard>(), Ok(Shard { index: 1, count: 4 }));
        assert_eq!(" 0 / 1 ".parse::<Shard>(), Ok(Shard { index: 0, count: 1 }));
        assert!(matches!(
            "4/4".parse::<Shard>(),
            Err(ShardError::OutOfRange { .. })
        ));
        assert!(matches!(
            "0/0".parse::<Shard>(),
            Err(ShardError::OutOfRange { .. })
        ));
        for bad in ["", "1", "1/", "/2", "a/2", "-1/2", "1/2/3"] {
            assert!(
                matches!(bad.parse::<Shard>(), Err(ShardError::Syntax { .. })),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn shards_partition_the_trials() {
        let plan = |shard| BatchPlan {
            scenario_name: "s".into(),
            scenario_seed: 1,
            perception: Perception::Camera,
            trials: 10,
            jobs: None,
            shard,
            min_success: None,
        };
        let mut all: Vec<u32> = (0..3)
            .flat_map(|i| plan(Some(Shard { index: i, count: 3 })).trial_indices())
            .collect();
        all.sort_unstable();
        assert_eq!(all, plan(None).trial_indices());
        assert_eq!(
            plan(Some(Shard { index: 1, count: 3 })).trial_indices(),
            [1, 4, 7]
        );
    }

    #[test]
    fn shard_json_is_range_checked() {
        let ok: Shard = serde_json::from_str(r#"{"index":1,"count":4}"#).expect("valid shard");
        assert_eq!(ok, Shard { index: 1, count: 4 });
        // A zero count read from a report once reached `trial % 0` in merge.
        for bad in [r#"{"index":0,"count":0}"#, r#"{"index":4,"count":4}"#] {
            let err = serde_json::from_str::<Shard>(bad).expect_err(bad);
            assert!(err.to_string().contains("need 0 <= I < N"), "{err}");
        }
    }

    #[test]
    fn trial_seed_is_the_derived_stream() {
        assert_eq!(trial_seed(42, 3), SimRng::derive(42, 3).next_u64());
        assert_ne!(trial_seed(42, 3), trial_seed(42, 4));
        assert_ne!(trial_seed(42, 3), trial_seed(43, 3));
    }
}
