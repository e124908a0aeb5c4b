//! Picking from a belt that never stops (issue 26): tracked streams in oracle and camera mode
//! sort what the arm can meet, hold each part firmly while following the belt, keep every
//! joint inside its limits, and let the parts the arm cannot meet ride on; the new keys are
//! validated.

mod common;

use std::path::{Path, PathBuf};

use twincell::batch::{Outcome, Perception, TrialRecord, TrialRunner, trial_seed};
use twincell::outcome::StreamRecord;
use twincell::scenario::Scenario;
use twincell::task::CellTrialRunner;

/// Largest drift of a part in the jaws the issue allows, mm.
const MAX_JAW_DRIFT_MM: f64 = 5.0;
/// Largest distance of the TCP from the part's axis as the jaws close, mm: well inside the
/// jaws' opening clearance (12 mm each side by default).
const MAX_TRACKING_ERROR_MM: f64 = 5.0;

/// `stream.toml` picked from the moving belt: `parts` parts and `bottles` bottles,
/// `spacing_m` apart, at `speed_m_s`.
fn tracked(parts: u32, bottles: u32, spacing_m: f64, speed_m_s: f64) -> (Scenario, PathBuf) {
    let path = common::scenario_path("stream.toml");
    let mut scenario = common::scenario("stream.toml");
    scenario.conveyor.tracking = true;
    scenario.conveyor.speed_m_s = speed_m_s;
    scenario.conveyor.creep_speed_m_s = speed_m_s;
    scenario.parts_per_trial = parts;
    scenario.stream.bottles = bottles;
    scenario.stream.spacing_m = spacing_m;
    if let Err(e) = scenario.validate(&path) {
        panic!("{e}");
    }
    (scenario, path)
}

fn run(scenario: &Scenario, path: &Path, perception: Perception, trials: u32) -> Vec<TrialRecord> {
    let runner = CellTrialRunner::new(scenario.clone(), path, perception).expect("runner");
    (0..trials)
        .map(|i| runner.run_trial(i, trial_seed(scenario.seed, i)))
        .collect()
}

fn stream(record: &TrialRecord) -> &StreamRecord {
    match &record.stream {
        Some(s) => s,
        None => panic!("trial {} has no stream record", record.trial),
    }
}

/// Every part picked was held within the drift bound and met within the tracking bound, no
/// joint passed a limit, every hold of the belt is recorded with its part, and nothing failed.
fn check_tracked(record: &TrialRecord) {
    println!(
        "trial {}: {:?} {:?} margin {:.3} rad",
        record.trial, record.outcome, record.detail, record.motion.joint_limit_margin_rad
    );
    let s = stream(record);
    assert!(s.tracking, "not a tracking stream");
    let recorded: u32 = s
        .parts
        .iter()
        .filter_map(|p| p.tracking.map(|t| t.belt_holds))
        .sum();
    assert_eq!(
        recorded, s.belt_stops,
        "a hold of the belt not recorded with its part"
    );
    assert_ne!(record.outcome, Outcome::Failure, "{:?}", record.detail);
    assert!(
        record.motion.joint_limit_margin_rad >= 0.0,
        "a joint went past its limit"
    );
    for part in &s.parts {
        match part.outcome {
            Outcome::Success => {
                let Some(t) = &part.tracking else {
                    panic!("part {} sorted without its tracking record", part.index);
                };
                println!("  part {}: {t:?}", part.index);
                assert!(t.jaw_drift_mm <= MAX_JAW_DRIFT_MM, "{t:?}");
                assert!(t.tracking_error_mm <= MAX_TRACKING_ERROR_MM, "{t:?}");
                assert!(t.latch_to_grasp_s > 0.0, "{t:?}");
                assert_eq!(
                    part.placed_bin.as_deref(),
                    Some(part.part.correct_bin.as_str())
                );
            }
            Outcome::Passed => {
                assert!(part.placed_bin.is_none());
                // Passed unpicked: at most the record of a hold for it.
                if let Some(t) = &part.tracking {
                    assert!(t.belt_holds > 0 && t.latch_to_grasp_s == 0.0, "{t:?}");
                }
            }
            Outcome::Failure => panic!("part {} failed: {:?}", part.index, part.detail),
        }
    }
}

#[test]
fn a_stream_the_arm_keeps_up_with_is_sorted_whole_in_oracle_mode() {
    // 2 m apart at 0.25 m/s: an item every 8 s, more than a pick cycle.
    let (scenario, path) = tracked(3, 1, 2.0, 0.25);
    let records = run(&scenario, &path, Perception::Oracle, 2);
    for record in &records {
        check_tracked(record);
        let s = stream(record);
        assert_eq!(s.parts_sorted, 3, "{:?}", record.detail);
        assert_eq!(record.outcome, Outcome::Success);
        assert_eq!(s.bottles_passed, 1);
    }
    // The same trial again: the same record.
    let again = run(&scenario, &path, Perception::Oracle, 1);
    let strip = |r: &TrialRecord| {
        let mut r = r.clone();
        r.timing = Default::default();
        serde_json::to_string(&r).unwrap_or_default()
    };
    assert_eq!(strip(&records[0]), strip(&again[0]));
}

