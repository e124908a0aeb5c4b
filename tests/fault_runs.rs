//! Faults injected into real trials (oracle mode, a few trials each, every fault of a kind
//! forced on): each record lists the faults that struck with what the controller did,
//! report.json tallies them per kind, every lost part is in the records, and a fault run gives
//! the same records with `--jobs 1` and `--jobs 2`.

mod common;

use std::path::{Path, PathBuf};

use serde_json::Value;
use twincell::scenario::FAULT_KINDS;

const TRIALS: &str = "4";

/// Runs `scenarios/faults/KIND.toml` with its fault forced on; returns the output folder.
fn run_forced(kind: &str, jobs: &str, name: &str) -> PathBuf {
    let out = common::absent_dir("fault_runs", name);
    let scenario = common::scenario_path(&format!("faults/{kind}.toml"));
    let set = match kind {
        "photo_eye" => "faults.photo_eye.missed_trigger_rate=1".to_owned(),
        _ => format!("faults.{kind}.rate=1"),
    };
    let (code, _, stderr) = common::twincell(&[
        "run",
        common::path_str(&scenario),
        "--trials",
        TRIALS,
        "--perception",
        "oracle",
        "--jobs",
        jobs,
        "--min-success",
        "0",
        "--set",
        &set,
        "--out",
        common::path_str(&out),
    ]);
    assert_eq!(code, 0, "{kind}: {stderr}");
    out
}

fn records(dir: &Path) -> Vec<Value> {
    common::read(&dir.join("trials.jsonl"))
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect()
}

#[test]
fn every_fault_kind_forced_on_is_recorded_tallied_and_its_lost_parts_accounted_for() {
    for kind in FAULT_KINDS {
        let dir = run_forced(kind, "2", kind);
        let records = records(&dir);
        assert_eq!(records.len(), 4, "{kind}");
        let (mut injected, mut recovered, mut lost) = (0, 0, 0);
        for record in &records {
            let faults = record["faults"].as_array().cloned().unwrap_or_default();
            let own: Vec<&Value> = faults.iter().filter(|f| f["kind"] == *kind).collect();
            assert!(
                !own.is_empty(),
                "{kind}: trial {} lists no fault",
                record["trial"]
            );
            for fault in &own {
                let actions = fault["actions"].as_array().expect("actions");
                assert!(!actions.is_empty(), "{kind}: {fault}");
                injected += 1;
                recovered += u64::from(fault["recovered"] == true);
                let parts = fault["lost_parts"].as_u64().expect("lost_parts");
                lost += parts;
                if parts > 0 {
                    // A lost part is a failed trial that says so, and no recovery.
                    assert_eq!(record["outcome"], "failure", "{kind}: {record}");
                    assert_eq!(fault["recovered"], false, "{kind}: {fault}");
                    assert!(
                        actions.iter().any(|a| a == "counted_lost"),
                        "{kind}: {fault}"
                    );
                }
            }
        }
        let report = common::report(&dir);
        let tally = &report["faults"][kind];
        assert_eq!(
            tally["injected"].as_u64(),
            Some(injected),
            "{kind}: {report}"
        );
        assert_eq!(tally["recovered"].as_u64(), Some(recovered), "{kind}");
        assert_eq!(tally["lost"].as_u64(), Some(lost), "{kind}");
        let failures = report["failures"].as_object().cloned().unwrap_or_default();
        assert!(
            !failures.contains_key("panic") && !failures.contains_key("physics_blow_up"),
            "{kind}: {failures:?}"
        );
        let page = common::read(&dir.join("report.html"));
        assert!(
            page.contains("Faults injected") && page.contains(kind),
            "{kind}"
        );
    }
}

#[test]
fn a_fault_run_gives_the_same_records_with_one_job_and_two() {
    let one = run_forced("gripper", "1", "gripper_jobs1");
    let two = run_forced("gripper", "2", "gripper_jobs2");
    assert_eq!(
        common::trials_text_without_timing(&one),
        common::trials_text_without_timing(&two)
    );
}
