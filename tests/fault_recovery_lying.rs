//! A part that falls lying is picked again, and a stream goes on past a drop (the gripper
//! fault forced on in every trial, so that drops, and among them parts that land lying, come
//! often): in both perception modes a tube seen lying is picked by its body and laid in the bin
//! decided while it stood, or counted lost with its reason; nothing dropped goes unrecorded;
//! and the stream scenario gives the same records on one job and two.

mod common;

use std::path::PathBuf;

use serde_json::Value;

/// Runs `scenario` with the gripper fault in every trial; returns the output folder.
fn run_forced(scenario: &str, perception: &str, trials: &str, jobs: &str, name: &str) -> PathBuf {
    let out = common::absent_dir("fault_recovery_lying", name);
    let path = common::scenario_path(scenario);
    let (code, _, stderr) = common::twincell(&[
        "run",
        common::path_str(&path),
        "--trials",
        trials,
        "--perception",
        perception,
        "--jobs",
        jobs,
        "--min-success",
        "0",
        "--set",
        "faults.gripper.rate=1",
        "--out",
        common::path_str(&out),
    ]);
    assert_eq!(code, 0, "{scenario} {perception}: {stderr}");
    out
}

fn records(dir: &std::path::Path) -> Vec<Value> {
    common::read(&dir.join("trials.jsonl"))
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect()
}

fn actions(fault: &Value) -> Vec<&str> {
    fault["actions"]
        .as_array()
        .expect("actions")
        .iter()
        .filter_map(Value::as_str)
        .collect()
}

/// Each fault seen lying in `records`: picked again lying, and then either recovered (the part
/// in the bin its truth calls for) or counted lost with a reason. Returns (seen lying, laid in
/// its bin).
fn lying_outcomes(records: &[Value]) -> (usize, usize) {
    let (mut lying, mut laid) = (0, 0);
    for record in records {
        for fault in record["faults"].as_array().into_iter().flatten() {
            let done = actions(fault);
            if fault.get("saw_lying_part").is_none() {
                assert!(!done.contains(&"repicked_lying"), "{fault}");
                continue;
            }
            lying += 1;
            assert!(done.contains(&"saw_lying_part"), "{fault}");
            let lost = done.contains(&"counted_lost");
            if fault["recovered"] == true {
                assert!(!lost && done.contains(&"repicked_lying"), "{fault}");
                laid += 1;
            } else {
                assert!(lost || record["outcome"] == "failure", "{record}");
            }
        }
    }
    (lying, laid)
}

/// Over 40 trials each fault is answered; in each mode at least one tube fell lying and was
/// laid, by its body, in the bin its truth calls for. Measured 6 December 2026, the jaws
/// kinematic fingers, which feel most weakened grips in time to set the part down: oracle 6
/// lying, 3 laid, camera 6 lying, 4 laid (in the first 16 trials one lying part in oracle mode,
/// so the test runs 40); with the arm's multibody, 16 trials: oracle 3 lying, 1 laid, camera 2
/// lying, 1 laid.
#[test]
fn a_tube_that_falls_lying_is_picked_again_and_laid_in_its_bin_in_both_modes() {
    for perception in ["oracle", "camera"] {
        let dir = run_forced("faults/gripper.toml", perception, "40", "2", perception);
        let records = records(&dir);
        assert_eq!(records.len(), 40);
        let (lying, laid) = lying_outcomes(&records);
        assert!(
            laid >= 1,
            "{perception}: {laid} of {lying} lying tubes laid in a bin"
        );
        for record in &records {
            if record["outcome"] != "success" {
                continue;
            }
            // A success is the part in the bin its truth calls for, lying or standing.
            assert_eq!(
                record["placed_bin"], record["part"]["correct_bin"],
                "{record}"
            );
        }
    }
}

/// A stream meets one weakened grip per run of 8 parts: the drop is answered as in a single
/// trial and the stream goes on; every part is in its record; one job and two give the same
/// records.
#[test]
fn a_stream_answers_a_drop_and_goes_on_and_is_deterministic() {
    let one = run_forced("faults/gripper_stream.toml", "oracle", "4", "1", "stream_1");
    let two = run_forced("faults/gripper_stream.toml", "oracle", "4", "2", "stream_2");
    assert_eq!(
        common::without_timing(&one),
        common::without_timing(&two),
        "--jobs 1 and --jobs 2 differ"
    );
    let records = records(&two);
    let mut answered = 0;
    for record in &records {
        let stream = &record["stream"];
        let parts = stream["parts"].as_array().expect("parts");
        let faults = record["faults"].as_array().cloned().unwrap_or_default();
        let grip: Vec<&Value> = faults.iter().filter(|f| f["kind"] == "gripper").collect();
        assert!(grip.len() <= 2, "{record}");
        for fault in &grip {
            let done = actions(fault);
            if done.contains(&"counted_lost") {
                // Lost: its part failed, its record says so, and the stream went on.
                let lost: Vec<&Value> = parts
                    .iter()
                    .filter(|p| {
                        p["detail"]
                            .as_str()
                            .is_some_and(|d| d.contains("counted lost"))
                    })
                    .collect();
                assert_eq!(lost.len(), 1, "{record}");
                assert_eq!(fault["lost_parts"], 1, "{fault}");
            }
            answered += usize::from(done.len() > 1);
        }
        if record["outcome"] == "success" {
            assert_eq!(stream["parts_sorted"], stream["parts_planned"], "{record}");
        }
    }
    assert!(answered >= 1, "no drop answered in 4 streams");
    let (lying, laid) = lying_outcomes(&records);
    assert!(laid <= lying);
}
