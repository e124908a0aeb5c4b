//! The batch runner with a test-double cell: determinism across jobs and shards, panics,
//! cancellation, reports, JUnit, and `twincell merge` through the binary.

mod common;
use common::fake_cell::FakeCell;
use common::{path_str, read, report, twincell, without_timing};

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use serde_json::Value;
use twincell::batch::{
    BatchPlan, FailureReason, Outcome, Perception, Shard, TrialRecord, TrialRunner, merge_shards,
    run_batch, trial_seed,
};

fn plan(trials: u32, jobs: usize, shard: Option<Shard>) -> BatchPlan {
    BatchPlan {
        scenario_name: "sort<six> & bottle".to_owned(),
        scenario_seed: 42,
        perception: Perception::Camera,
        trials,
        jobs: Some(jobs),
        shard,
        min_success: None,
    }
}

/// `name` under this crate's temporary folder, absent: the batch creates it.
fn out_dir(name: &str) -> PathBuf {
    common::absent_dir("batch", name)
}

fn run(cell: &FakeCell, plan: &BatchPlan, dir: &Path) -> twincell::batch::BatchSummary {
    run_batch(cell, plan, dir, &AtomicBool::new(false), false).expect("batch runs")
}

#[test]
fn trials_are_identical_whatever_the_jobs_or_shards() {
    let cell = FakeCell {
        sleepy: true,
        ..FakeCell::default()
    };
    let n = 40;
    let one = out_dir("det-jobs1");
    run(&cell, &plan(n, 1, None), &one);
    let expected = without_timing(&one);
    assert_eq!(expected.len(), n as usize);
    for (i, line) in expected.iter().enumerate() {
        let value: Value = serde_json::from_str(line).expect("JSON");
        assert_eq!(value["trial"], i);
        assert_eq!(value["seed"], trial_seed(42, i as u32));
    }
    for jobs in [2, 4] {
        let dir = out_dir(&format!("det-jobs{jobs}"));
        run(&cell, &plan(n, jobs, None), &dir);
        assert_eq!(without_timing(&dir), expected, "jobs {jobs}");
    }

    let shards: Vec<PathBuf> = (0..2)
        .map(|i| {
            let dir = out_dir(&format!("det-shard{i}"));
            let shard = Shard::new(i, 2).expect("shard");
            run(&cell, &plan(n, 3, Some(shard)), &dir);
            dir
        })
        .collect();
    assert_eq!(without_timing(&shards[1]).len(), 20);
    let merged = out_dir("det-merged");
    let summary = merge_shards(&shards, &merged, None).expect("merge");
    assert_eq!(summary.missing_trials, 0);
    assert_eq!(without_timing(&merged), expected);

    // The reports agree too, wall-clock figures aside.
    assert_eq!(
        common::report_without_timing(&merged),
        common::report_without_timing(&one)
    );
    assert_eq!(
        report(&shards[0])["shard"],
        serde_json::json!({"index": 0, "count": 2})
    );
}

#[test]
fn a_panicking_trial_is_a_failure_and_the_batch_goes_on() {
    let cell = FakeCell {
        panic_on: Some(3),
        ..FakeCell::default()
    };
    let dir = out_dir("panic");
    let summary = run(&cell, &plan(8, 2, None), &dir);
    assert_eq!(summary.report.trials, 8);
    assert!(!summary.report.interrupted);
    assert!(summary.report.failures.get("panic") == Some(&1));
    let lines = read(&dir.join("trials.jsonl"));
    let record: TrialRecord =
        serde_json::from_str(lines.lines().nth(3).expect("line 4")).expect("record");
    assert_eq!(record.outcome, Outcome::Failure);
    assert_eq!(record.failure, Some(FailureReason::Panic));
    assert_eq!(record.seed, trial_seed(42, 3));
    let detail = record.detail.unwrap_or_default();
    assert!(detail.contains("gripper <jammed>"), "{detail}");
}

