//! The grip watch on real trials (oracle mode, the gripper fault forced on in every trial): the
//! controller feels every weakened grip from the jaws' force before the part is gone, takes it
//! again or sets the part down and picks it again, and picks a part it sees lying by its body.

mod common;

use serde_json::Value;

#[test]
fn every_weakened_grip_is_felt_and_most_parts_are_set_down_and_sorted() {
    let out = common::absent_dir("faults_grip", "forced");
    let scenario = common::scenario_path("faults/gripper.toml");
    let (code, _, stderr) = common::twincell(&[
        "run",
        common::path_str(&scenario),
        "--trials",
        "16",
        "--perception",
        "oracle",
        "--jobs",
        "2",
        "--min-success",
        "0",
        "--set",
        "faults.gripper.rate=1",
        "--out",
        common::path_str(&out),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let records: Vec<Value> = common::read(&out.join("trials.jsonl"))
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    assert_eq!(records.len(), 16);
    let mut sorted = 0;
    for record in &records {
        let faults = record["faults"].as_array().cloned().unwrap_or_default();
        let [fault] = faults.as_slice() else {
            panic!("trial {}: one fault expected: {faults:?}", record["trial"]);
        };
        let actions: Vec<&str> = fault["actions"]
            .as_array()
            .expect("actions")
            .iter()
            .filter_map(Value::as_str)
            .collect();
        // Felt from the force, before (or instead of) any drop the jaws show.
        assert_eq!(actions.first(), Some(&"saw_weak_grip"), "{fault}");
        let answered = actions.contains(&"regripped")
            || actions.contains(&"set_down")
            || actions.contains(&"saw_drop");
        assert!(answered, "{fault}");
        if actions.contains(&"saw_lying_part") {
            let lying = &fault["saw_lying_part"];
            assert_eq!(lying["part_type"], record["part"]["part_type"], "{fault}");
            // Picked again lying: laid in its bin, or counted lost with its reason, or the trial
            // failed with its own (a bottle the pick touched).
            let laid = fault["recovered"] == true && actions.contains(&"repicked_lying");
            let failed = record["outcome"] == "failure" && record["failure"].is_string();
            assert!(
                laid || actions.contains(&"counted_lost") || failed,
                "{fault}"
            );
        } else {
            assert!(fault.get("saw_lying_part").is_none(), "{fault}");
        }
        sorted += usize::from(record["outcome"] == "success");
    }
    // Measured 15 of 16 (6 December 2026, the jaws kinematic fingers, which feel most weakened
    // grips in time to set the part down): one fell lying, was picked lying, its grip weakened
    // again in the lift and it was counted lost (14 of 16 with the arm's multibody: 3 lying, one
    // laid, two against the belt's rail).
    assert!(sorted >= 12, "{sorted} of 16 sorted");
}
