//! The arm at its real pace stays within its published limits, as the physics measures it: every
//! trial of paper_50 (seed 731, oracle perception so that the test needs no renderer; the batch
//! tests/resume.rs resumes to, run once for both), with the joint speeds taken from the simulated
//! joint angles step by step, not from the plan.

mod common;

use twincell::batch::{Outcome, Perception, TrialRecord, TrialRunner, trial_seed};
use twincell::scenario::Scenario;
use twincell::task::CellTrialRunner;

/// Largest drift of a part in the jaws over a carry, mm.
const MAX_GRIP_DRIFT_MM: f64 = 5.0;
/// Largest mean simulated cycle, s (7.5 parts a minute).
const MAX_MEAN_CYCLE_S: f64 = 8.0;

/// Every trial of paper_50 through `twincell run --perception oracle`.
fn all_trials() -> (Scenario, Vec<TrialRecord>) {
    let records = common::shared_batch::records(&common::shared_batch::paper_50_oracle());
    (common::paper_50(), records)
}

/// The first `trials` trials of `scenario` (read from paper_50's path), oracle perception, on
/// two threads.
fn run_trials(scenario: Scenario, trials: u32) -> (Scenario, Vec<TrialRecord>) {
    let path = common::scenario_path("paper_50.toml");
    let runner =
        CellTrialRunner::new(scenario.clone(), &path, Perception::Oracle).expect("runner builds");
    let (runner, seed) = (&runner, scenario.seed);
    let mut records: Vec<TrialRecord> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..2u32)
            .map(|worker| {
                scope.spawn(move || {
                    (0..trials)
                        .filter(|i| i % 2 == worker)
                        .map(|i| runner.run_trial(i, trial_seed(seed, i)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("worker finishes"))
            .collect()
    });
    records.sort_by_key(|r| r.trial);
    (scenario, records)
}

#[test]
fn every_trial_keeps_the_joints_within_their_limits_and_the_part_in_the_jaws() {
    let (scenario, records) = all_trials();
    assert_eq!(records.len(), scenario.trials as usize);
    let mut fastest = 0.0f64;
    for record in &records {
        let m = &record.motion;
        assert_eq!(
            record.outcome,
            Outcome::Success,
            "trial {}: {:?}",
            record.trial,
            record.detail
        );
        assert!(
            m.joint_speed_ratio <= 1.0,
            "trial {}: a joint ran at {:.3} of its velocity limit",
            record.trial,
            m.joint_speed_ratio
        );
        assert!(
            m.joint_limit_margin_rad >= 0.0,
            "trial {}: a joint went {:.4} rad past its position limit",
            record.trial,
            -m.joint_limit_margin_rad
        );
        assert!(
            m.grip_drift_mm <= MAX_GRIP_DRIFT_MM,
            "trial {}: the part drifted {:.2} mm in the jaws",
            record.trial,
            m.grip_drift_mm
        );
        // The phases account for every simulated second of the trial.
        let booked: f64 = m.phase_s.iter().map(|(_, s)| s).sum();
        assert!(
            (booked - record.sim_time_s).abs() < 1e-6,
            "trial {}: phases {booked} s of {} s",
            record.trial,
            record.sim_time_s
        );
        fastest = fastest.max(m.joint_speed_ratio);
    }
    // The arm does work near its limits: the check above is not passed by a crawling arm.
    assert!(fastest > 0.8, "fastest joint at {fastest:.2} of its limit");
    let mean_cycle_s = records.iter().map(|r| r.cycle_time_s).sum::<f64>() / records.len() as f64;
    assert!(
        mean_cycle_s <= MAX_MEAN_CYCLE_S,
        "mean cycle {mean_cycle_s:.2} s"
    );
}

/// The pads' pre-sliding stiction is what keeps a carried part in place at the default
/// substeps: with it turned off (`gripper.pad_preslide_mm = 0`) the solver's Coulomb friction
/// alone lets the same parts creep along the pads by several millimetres, and they still arrive
/// (it is friction, not a weld, either way).
#[test]
fn pad_stiction_keeps_a_carried_part_from_creeping() {
    let scenario = common::paper_50();
    let mut plain = scenario.clone();
    plain.gripper.pad_preslide_mm = 0.0;
    let largest = |records: &[TrialRecord]| {
        assert!(records.iter().all(|r| r.outcome == Outcome::Success));
        records
            .iter()
            .map(|r| r.motion.grip_drift_mm)
            .fold(0.0f64, f64::max)
    };
    let with = largest(&run_trials(scenario, 10).1);
    let without = largest(&run_trials(plain, 10).1);
    assert!(with < 1.0, "with stiction a part drifted {with:.2} mm");
    assert!(
        without > 3.0 * with,
        "without stiction {without:.2} mm, with {with:.2} mm"
    );
}