#[test]
fn cancellation_keeps_every_finished_trial_and_says_interrupted() {
    for (jobs, k) in [(1, 5), (3, 7)] {
        let flag = Arc::new(AtomicBool::new(false));
        let cell = FakeCell {
            sleepy: true,
            cancel_after: Some((k - 1, Arc::clone(&flag))),
            ..FakeCell::default()
        };
        let dir = out_dir(&format!("cancel-{jobs}"));
        let summary =
            run_batch(&cell, &plan(30, jobs, None), &dir, &flag, false).expect("batch runs");
        let lines = without_timing(&dir);
        if jobs == 1 {
            assert_eq!(lines.len(), k as usize);
        } else {
            assert!(
                lines.len() >= k as usize && lines.len() < 30,
                "{}",
                lines.len()
            );
        }
        // A prefix of the trials, in order.
        for (i, line) in lines.iter().enumerate() {
            let value: Value = serde_json::from_str(line).expect("JSON");
            assert_eq!(value["trial"], i);
        }
        let report = report(&dir);
        assert_eq!(report["interrupted"], true);
        assert_eq!(report["trials"], lines.len());
        assert_eq!(report["scenario_trials"], 30);
        assert_eq!(summary.exit_code(), 1);
        let junit = read(&dir.join("junit.xml"));
        assert_eq!(junit.matches("<testcase ").count(), lines.len());
    }
}

#[test]
fn report_holds_the_contract_fields() {
    let cell = FakeCell::default();
    let dir = out_dir("report");
    let mut plan = plan(50, 2, None);
    plan.perception = Perception::Oracle;
    plan.min_success = Some(0.5);
    let summary = run(&cell, &plan, &dir);
    let r = report(&dir);
    for key in [
        "scenario",
        "seed",
        "perception",
        "trials",
        "successes",
        "success_rate",
        "wilson95",
        "failures",
        "distractor_picks",
        "distractor_touches",
        "distractor_max_displacement_mm",
        "metrology",
        "sorting",
        "cycle_time_s",
        "parts_per_minute",
        "timing",
        "shard",
        "interrupted",
    ] {
        assert!(r.get(key).is_some(), "report.json lacks {key}");
    }
    assert_eq!(r["perception"], "oracle");
    assert!(
        r["perception_note"]
            .as_str()
            .unwrap_or("")
            .contains("ORACLE")
    );
    assert_eq!(r["trials"], 50);
    let successes = r["successes"].as_u64().expect("successes");
    let failures: u64 = r["failures"]
        .as_object()
        .expect("failures")
        .values()
        .map(|v| v.as_u64().expect("count"))
        .sum();
    assert_eq!(successes + failures, 50);
    let w = &r["wilson95"];
    let (low, high) = (w[0].as_f64().expect("low"), w[1].as_f64().expect("high"));
    let rate = r["success_rate"].as_f64().expect("rate");
    assert!(low < rate && rate < high);
    assert_eq!(r["metrology"]["count"], 50);
    assert_eq!(r["metrology"]["roundness_error_mm"]["count"], 50);
    assert_eq!(r["sorting"]["count"], 50);
    let stage_total = r["timing"]["stages"]["physics"]["total_s"]
        .as_f64()
        .expect("physics");
    assert!((stage_total - 0.075).abs() < 1e-9);
    assert_eq!(r["gate"]["passed"], true);
    assert_eq!(summary.exit_code(), 0);
    let table = summary.report.summary_table();
    assert!(
        table.contains("ORACLE") && table.contains("Wilson"),
        "{table}"
    );
}

