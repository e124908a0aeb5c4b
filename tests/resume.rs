//! `twincell run --resume`: a batch killed at any instant continues to the files an
//! uninterrupted run writes; a directory of another batch or with damaged records is refused.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

mod common;

use serde_json::Value;
use twincell::batch::{
    BatchError, BatchOptions, BatchPlan, Outcome, PartRecord, Perception, ResumeError, Shard,
    TrialRecord, TrialRunner, merge_shards, run_batch, run_batch_with,
};
use twincell::rng::SimRng;

/// The binary under test: cargo's, or `TWINCELL_BIN` when set (a copy taken right after the
/// build, for machines where several checkouts share one target directory and its binary).
fn bin() -> PathBuf {
    std::env::var_os("TWINCELL_BIN").map_or_else(
        || PathBuf::from(env!("CARGO_BIN_EXE_twincell")),
        PathBuf::from,
    )
}

/// Runs the binary; returns its exit code, stdout and stderr.
fn twincell(args: &[&str]) -> (i32, String, String) {
    let output = Command::new(bin())
        .args(args)
        .output()
        .expect("binary runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("resume")
        .join(name);
    let _ = fs::remove_dir_all(&dir);
    dir
}

fn read(path: &Path) -> String {
    fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn path_str(path: &Path) -> &str {
    path.to_str().expect("UTF-8 path")
}

/// `trials.jsonl` with each line's `"timing":{...}` object cut out, bytes otherwise untouched.
fn trials_without_timing(dir: &Path) -> String {
    let text = read(&dir.join("trials.jsonl"));
    let mut out = String::new();
    for line in text.split_inclusive('\n') {
        let start = line.find(",\"timing\":{").expect("a timing object");
        let end = start + line[start..].find('}').expect("its end") + 1;
        out.push_str(&line[..start]);
        out.push_str(&line[end..]);
    }
    out
}

/// `report.json` without its wall-clock `timing`.
fn report_without_timing(dir: &Path) -> Value {
    let mut report: Value = serde_json::from_str(&read(&dir.join("report.json"))).expect("JSON");
    report
        .as_object_mut()
        .expect("object")
        .remove("timing")
        .expect("timing");
    report
}

/// A cell whose records are a function of the seed, with floats of every size.
struct SeededCell;

impl TrialRunner for SeededCell {
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord {
        let mut rng = SimRng::new(seed);
        let mut record =
            TrialRecord::failed(index, seed, twincell::batch::FailureReason::Slipped, "slid");
        if rng.uniform() < 0.7 {
            record.outcome = Outcome::Success;
            record.failure = None;
            record.detail = None;
        }
        record.part = Some(PartRecord {
            part_type: "axle".into(),
            true_roundness_mm: rng.range(0.0, 1.0) * 1e-7,
            true_bore_diameter_mm: rng.range(18.0, 30.0),
            truly_acceptable: true,
            clear_cut: true,
            correct_bin: "axle".into(),
        });
        record.cycle_time_s = rng.range(5.0, 9.0);
        record.sim_time_s = rng.range(9.0, 12.0) * 1e9;
        record
    }
}

fn plan(trials: u32, shard: Option<Shard>) -> BatchPlan {
    BatchPlan {
        scenario_name: "resume".into(),
        scenario_seed: 11,
        perception: Perception::Oracle,
        trials,
        jobs: Some(2),
        shard,
        min_success: None,
    }
}

fn resume_options() -> BatchOptions {
    BatchOptions {
        scenario_sha256: None,
        resume: true,
    }
}

fn resume(dir: &Path, plan: &BatchPlan) -> Result<(), BatchError> {
    let cancel = AtomicBool::new(false);
    run_batch_with(&SeededCell, plan, &resume_options(), dir, &cancel, false).map(|_| ())
}

#[test]
fn a_torn_last_line_is_dropped_and_the_batch_completes_as_uninterrupted() {
    let whole = out_dir("torn-whole");
    let cancel = AtomicBool::new(false);
    run_batch(&SeededCell, &plan(12, None), &whole, &cancel, false).expect("batch");
    let text = read(&whole.join("trials.jsonl"));
    let offsets: Vec<usize> = text.match_indices('\n').map(|(i, _)| i + 1).collect();

    // Cut the file at every kind of place: nothing, mid-line, right after a newline, all.
    for cut in [
        0,
        1,
        offsets[0],
        offsets[4] + 17,
        offsets[9] - 1,
        text.len(),
    ] {
        let dir = out_dir(&format!("torn-{cut}"));
        fs::create_dir_all(&dir).expect("dir");
        fs::copy(whole.join("batch.json"), dir.join("batch.json")).expect("manifest");
        fs::write(dir.join("trials.jsonl"), &text[..cut]).expect("write");
        resume(&dir, &plan(12, None)).expect("resumes");
        assert_eq!(trials_without_timing(&dir), trials_without_timing(&whole));
        assert_eq!(report_without_timing(&dir), report_without_timing(&whole));
        // Kept records keep their bytes, timing included.
        let kept = &text[..offsets.iter().rev().find(|&&o| o <= cut).map_or(0, |&o| o)];
        assert!(
            read(&dir.join("trials.jsonl")).starts_with(kept),
            "cut {cut}"
        );
    }
}

#[test]
fn a_shard_resumes_and_a_missing_directory_starts_fresh() {
    let shard = Some(Shard::new(1, 3).expect("shard"));
    let whole = out_dir("shard-whole");
    run_batch(
        &SeededCell,
        &plan(20, shard),
        &whole,
        &AtomicBool::new(false),
        false,
    )
    .expect("batch");
    let dir = out_dir("shard-resumed");
    resume(&dir, &plan(20, shard)).expect("a missing directory starts the batch");
    assert_eq!(trials_without_timing(&dir), trials_without_timing(&whole));
    // A complete directory resumes to itself.
    resume(&dir, &plan(20, shard)).expect("nothing left to run");
    assert_eq!(trials_without_timing(&dir), trials_without_timing(&whole));
    assert_eq!(report_without_timing(&dir), report_without_timing(&whole));
}

#[test]
fn damaged_or_foreign_records_are_refused_naming_the_line() {
    let whole = out_dir("damaged-whole");
    run_batch(
        &SeededCell,
        &plan(6, None),
        &whole,
        &AtomicBool::new(false),
        false,
    )
    .expect("batch");
    let text = read(&whole.join("trials.jsonl"));
    let lines: Vec<&str> = text.lines().collect();
    let cases: [(&str, String, &str); 4] = [
        (
            "garbage",
            format!("{}\n{{\"trial\": 1,\n", lines[0]),
            "line 2",
        ),
        ("swapped", format!("{}\n{}\n", lines[1], lines[0]), "line 1"),
        ("skipped", format!("{}\n{}\n", lines[0], lines[2]), "line 2"),
        (
            "reseeded",
            format!("{}\n", lines[0].replacen("\"seed\":", "\"seed\":1", 1)),
            "line 1",
        ),
    ];
    for (name, content, line) in cases {
        let dir = out_dir(&format!("damaged-{name}"));
        fs::create_dir_all(&dir).expect("dir");
        fs::copy(whole.join("batch.json"), dir.join("batch.json")).expect("manifest");
        fs::write(dir.join("trials.jsonl"), &content).expect("write");
        let err = resume(&dir, &plan(6, None)).expect_err(name);
        assert!(err.is_bad_input(), "{name}: {err}");
        let message = err.to_string();
        assert!(
            message.contains(path_str(&dir.join("trials.jsonl"))),
            "{message}"
        );
        assert!(message.contains(line), "{name}: {message}");
        // Refused means untouched.
        assert_eq!(read(&dir.join("trials.jsonl")), content, "{name}");
    }

    // Records without a manifest cannot be told apart from another batch's.
    let dir = out_dir("damaged-no-manifest");
    fs::create_dir_all(&dir).expect("dir");
    fs::write(dir.join("trials.jsonl"), &text).expect("write");
    let err = resume(&dir, &plan(6, None)).expect_err("no manifest");
    assert!(
        matches!(err, BatchError::Resume(ResumeError::NoManifest { .. })),
        "{err}"
    );
}

#[test]
fn merge_counts_a_killed_shard_by_its_manifest() {
    let shards = [Shard::new(0, 2), Shard::new(1, 2)].map(|s| Some(s.expect("shard")));
    let dirs = [out_dir("merge-killed-0"), out_dir("merge-killed-1")];
    for (dir, shard) in dirs.iter().zip(shards) {
        run_batch(
            &SeededCell,
            &plan(10, shard),
            dir,
            &AtomicBool::new(false),
            false,
        )
        .expect("batch");
    }
    // Shard 1 "killed" mid-line of its third record, before writing its report.
    let trials = dirs[1].join("trials.jsonl");
    let text = read(&trials);
    let third = text.match_indices('\n').nth(1).expect("3 lines").0 + 1;
    fs::write(&trials, &text[..third + 10]).expect("write");
    fs::remove_file(dirs[1].join("report.json")).expect("rm");
    let merged = out_dir("merge-killed-out");
    let summary = merge_shards(&dirs, &merged, None).expect("merges");
    assert!(summary.report.interrupted);
    assert_eq!(summary.report.trials, 5 + 2);
    assert_eq!(summary.missing_trials, 3);

    // Resumed, the shard merges into the unsharded run's files.
    resume(&dirs[1], &plan(10, shards[1])).expect("resumes");
    let summary = merge_shards(&dirs, &merged, None).expect("merges");
    assert!(!summary.report.interrupted);
    let whole = out_dir("merge-killed-whole");
    run_batch(
        &SeededCell,
        &plan(10, None),
        &whole,
        &AtomicBool::new(false),
        false,
    )
    .expect("batch");
    assert_eq!(
        trials_without_timing(&merged),
        trials_without_timing(&whole)
    );
}

/// Runs `twincell run` on a scenario in oracle mode and returns its exit code and stderr.
fn run_cli(args: &[&str]) -> (i32, String) {
    let (code, _, stderr) = twincell(&[&["run"][..], args].concat());
    (code, stderr)
}

#[test]
fn resume_refuses_another_batch_with_exit_2_naming_the_field() {
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/smoke.toml");
    let dir = out_dir("cli-mismatch");
    let base = [
        scenario,
        "--perception",
        "oracle",
        "--trials",
        "2",
        "--jobs",
        "1",
    ];
    let (code, stderr) = run_cli(&[&base[..], &["--out", path_str(&dir)]].concat());
    assert_eq!(code, 0, "{stderr}");
    let before = read(&dir.join("trials.jsonl"));

    let edited = out_dir("cli-mismatch-scenario").join("smoke.toml");
    fs::create_dir_all(edited.parent().expect("parent")).expect("dir");
    fs::write(
        &edited,
        common::portable_text("smoke.toml") + "\n# edited\n",
    )
    .expect("write");
    let edited = path_str(&edited);
    let cases: [(&str, Vec<&str>); 6] = [
        ("seed", vec![scenario, "--seed", "8", "--trials", "2"]),
        (
            "perception",
            vec![scenario, "--perception", "camera", "--trials", "2"],
        ),
        ("scenario_trials", vec![scenario, "--trials", "3"]),
        ("shard", vec![scenario, "--trials", "2", "--shard", "0/2"]),
        ("scenario_sha256", vec![edited, "--trials", "2"]),
        ("scenario_trials", vec![scenario]),
    ];
    for (field, args) in cases {
        let mut args = args;
        if !args.contains(&"--perception") {
            args.extend(["--perception", "oracle"]);
        }
        args.extend(["--resume", path_str(&dir)]);
        let (code, stderr) = run_cli(&args);
        assert_eq!(code, 2, "{field}: {stderr}");
        assert!(stderr.contains(&format!("`{field}`")), "{field}: {stderr}");
        assert!(
            stderr.contains(path_str(&dir.join("batch.json"))),
            "{stderr}"
        );
        assert_eq!(read(&dir.join("trials.jsonl")), before, "{field}");
    }
    // --out and --resume name the directory twice.
    let (code, stderr) = run_cli(&[&base[..], &["--out", "x", "--resume", "y"]].concat());
    assert_eq!(code, 2, "{stderr}");
}

/// 20 batches of paper_50 (oracle, 50 trials), each SIGKILLed at a random instant and resumed,
/// all end byte-identical to the uninterrupted run (timing aside), report.json included.
#[test]
fn sigkill_at_random_instants_then_resume_gives_the_uninterrupted_files() {
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/paper_50.toml");
    let args = |dir: &Path, flag: &str| {
        [
            "run",
            scenario,
            "--perception",
            "oracle",
            "--jobs",
            "2",
            flag,
            path_str(dir),
        ]
        .map(str::to_owned)
    };
    let whole = out_dir("kill-whole");
    let started = Instant::now();
    let status = Command::new(bin())
        .args(args(&whole, "--out"))
        .stdout(Stdio::null())
        .status()
        .expect("runs");
    let full = started.elapsed();
    assert!(status.success(), "{status}");
    let expected_trials = trials_without_timing(&whole);
    let expected_report = report_without_timing(&whole);
    assert_eq!(expected_trials.lines().count(), 50);

    // Instants spread over the uninterrupted run's wall time, from a fixed seed.
    let mut rng = SimRng::new(20_261_201);
    let mut on_disk = Vec::new();
    for run in 0..20 {
        let dir = out_dir(&format!("kill-{run}"));
        let delay = full.mul_f64(rng.uniform());
        let mut child = Command::new(bin())
            .args(args(&dir, "--resume"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawns");
        std::thread::sleep(delay);
        // SIGKILL: no handler runs, nothing is flushed or reported.
        child.kill().expect("killed");
        let status = child.wait().expect("reaped");
        let lines = fs::read_to_string(dir.join("trials.jsonl"))
            .map(|t| t.matches('\n').count())
            .unwrap_or(0);
        on_disk.push((delay, lines, status.success()));

        let (code, _, stderr) = twincell(&args(&dir, "--resume").each_ref().map(String::as_str));
        assert_eq!(code, 0, "run {run}: {stderr}");
        assert_eq!(
            trials_without_timing(&dir),
            expected_trials,
            "run {run} killed after {delay:?} with {lines} trials on disk"
        );
        assert_eq!(report_without_timing(&dir), expected_report, "run {run}");
    }
    eprintln!("uninterrupted: {full:?}; (kill after, trials on disk, finished first): {on_disk:?}");
    // The kills must have landed inside batches, not only before or after them.
    let mid_batch = on_disk
        .iter()
        .filter(|(_, lines, finished)| (1..50).contains(lines) && !finished)
        .count();
    assert!(
        mid_batch >= 5,
        "only {mid_batch} kills mid-batch: {on_disk:?}"
    );
}