#[test]
fn a_faster_belt_is_followed_too() {
    // 0.1 and 0.3 m/s, items far enough apart for the arm (at 0.4 m/s the follow carries
    // some parts past the reach: docs/conveyor_tracking.md).
    for (speed, spacing) in [(0.1, 1.0), (0.3, 3.0)] {
        let (scenario, path) = tracked(2, 0, spacing, speed);
        for record in run(&scenario, &path, Perception::Oracle, 1) {
            check_tracked(&record);
            assert_eq!(
                stream(&record).parts_sorted,
                2,
                "{speed} m/s: {:?}",
                record.detail
            );
        }
    }
}

#[test]
fn a_stream_denser_than_the_arm_s_cycle_holds_the_belt_and_is_sorted() {
    // 0.3 m apart at 0.25 m/s: an item every 1.2 s while a pick takes the arm 6-7 s. Without
    // the hold a quarter of the parts were sorted; with it the belt stops for each part that
    // would otherwise leave the window while the arm is away, and the arm picks it standing.
    let (scenario, path) = tracked(6, 1, 0.3, 0.25);
    let records = run(&scenario, &path, Perception::Oracle, 2);
    let (mut sorted, mut fed) = (0, 0);
    for record in &records {
        check_tracked(record);
        let s = stream(record);
        assert!(
            s.belt_stops >= 1,
            "the belt was never held: {:?}",
            record.detail
        );
        let held_and_sorted = s
            .parts
            .iter()
            .any(|p| p.outcome == Outcome::Success && p.tracking.is_some_and(|t| t.belt_holds > 0));
        assert!(held_and_sorted, "no part held for was sorted");
        for part in &s.parts {
            if let Some(t) = part.tracking.filter(|t| t.belt_holds > 0) {
                assert!(t.belt_hold_s > 0.0, "part {}: {t:?}", part.index);
            }
        }
        sorted += s.parts_sorted;
        fed += s.parts_planned;
    }
    // Measured: 12/12 (and 80/80 on stream.toml's 10 camera streams, seeds 731 and 2602).
    assert!(sorted * 20 >= fed * 19, "{sorted}/{fed} sorted");
}

#[test]
fn the_camera_measures_and_sorts_parts_it_saw_moving_with_motion_blur() {
    let (mut scenario, path) = tracked(3, 1, 2.0, 0.25);
    scenario.camera.exposure_ms = 1.0;
    for record in run(&scenario, &path, Perception::Camera, 1) {
        check_tracked(&record);
        let s = stream(&record);
        assert_eq!(s.parts_sorted, 3, "{:?}", record.detail);
        for part in &s.parts {
            let Some(decision) = &part.decision else {
                panic!("part {} without a decision", part.index);
            };
            let (Some(roundness), Some(diameter)) = (
                decision.measured_roundness_mm,
                decision.measured_bore_diameter_mm,
            ) else {
                panic!("part {} not measured", part.index);
            };
            let roundness_error = roundness - part.part.true_roundness_mm;
            let diameter_error = diameter - part.part.true_bore_diameter_mm;
            println!(
                "  part {}: roundness {roundness_error:+.4} mm, diameter {diameter_error:+.4} mm",
                part.index
            );
            // A 1 ms exposure at 0.25 m/s smears 0.25 mm (1.4 pixels of the area of
            // interest): the metrology still measures within a few hundredths of a mm; at 2 ms
            // the smear starts to read as out-of-roundness (docs/conveyor_tracking.md).
            assert!(roundness_error.abs() < 0.03, "{roundness_error}");
            assert!(diameter_error.abs() < 0.05, "{diameter_error}");
        }
    }
}

#[test]
fn the_new_keys_are_validated_naming_file_key_and_reason() {
    let paper = common::scenario_path("paper_50.toml");
    let stream = common::scenario_path("stream.toml");
    let cases = [
        (&paper, "conveyor.tracking=true", "parts_per_trial"),
        (&stream, "conveyor.tracking=3", "conveyor.tracking"),
        (&stream, "camera.exposure_ms=-1", "camera.exposure_ms"),
        (&stream, "camera.exposure_ms=80", "camera.exposure_ms"),
    ];
    for (path, set, expect) in cases {
        let out = common::out_dir("conveyor_tracking", "invalid");
        let (code, _, stderr) = common::twincell(&[
            "run",
            common::path_str(path),
            "--set",
            set,
            "--trials",
            "1",
            "--out",
            common::path_str(&out),
        ]);
        println!("{set}: {stderr}");
        assert_eq!(code, 2, "{set}: {stderr}");
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        assert!(
            stderr.contains(name),
            "{set}: the file is not named: {stderr}"
        );
        assert!(stderr.contains(expect), "{set}: {stderr}");
    }
}
