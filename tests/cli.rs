//! The command-line contract: JSON shapes and exit codes, through the real binary.

mod common;
use common::twincell;

use serde_json::Value;

fn numbers(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .expect("array")
        .iter()
        .map(|v| v.as_f64().expect("number"))
        .collect()
}

#[test]
fn fk_then_ik_round_trips_through_the_cli() {
    let q = ["0.4", "-0.7", "1.3", "0.2", "-1.1", "2.0"];
    let mut args = vec!["fk"];
    args.extend(q);
    args.push("--json");
    let (code, stdout, stderr) = twincell(&args);
    assert_eq!(code, 0, "{stderr}");
    let fk: Value = serde_json::from_str(&stdout).expect("fk JSON");
    let xyz = numbers(&fk["xyz"]);
    let rpy = numbers(&fk["rpy"]);
    let matrix: Vec<Vec<f64>> = fk["matrix"]
        .as_array()
        .expect("rows")
        .iter()
        .map(numbers)
        .collect();
    assert_eq!((xyz.len(), rpy.len(), matrix.len()), (3, 3, 4));
    for i in 0..3 {
        assert!((matrix[i][3] - xyz[i]).abs() < 1e-12);
    }
    assert_eq!(matrix[3], vec![0.0, 0.0, 0.0, 1.0]);
    // R = Rz(yaw) Ry(pitch) Rx(roll): element (2,0) is -sin(pitch).
    assert!((matrix[2][0] + rpy[1].sin()).abs() < 1e-12);

    let pose: Vec<String> = xyz.iter().chain(&rpy).map(|v| format!("{v:.17}")).collect();
    let mut args = vec!["ik"];
    args.extend(pose.iter().map(String::as_str));
    args.push("--json");
    let (code, stdout, stderr) = twincell(&args);
    assert_eq!(code, 0, "{stderr}");
    let ik: Value = serde_json::from_str(&stdout).expect("ik JSON");
    let solutions: Vec<Vec<f64>> = ik["solutions"]
        .as_array()
        .expect("list")
        .iter()
        .map(numbers)
        .collect();
    let expected: Vec<f64> = q.iter().map(|v| v.parse().expect("number")).collect();
    assert!(
        solutions
            .iter()
            .any(|s| s.iter().zip(&expected).all(|(a, b)| (a - b).abs() < 1e-9))
    );
}

#[test]
fn unreachable_pose_gives_an_empty_list() {
    let (code, stdout, _) = twincell(&["ik", "2.0", "0", "0.3", "0", "0", "0", "--json"]);
    assert_eq!(code, 0);
    let ik: Value = serde_json::from_str(&stdout).expect("ik JSON");
    assert_eq!(ik["solutions"].as_array().map(Vec::len), Some(0));
}

#[test]
fn bad_input_exits_with_code_2_and_says_why() {
    let (code, _, stderr) = twincell(&["fk", "0", "0", "0", "0", "0", "nan", "--json"]);
    assert_eq!(code, 2);
    assert!(stderr.contains("value 6 is not finite"), "{stderr}");
    let (code, _, _) = twincell(&["fk", "0", "0", "0", "--json"]);
    assert_eq!(code, 2);
    let (code, _, stderr) = twincell(&["demo", "--speed", "3"]);
    assert_eq!(code, 2);
    assert!(stderr.contains("--speed"), "{stderr}");
}

#[test]
fn a_success_rate_outside_zero_to_one_is_bad_input() {
    for command in ["run", "merge"] {
        let (code, _, stderr) = twincell(&[
            command,
            "scenarios/smoke.toml",
            "--min-success",
            "1.5",
            "--out",
            "target/never-written",
        ]);
        assert_eq!(code, 2, "{command}: {stderr}");
        assert!(stderr.contains("--min-success"), "{command}: {stderr}");
    }
}

#[test]
fn bench_reports_each_stage_and_the_cost_of_a_simulated_second() {
    let out = common::absent_dir("cli", "bench");
    let (code, stdout, stderr) = twincell(&[
        "bench",
        "scenarios/smoke.toml",
        "--perception",
        "oracle",
        "--trials",
        "2",
        "--jobs",
        "1",
        "--out",
        common::path_str(&out),
        "--json",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let bench: Value = serde_json::from_str(&stdout).expect("bench JSON");
    assert_eq!(bench["trials"], 2);
    let stages = bench["stages"].as_array().expect("stages");
    let names: Vec<&str> = stages.iter().filter_map(|s| s["stage"].as_str()).collect();
    assert_eq!(
        names,
        [
            "physics",
            "render",
            "detect",
            "metrology",
            "planning",
            "other"
        ]
    );
    let share: f64 = stages.iter().filter_map(|s| s["share"].as_f64()).sum();
    assert!((share - 1.0).abs() < 1e-6, "shares sum to {share}");
    let sim_s = bench["sim_time_s"].as_f64().expect("sim_time_s");
    let total_s = bench["trial_total_s"].as_f64().expect("trial_total_s");
    let per_sim_s = bench["wall_per_sim_s"].as_f64().expect("wall_per_sim_s");
    assert!(sim_s > 1.0 && total_s > 0.0, "{sim_s} {total_s}");
    assert!((per_sim_s - total_s / sim_s).abs() < 1e-9, "{per_sim_s}");
}

/// `twincell dataset --family --occlude` sets bottles in front of tubes: of 30 shots of the
/// paper's cell, some hold a tube with 0.5-0.9 of its end face in view (recorded beside its
/// label), none one hidden past half; without `--occlude` the same shots hold none partly hidden
/// by a moved bottle. `--occlude` without `--family` is refused.
#[test]
fn family_datasets_set_bottles_in_front_of_tubes_on_request() {
    let scenario = common::scenario_path("paper_50.toml");
    let scenario = scenario.to_str().expect("utf-8 path");
    let mut partly = [0usize; 2];
    for (k, occlude) in [false, true].into_iter().enumerate() {
        let out = common::out_dir("cli", if occlude { "occluded" } else { "clear" });
        let out = out.to_str().expect("utf-8 path");
        let mut args = vec![
            "dataset",
            scenario,
            "--count",
            "30",
            "--out",
            out,
            "--resolution",
            "640",
            "480",
            "--family",
        ];
        if occlude {
            args.push("--occlude");
        }
        let (code, _, stderr) = twincell(&args);
        assert_eq!(code, 0, "{stderr}");
        for split in ["train", "val"] {
            let dir = std::path::Path::new(out).join("labels").join(split);
            for entry in std::fs::read_dir(&dir).expect("labels") {
                let path = entry.expect("entry").path();
                if path.extension().is_none_or(|e| e != "json") {
                    continue;
                }
                let meta: Value =
                    serde_json::from_str(&std::fs::read_to_string(&path).expect("json"))
                        .expect("label metadata");
                for tube in meta["tubes"].as_array().expect("tubes") {
                    let seen = tube["face_visible"].as_f64().expect("face_visible");
                    if occlude {
                        assert!(seen >= 0.5, "{}: {tube}", path.display());
                    }
                    partly[k] += usize::from(seen < 0.9);
                }
            }
        }
    }
    assert!(
        partly[1] >= 2,
        "partly hidden tubes with --occlude: {partly:?}"
    );
    assert!(partly[1] > partly[0], "{partly:?}");
    let (code, _, stderr) = twincell(&["dataset", scenario, "--out", "/tmp/x", "--occlude"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("--family"), "{stderr}");
}