/// Checks `xml` is well-formed in the subset junit.xml uses (declaration, elements,
/// attributes in double quotes, escaped text) and returns the element names in order.
fn check_xml(xml: &str) -> Vec<String> {
    let mut stack: Vec<String> = Vec::new();
    let mut names = Vec::new();
    let mut rest = xml.trim_start();
    let decl_end = rest.find("?>").expect("XML declaration");
    assert!(rest.starts_with("<?xml "));
    rest = &rest[decl_end + 2..];
    let check_text = |text: &str| {
        assert!(!text.contains('>'), "raw > in {text:?}");
        for (i, _) in text.match_indices('&') {
            let entity = &text[i..text[i..].find(';').map_or(text.len(), |e| i + e + 1)];
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"].contains(&entity)
                    || entity.starts_with("&#"),
                "bad entity {entity:?}"
            );
        }
    };
    while let Some(open) = rest.find('<') {
        check_text(&rest[..open]);
        let close = rest[open..].find('>').expect("tag closes") + open;
        let tag = &rest[open + 1..close];
        rest = &rest[close + 1..];
        if let Some(name) = tag.strip_prefix('/') {
            assert_eq!(stack.pop().as_deref(), Some(name), "mismatched </{name}>");
            continue;
        }
        let self_closing = tag.ends_with('/');
        let body = tag.trim_end_matches('/');
        let name: String = body.chars().take_while(|c| !c.is_whitespace()).collect();
        assert!(!name.is_empty() && !name.contains(['<', '"', '&']), "{tag}");
        // Attributes: name="value" pairs, values free of < and raw quotes.
        let mut attrs = body[name.len()..].trim();
        while !attrs.is_empty() {
            let eq = attrs.find("=\"").expect("attr=\"");
            let end = attrs[eq + 2..].find('"').expect("closing quote") + eq + 2;
            let value = &attrs[eq + 2..end];
            assert!(!value.contains('<'), "< in attribute {value:?}");
            check_text(value);
            attrs = attrs[end + 1..].trim_start();
        }
        names.push(name.clone());
        if !self_closing {
            stack.push(name);
        }
    }
    assert!(rest.trim().is_empty(), "trailing text {rest:?}");
    assert!(stack.is_empty(), "unclosed {stack:?}");
    names
}

