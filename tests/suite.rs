//! `twincell sweep` and `twincell suite` through the real binary, on the smoke scenario in
//! oracle mode with few trials.

mod common;
use common::{read, report, twincell, without_timing};

use std::path::PathBuf;

use serde_json::Value;

const SMOKE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/smoke.toml");

/// `name` under this crate's temporary folder, absent: the command creates it.
fn out_dir(name: &str) -> PathBuf {
    common::absent_dir("suite", name)
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

fn run_ok(args: &[&str]) -> i32 {
    let (code, _, stderr) = twincell(args);
    assert_ne!(code, 2, "{stderr}");
    code
}

#[test]
fn a_sweep_runs_every_grid_point_through_the_batch_driver() {
    let out = out_dir("sweep");
    let out_s = out.to_str().expect("utf-8 path");
    // A 0.01 s wait for the part cannot succeed: the override must reach the trials.
    let code = run_ok(&[
        "sweep",
        SMOKE,
        "--set",
        "task.wait_timeout_s=6.0,0.01",
        "--set",
        "conveyor.speed_m_s=0.25",
        "--trials",
        "2",
        "--perception",
        "oracle",
        "--jobs",
        "2",
        "--min-success",
        "0.5",
        "--out",
        out_s,
    ]);
    assert_eq!(code, 1, "the point that cannot succeed fails its gate");
    let report = report(&out);
    assert_eq!(report["scenario"], "smoke");
    assert_eq!(report["seed"], 7);
    assert_eq!(report["perception"], "oracle");
    assert_eq!(report["passed"], false);
    assert_eq!(report["axes"][0]["key"], "task.wait_timeout_s");
    let points = report["points"].as_array().expect("points");
    assert_eq!(points.len(), 2);
    for (i, point) in points.iter().enumerate() {
        assert_eq!(point["point"], i);
        assert_eq!(point["overrides"]["conveyor.speed_m_s"], 0.25);
        assert_eq!(point["trials"], 2);
        let dir = out.join(point["dir"].as_str().expect("dir"));
        assert_eq!(without_timing(&dir).len(), 2, "{}", dir.display());
        for key in ["success_rate", "wilson95", "failures", "strict_successes"] {
            assert!(!point[key].is_null(), "{key} in {point}");
        }
    }
    assert_eq!(points[0]["overrides"]["task.wait_timeout_s"], 6.0);
    assert_eq!(points[0]["successes"], 2, "{}", points[0]);
    assert_eq!(points[0]["gate"]["passed"], true);
    assert_eq!(points[1]["overrides"]["task.wait_timeout_s"], 0.01);
    assert_eq!(points[1]["successes"], 0, "{}", points[1]);
    assert_eq!(points[1]["gate"]["passed"], false);

    // A point whose overrides restate the file gives `run`'s very trials, on one thread too.
    let plain = out_dir("sweep-plain-run");
    let code = run_ok(&[
        "run",
        SMOKE,
        "--trials",
        "2",
        "--perception",
        "oracle",
        "--jobs",
        "1",
        "--out",
        plain.to_str().expect("utf-8 path"),
    ]);
    assert_eq!(code, 0);
    assert_eq!(
        without_timing(&out.join("point-000")),
        without_timing(&plain)
    );
}

#[test]
fn a_sweep_shards_every_point() {
    let out = out_dir("sweep-shard");
    let code = run_ok(&[
        "sweep",
        SMOKE,
        "--set",
        "bottle.distance_range_m=[0.10,0.16],[0.12,0.16]",
        "--trials",
        "2",
        "--shard",
        "1/2",
        "--perception",
        "oracle",
        "--out",
        out.to_str().expect("utf-8 path"),
    ]);
    assert_eq!(code, 0);
    let report = report(&out);
    assert_eq!(report["shard"]["index"], 1);
    for point in report["points"].as_array().expect("points") {
        let dir = out.join(point["dir"].as_str().expect("dir"));
        let lines = without_timing(&dir);
        assert_eq!(lines.len(), 1);
        let record: Value = serde_json::from_str(&lines[0]).expect("record");
        assert_eq!(record["trial"], 1);
    }
}

#[test]
fn a_bad_override_is_bad_input_before_any_trial() {
    let out = out_dir("sweep-bad");
    let out_s = out.to_str().expect("utf-8 path");
    let cases: [(&str, &str); 3] = [
        ("sensor.noise_sigma=2,-1", "sensor.noise_sigma"),
        ("sensor.noise_sigmaa=2", "noise_sigmaa"),
        ("part_types.axle_q1.grip_force_n=40", "axle_q1"),
    ];
    for (set, key) in cases {
        let args = [
            "sweep",
            SMOKE,
            "--set",
            set,
            "--trials",
            "1",
            "--perception",
            "oracle",
        ];
        let (code, _, stderr) = twincell(&[&args[..], &["--out", out_s]].concat());
        assert_eq!(code, 2, "{set}: {stderr}");
        assert!(
            stderr.contains("smoke.toml") && stderr.contains(key),
            "{set}: {stderr}"
        );
        assert!(!out.exists(), "{set}: no trial may run");
    }
    let (code, _, stderr) = twincell(&["run", SMOKE, "--set", "bottle.enabled=maybe"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("bottle.enabled"), "{stderr}");
}

#[test]
fn a_suite_runs_every_scenario_file_with_its_gate_per_scenario() {
    let suite = out_dir("suite-files");
    std::fs::create_dir_all(&suite).expect("suite dir");
    let smoke = common::portable_text("smoke.toml");
    std::fs::write(suite.join("a_smoke.toml"), &smoke).expect("write");
    let hopeless = smoke.replace("name = \"smoke\"", "name = \"hopeless\"")
        + "\n[task]\nwait_timeout_s = 0.01\n";
    std::fs::write(suite.join("b_hopeless.toml"), hopeless).expect("write");
    std::fs::write(suite.join("notes.txt"), "not a scenario").expect("write");
    let out = out_dir("suite-out");
    let args = |min: &'static str| {
        vec![
            "suite".to_owned(),
            suite.to_str().expect("utf-8").to_owned(),
            "--trials".into(),
            "2".into(),
            "--perception".into(),
            "oracle".into(),
            "--min-success".into(),
            min.into(),
            "--out".into(),
            out.to_str().expect("utf-8").to_owned(),
        ]
    };
    let code = run_ok(&strs(&args("0.9")));
    assert_eq!(code, 1, "the hopeless scenario fails its gate");
    let report = report(&out);
    let rows = report["scenarios"].as_array().expect("scenarios");
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[0]["scenario"], "smoke");
    assert_eq!(rows[0]["successes"], 2);
    assert_eq!(rows[0]["gate"]["passed"], true);
    assert!(rows[0]["cycle_time_s"]["mean"].as_f64().expect("cycle") > 0.0);
    assert_eq!(rows[1]["scenario"], "hopeless");
    assert_eq!(rows[1]["successes"], 0);
    assert_eq!(rows[1]["gate"]["passed"], false);
    assert!(rows[1]["failures"].as_object().expect("failures").len() == 1);
    for (row, dir) in rows.iter().zip(["a_smoke", "b_hopeless"]) {
        assert_eq!(row["dir"], dir);
        assert_eq!(row["wilson95"].as_array().expect("interval").len(), 2);
        assert_eq!(without_timing(&out.join(dir)).len(), 2);
    }
    assert_eq!(report["passed"], false);
    let html = read(&out.join("report.html"));
    assert!(
        html.contains("hopeless") && html.contains("FAILED"),
        "{html}"
    );
    assert_eq!(run_ok(&strs(&args("0.0"))), 0);

    // A bad file stops the suite before any trial.
    std::fs::write(
        suite.join("c_bad.toml"),
        smoke.replace("trials = 4", "trials = 0"),
    )
    .expect("write");
    let _ = std::fs::remove_dir_all(&out);
    let (code, _, stderr) = twincell(&strs(&args("0.0")));
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("c_bad.toml") && stderr.contains("trials"),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn a_scenario_files_gate_applies_unless_min_success_replaces_it() {
    // fast_belt without its slow-down zone (the creep at the belt's own 0.5 m/s) fails every
    // trial (the belt cannot stop before the photo-eye), fast in oracle mode.
    let no_zone = "conveyor.creep_speed_m_s=0.5";
    let fast = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/suite/fast_belt.toml"
    );
    let dir = out_dir("file_gate");
    let out = dir.to_str().expect("UTF-8");
    let base = [
        "run",
        fast,
        "--set",
        no_zone,
        "--perception",
        "oracle",
        "--trials",
        "2",
        "--out",
        out,
    ];
    let gated = [&base[..], &["--set", "min_success=0.5"]].concat();
    assert_eq!(run_ok(&gated), 1, "the file's gate of 0.5 fails on 0/2");
    assert_eq!(report(&dir)["gate"]["min_success"], 0.5);
    let replaced = [&gated[..], &["--min-success", "0"]].concat();
    assert_eq!(
        run_ok(&replaced),
        0,
        "--min-success 0 replaces the file's gate"
    );
    assert_eq!(report(&dir)["gate"]["min_success"], 0.0);
    // The file's own gate, whatever the suite's rule has raised it to.
    let own = twincell::scenario::Scenario::load(std::path::Path::new(fast))
        .expect("fast_belt loads")
        .min_success
        .expect("fast_belt sets a gate");
    assert!(own > 0.0, "a gate that 0/2 fails");
    assert_eq!(
        run_ok(&base),
        1,
        "fast_belt's own gate of {own} fails on 0/2"
    );
    assert_eq!(report(&dir)["gate"]["min_success"], own);
    // paper_50's file sets no gate (every suite file now has one): the batch passes on its
    // exit code alone, and its report carries no gate.
    let ungated_file = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/paper_50.toml");
    let ungated = [
        "run",
        ungated_file,
        "--perception",
        "oracle",
        "--trials",
        "1",
        "--out",
        out,
    ];
    assert_eq!(run_ok(&ungated), 0, "paper_50's file sets no gate");
    assert!(report(&dir)["gate"].is_null());

    // suite and sweep take each scenario's own gate too.
    let sweep = out_dir("file_gate_sweep");
    let code = run_ok(&[
        "sweep",
        fast,
        "--perception",
        "oracle",
        "--trials",
        "1",
        "--set",
        "min_success=0.5,0",
        "--set",
        no_zone,
        "--out",
        sweep.to_str().expect("UTF-8"),
    ]);
    assert_eq!(code, 1);
    let points = report(&sweep)["points"].clone();
    assert_eq!(points[0]["gate"]["passed"], false, "{points}");
    assert_eq!(points[1]["gate"]["passed"], true, "{points}");
}
