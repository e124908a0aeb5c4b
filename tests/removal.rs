//! Clearing foreign objects (issue 25, item 2): when a bottle blocks the part's only grasps and
//! the scenario has a waste bin, the cell picks the bottle, drops it into the waste bin, looks
//! again and picks the part. A removed bottle is not a touched one; a scenario without a waste
//! bin removes nothing.

mod common;

use std::path::Path;

use twincell::batch::{Outcome, Perception, TrialRecord, TrialRunner, trial_seed};
use twincell::outcome::FailureReason;
use twincell::scenario::Scenario;
use twincell::task::CellTrialRunner;

fn run(scenario: &Scenario, path: &Path, perception: Perception, trials: u32) -> Vec<TrialRecord> {
    let runner = CellTrialRunner::new(scenario.clone(), path, perception).expect("runner");
    (0..trials)
        .map(|i| runner.run_trial(i, trial_seed(scenario.seed, i)))
        .collect()
}

#[test]
fn blocking_bottles_are_removed_into_the_waste_bin_and_the_part_then_sorted() {
    let path = common::scenario_path("suite/clutter.toml");
    let scenario = common::scenario("suite/clutter.toml");
    assert!(scenario.bins.iter().any(|b| b.waste));
    let trials = 10;
    let with = run(&scenario, &path, Perception::Oracle, trials);
    let mut bare = scenario.clone();
    bare.bins.retain(|b| !b.waste);
    let without = run(&bare, &path, Perception::Oracle, trials);
    let successes = |records: &[TrialRecord]| {
        records
            .iter()
            .filter(|r| r.outcome == Outcome::Success)
            .count()
    };
    let mut removed_then_sorted = 0;
    for (a, b) in with.iter().zip(&without) {
        println!(
            "trial {}: {:?} {:?} removals {}; without a waste bin {:?}",
            a.trial, a.outcome, a.detail, a.removals, b.outcome
        );
        // Without a waste bin nothing is removed.
        assert_eq!(b.removals, 0, "trial {}", b.trial);
        if a.removals == 0 {
            // Nothing removed: the waste bin changed nothing.
            assert_eq!(a.outcome, b.outcome, "trial {}", a.trial);
            assert_eq!(a.failure, b.failure, "trial {}", a.trial);
            continue;
        }
        assert!(
            a.removals <= 3,
            "trial {}: {} removals",
            a.trial,
            a.removals
        );
        // A bottle the cell put into the waste bin is neither touched nor picked.
        assert!(
            a.failure != Some(FailureReason::DistractorTouched)
                && a.failure != Some(FailureReason::DistractorPicked),
            "trial {}: {:?}",
            a.trial,
            a.detail
        );
        if a.outcome == Outcome::Success {
            assert!(!a.distractor_touched && !a.distractor_picked);
            removed_then_sorted += 1;
            // Without the waste bin the same part could not be picked.
            assert_ne!(b.outcome, Outcome::Success, "trial {}", b.trial);
        }
    }
    assert!(
        removed_then_sorted >= 2,
        "{removed_then_sorted} of {trials} clutter trials sorted their part after a removal"
    );
    assert!(successes(&with) > successes(&without));
}

#[test]
fn removals_run_in_camera_mode_and_count_in_the_records() {
    let path = common::scenario_path("suite/clutter.toml");
    let scenario = common::scenario("suite/clutter.toml");
    let records = run(&scenario, &path, Perception::Camera, 10);
    let removals: u32 = records.iter().map(|r| r.removals).sum();
    for r in &records {
        println!(
            "trial {}: {:?} {:?} removals {}",
            r.trial, r.outcome, r.detail, r.removals
        );
        if r.removals > 0 {
            assert!(
                r.failure != Some(FailureReason::DistractorPicked),
                "trial {}: {:?}",
                r.trial,
                r.detail
            );
        }
    }
    assert!(
        removals >= 2,
        "{removals} removals in 10 camera clutter trials"
    );
    assert!(
        records
            .iter()
            .any(|r| r.removals > 0 && r.outcome == Outcome::Success),
        "no camera trial sorted its part after a removal"
    );
}

/// A bottle ahead of the part trips the photo-eye first and stops the belt with the part up to
/// 0.3 m upstream, at the camera's edge or out of its view; the cell indexes the belt to the
/// part. `clutter_dense`'s first 10 camera trials (4 of them found no part before) all find it.
#[test]
fn a_part_a_bottle_stopped_the_belt_ahead_of_is_indexed_to() {
    let path = common::scenario_path("suite/clutter_dense.toml");
    let scenario = common::scenario("suite/clutter_dense.toml");
    for record in run(&scenario, &path, Perception::Camera, 10) {
        println!(
            "trial {}: {:?} {:?}",
            record.trial, record.outcome, record.detail
        );
        assert_ne!(
            record.failure,
            Some(FailureReason::NotDetected),
            "trial {}: {:?}",
            record.trial,
            record.detail
        );
    }
}
