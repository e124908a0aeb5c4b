//! The physical cell: scenario validation, the belt and photo-eye, and deterministic batches.

use std::path::{Path, PathBuf};
use std::process::Command;

use twincell::cell::Cell;
use twincell::rng::SimRng;
use twincell::scenario::Scenario;

fn scenario_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name)
}

fn paper() -> Scenario {
    Scenario::load(&scenario_path("paper_50.toml")).expect("paper_50 loads")
}

#[test]
fn shipped_scenarios_validate() {
    for name in ["paper_50.toml", "smoke.toml"] {
        let scenario = Scenario::load(&scenario_path(name)).expect(name);
        assert!(scenario.part_types.len() >= 6);
        assert!(scenario.reject_bin().is_some());
    }
}

fn error_for(edit: impl Fn(&str) -> String) -> String {
    let text = std::fs::read_to_string(scenario_path("paper_50.toml")).expect("read");
    let edited = edit(&text);
    match Scenario::from_toml(&edited, Path::new("edited.toml")) {
        Ok(_) => panic!("edited scenario was accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_scenarios_name_the_file_key_and_reason() {
    let unknown = error_for(|t| t.replace("trials = 50", "trials = 50\ntrails = 3"));
    assert!(
        unknown.contains("edited.toml") && unknown.contains("trails"),
        "{unknown}"
    );
    let negative = error_for(|t| t.replace("width_m = 0.32", "width_m = -0.32"));
    assert!(
        negative.contains("conveyor.width_m") && negative.contains("positive"),
        "{negative}"
    );
    let far = error_for(|t| {
        t.replace(
            "floor_center_m = [0.42, 0.24, 0.50]",
            "floor_center_m = [1.6, 0.24, 0.50]",
        )
    });
    assert!(
        far.contains("bins[0].floor_center_m") && far.contains("reach"),
        "{far}"
    );
    let orphan = error_for(|t| {
        t.replace(
            "accepts = [\"axle_a20\", \"axle_a24\"]",
            "accepts = [\"axle_a20\"]",
        )
    });
    assert!(orphan.contains("axle_a24"), "{orphan}");
}

#[test]
fn belt_carries_the_part_to_the_photo_eye_by_friction() {
    let scenario = paper();
    let mut rng = SimRng::new(3);
    let mut cell = Cell::build(&scenario, None, &mut rng).expect("cell builds");
    let start = cell.body_pose(cell.part_body).expect("part").translation.x;
    cell.conveyor
        .set_speed_m_s(scenario.conveyor.speed_m_s as f32);
    let mut steps = 0;
    while !cell.photo_eye_blocked() && steps < 2400 {
        cell.world.step_with_hooks(&cell.conveyor);
        steps += 1;
    }
    assert!(cell.photo_eye_blocked(), "nothing reached the photo-eye");
    let travelled = cell.body_pose(cell.part_body).expect("part").translation.x - start;
    // Something broke the beam; the part has moved downstream at about belt speed.
    let elapsed = steps as f64 * scenario.physics.dt_s;
    assert!(
        travelled > 0.5 * scenario.conveyor.speed_m_s * elapsed,
        "{travelled} m in {elapsed} s"
    );
    // The drive ramps the belt down (1 m/s^2, as the cell does); friction stops the part with
    // it and then holds it still.
    let dt = scenario.physics.dt_s as f32;
    for _ in 0..240 {
        cell.conveyor.ramp_towards(0.0, dt);
        cell.world.step_with_hooks(&cell.conveyor);
    }
    assert_eq!(cell.conveyor.speed_m_s(), 0.0);
    let at_rest = cell.body_pose(cell.part_body).expect("part").translation.x;
    for _ in 0..480 {
        cell.world.step_with_hooks(&cell.conveyor);
    }
    let later = cell.body_pose(cell.part_body).expect("part").translation.x;
    // The prism's contact with the belt jitters by a millimetre or so (rapier's soft contacts);
    // the grasp plan keeps 12 mm of jaw clearance for that.
    assert!(
        (later - at_rest).abs() < 0.005,
        "part crept {} m on a stopped belt",
        later - at_rest
    );
}

fn run_cli(args: &[&str]) -> (i32, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_twincell"))
        .args(args)
        .output()
        .expect("binary runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// trials.jsonl with the wall-clock `timing` objects removed.
fn without_timing(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .expect("trials.jsonl")
        .lines()
        .map(|line| {
            let mut value: serde_json::Value = serde_json::from_str(line).expect("JSON line");
            if let Some(object) = value.as_object_mut() {
                object.remove("timing");
            }
            value
        })
        .collect()
}

#[test]
fn run_is_deterministic_across_jobs() {
    let dir = std::env::temp_dir().join(format!("twincell-cell-det-{}", std::process::id()));
    let scenario = scenario_path("smoke.toml");
    let scenario = scenario.to_str().expect("utf-8 path");
    let mut outputs = Vec::new();
    for jobs in ["1", "2"] {
        let out = dir.join(format!("jobs{jobs}"));
        let out_str = out.to_str().expect("utf-8 path");
        let (code, stderr) = run_cli(&[
            "run",
            scenario,
            "--perception",
            "oracle",
            "--jobs",
            jobs,
            "--out",
            out_str,
            "--json",
        ]);
        assert!(code == 0 || code == 1, "exit {code}: {stderr}");
        outputs.push(without_timing(&out.join("trials.jsonl")));
    }
    assert_eq!(outputs[0].len(), 4);
    assert_eq!(outputs[0], outputs[1]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_scenario_exits_with_code_2() {
    let dir = std::env::temp_dir().join(format!("twincell-cell-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let text = std::fs::read_to_string(scenario_path("smoke.toml")).expect("read");
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        text.replace("length_m = 1.6", "length_m = 1.6\nlenght_m = 2.0"),
    )
    .expect("write");
    let (code, stderr) = run_cli(&[
        "run",
        bad.to_str().expect("utf-8"),
        "--perception",
        "oracle",
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("bad.toml") && stderr.contains("lenght_m"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn grasp_holds_by_friction_and_a_weak_grip_lets_the_part_slip() {
    use twincell::batch::{FailureReason, Outcome, Perception, TrialRunner, trial_seed};
    use twincell::cell::CellTrialRunner;
    let path = scenario_path("paper_50.toml");
    let scenario = Scenario::load(&path).expect("loads");
    let seed = trial_seed(scenario.seed, 1);
    let mut runner =
        CellTrialRunner::new(scenario, &path, Perception::Oracle).expect("runner builds");
    let firm = runner.run_trial(1, seed);
    assert_eq!(firm.outcome, Outcome::Success, "{:?}", firm.detail);
    // The same trial with 2 N per jaw: friction cannot carry the tube's weight.
    runner.set_grip_force_n(2.0);
    let weak = runner.run_trial(1, seed);
    assert_eq!(weak.outcome, Outcome::Failure);
    assert!(
        matches!(
            weak.failure,
            Some(FailureReason::Slipped | FailureReason::Dropped)
        ),
        "{:?} {:?}",
        weak.failure,
        weak.detail
    );
}