#[test]
fn junit_is_well_formed_with_one_testcase_per_trial() {
    let cell = FakeCell {
        panic_on: Some(2),
        ..FakeCell::default()
    };
    let dir = out_dir("junit");
    let summary = run(&cell, &plan(12, 2, None), &dir);
    let xml = read(&dir.join("junit.xml"));
    let names = check_xml(&xml);
    assert_eq!(names.iter().filter(|n| *n == "testcase").count(), 12);
    let failures = (summary.report.trials - summary.report.successes) as usize;
    assert_eq!(names.iter().filter(|n| *n == "failure").count(), failures);
    assert!(
        xml.contains(r#"<testcase name="trial_0007" classname="sort&lt;six&gt; &amp; bottle""#)
    );
    assert!(xml.contains(r#"<failure message="panic" type="panic">gripper &lt;jammed&gt;"#));
}

fn shard_pair(name: &str, n: u32) -> (PathBuf, PathBuf) {
    let cell = FakeCell::default();
    let a = out_dir(&format!("{name}-0"));
    let b = out_dir(&format!("{name}-1"));
    run(
        &cell,
        &plan(n, 2, Some(Shard::new(0, 2).expect("shard"))),
        &a,
    );
    run(
        &cell,
        &plan(n, 2, Some(Shard::new(1, 2).expect("shard"))),
        &b,
    );
    (a, b)
}

#[test]
fn merge_binary_merges_shards() {
    let (a, b) = shard_pair("cli-ok", 10);
    let out = out_dir("cli-ok-merged");
    let (code, stdout, stderr) = twincell(&[
        "merge",
        path_str(&a),
        path_str(&b),
        "--out",
        path_str(&out),
        "--json",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let merged: Value = serde_json::from_str(&stdout).expect("report on stdout");
    assert_eq!(merged["trials"], 10);
    assert_eq!(merged["shard"], Value::Null);
    assert_eq!(without_timing(&out).len(), 10);

    // One shard alone leaves trials uncovered: reports written, exit 1.
    let out = out_dir("cli-ok-half");
    let (code, _, stderr) = twincell(&["merge", path_str(&a), "--out", path_str(&out)]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("in no shard"), "{stderr}");
}

#[test]
fn merge_binary_rejects_mismatched_shards() {
    let (a, b) = shard_pair("cli-mismatch", 10);
    let cell = FakeCell::default();
    let other_seed = out_dir("cli-mismatch-seed");
    let mut plan_b = plan(10, 2, Some(Shard::new(1, 2).expect("shard")));
    plan_b.scenario_seed = 7;
    run(&cell, &plan_b, &other_seed);
    let out = out_dir("cli-mismatch-out");
    let (code, _, stderr) = twincell(&[
        "merge",
        path_str(&a),
        path_str(&other_seed),
        "--out",
        path_str(&out),
    ]);
    assert_eq!(code, 2, "{stderr}");
    let report_path = other_seed.join("report.json");
    assert!(stderr.contains(path_str(&report_path)), "{stderr}");
    assert!(stderr.contains("`seed`"), "{stderr}");

    let mut plan_oracle = plan(10, 2, Some(Shard::new(1, 2).expect("shard")));
    plan_oracle.perception = Perception::Oracle;
    let oracle = out_dir("cli-mismatch-oracle");
    run(&cell, &plan_oracle, &oracle);
    let (code, _, stderr) = twincell(&[
        "merge",
        path_str(&a),
        path_str(&oracle),
        "--out",
        path_str(&out),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("`perception`"), "{stderr}");

    // The same shard twice overlaps.
    let (code, _, stderr) =
        twincell(&["merge", path_str(&b), path_str(&b), "--out", path_str(&out)]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("already in"), "{stderr}");
    assert!(
        stderr.contains(path_str(&b.join("trials.jsonl"))),
        "{stderr}"
    );
}

#[test]
fn merge_binary_rejects_malformed_lines_naming_file_and_line() {
    let (a, b) = shard_pair("cli-malformed", 10);
    let trials = b.join("trials.jsonl");
    let text = read(&trials);
    let mut lines: Vec<&str> = text.lines().collect();
    lines[2] = "{\"trial\": 5, \"seed\": ";
    std::fs::write(&trials, lines.join("\n") + "\n").expect("write");
    let out = out_dir("cli-malformed-out");
    let (code, _, stderr) =
        twincell(&["merge", path_str(&a), path_str(&b), "--out", path_str(&out)]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains(path_str(&trials)), "{stderr}");
    assert!(stderr.contains("line 3"), "{stderr}");

    let missing = out_dir("cli-malformed-missing");
    let (code, _, stderr) = twincell(&[
        "merge",
        path_str(&a),
        path_str(&missing),
        "--out",
        path_str(&out),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("report.json"), "{stderr}");
}

/// A cell that sends its own process SIGTERM in trial `at`, as `kill` or Kubernetes would.
#[cfg(unix)]
struct SignalledCell {
    at: u32,
}

#[cfg(unix)]
impl TrialRunner for SignalledCell {
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord {
        if index == self.at {
            signal_hook::low_level::raise(signal_hook::consts::SIGTERM).expect("raise");
        }
        FakeCell::default().run_trial(index, seed)
    }
}

#[cfg(unix)]
#[test]
fn sigterm_interrupts_the_batch_through_cancel_on_signals() {
    let flag = Arc::new(AtomicBool::new(false));
    twincell::batch::cancel_on_signals(&flag).expect("handlers installed");
    let dir = out_dir("sigterm");
    let summary = run_batch(
        &SignalledCell { at: 4 },
        &plan(20, 1, None),
        &dir,
        &flag,
        false,
    )
    .expect("batch runs");
    assert!(flag.load(Ordering::SeqCst));
    assert!(summary.report.interrupted);
    assert_eq!(summary.report.trials, 5);
    assert_eq!(without_timing(&dir).len(), 5);
}
