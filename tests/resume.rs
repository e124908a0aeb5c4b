//! `twincell run --resume`: a batch killed at any instant continues to the files an
//! uninterrupted run writes; a directory of another batch or with damaged records is refused.
//!
//! The bookkeeping runs on the batch runner's fake cell (tests/common/fake_cell.rs), killed in a
//! child process at random instants; one paper_50 batch is killed and resumed through the real
//! binary, and the refusal's exit code is checked on the command line.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::time::Duration;

mod common;
use common::fake_cell::FakeCell;
use common::{bin, path_str, read, report_without_timing, trials_text_without_timing, twincell};

use twincell::batch::{
    BatchError, BatchOptions, BatchPlan, Perception, ResumeError, Shard, merge_shards, run_batch,
    run_batch_with,
};
use twincell::rng::SimRng;

/// `name` under this crate's temporary folder, absent: a batch creates it.
fn out_dir(name: &str) -> PathBuf {
    common::absent_dir("resume", name)
}

/// The fake cell, its records carrying floats of every size.
fn cell() -> FakeCell {
    FakeCell {
        wide_floats: true,
        ..FakeCell::default()
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

/// Resumes `plan` in `dir` with `cell`, as `twincell run --resume DIR` does.
fn resume_with(cell: &FakeCell, dir: &Path, plan: &BatchPlan) -> Result<(), BatchError> {
    let cancel = AtomicBool::new(false);
    run_batch_with(cell, plan, &resume_options(), dir, &cancel, false).map(|_| ())
}

fn resume(dir: &Path, plan: &BatchPlan) -> Result<(), BatchError> {
    resume_with(&cell(), dir, plan)
}

/// Complete lines in `DIR/trials.jsonl`, 0 when there is none.
fn lines_on_disk(dir: &Path) -> usize {
    fs::read_to_string(dir.join("trials.jsonl")).map_or(0, |t| t.matches('\n').count())
}

/// Waits until `child` has written `lines` records into `dir`, or has exited.
fn wait_for_lines(child: &mut Child, dir: &Path, lines: usize) {
    while lines_on_disk(dir) < lines && child.try_wait().expect("child status").is_none() {
        std::thread::sleep(Duration::from_micros(500));
    }
}

/// SIGKILLs `child` (no handler runs, nothing is flushed or reported); returns whether it had
/// finished on its own first.
fn sigkill(mut child: Child) -> bool {
    child.kill().expect("killed");
    child.wait().expect("reaped").success()
}

#[test]
fn a_torn_last_line_is_dropped_and_the_batch_completes_as_uninterrupted() {
    let whole = out_dir("torn-whole");
    let cancel = AtomicBool::new(false);
    run_batch(&cell(), &plan(12, None), &whole, &cancel, false).expect("batch");
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
        assert_eq!(
            trials_text_without_timing(&dir),
            trials_text_without_timing(&whole)
        );
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
        &cell(),
        &plan(20, shard),
        &whole,
        &AtomicBool::new(false),
        false,
    )
    .expect("batch");
    let dir = out_dir("shard-resumed");
    resume(&dir, &plan(20, shard)).expect("a missing directory starts the batch");
    assert_eq!(
        trials_text_without_timing(&dir),
        trials_text_without_timing(&whole)
    );
    // A complete directory resumes to itself.
    resume(&dir, &plan(20, shard)).expect("nothing left to run");
    assert_eq!(
        trials_text_without_timing(&dir),
        trials_text_without_timing(&whole)
    );
    assert_eq!(report_without_timing(&dir), report_without_timing(&whole));
}

#[test]
fn damaged_or_foreign_records_are_refused_naming_the_line() {
    let whole = out_dir("damaged-whole");
    run_batch(
        &cell(),
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
            &cell(),
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
        &cell(),
        &plan(10, None),
        &whole,
        &AtomicBool::new(false),
        false,
    )
    .expect("batch");
    assert_eq!(
        trials_text_without_timing(&merged),
        trials_text_without_timing(&whole)
    );
}

#[test]
fn a_directory_of_another_batch_is_refused_naming_the_field() {
    let dir = out_dir("mismatch");
    let options = |sha: &str| BatchOptions {
        scenario_sha256: Some(sha.to_owned()),
        resume: false,
    };
    run_batch_with(
        &cell(),
        &plan(6, None),
        &options("a1"),
        &dir,
        &AtomicBool::new(false),
        false,
    )
    .expect("batch");
    let before = read(&dir.join("trials.jsonl"));
    let changed = |edit: fn(&mut BatchPlan)| {
        let mut plan = plan(6, None);
        edit(&mut plan);
        plan
    };
    let cases: [(&str, BatchPlan, &str); 6] = [
        (
            "scenario",
            changed(|p| p.scenario_name = "other".into()),
            "a1",
        ),
        ("scenario_sha256", plan(6, None), "b2"),
        ("seed", changed(|p| p.scenario_seed = 12), "a1"),
        (
            "perception",
            changed(|p| p.perception = Perception::Camera),
            "a1",
        ),
        ("scenario_trials", plan(7, None), "a1"),
        (
            "shard",
            plan(6, Some(Shard::new(0, 2).expect("shard"))),
            "a1",
        ),
    ];
    for (field, plan, sha) in cases {
        let options = BatchOptions {
            resume: true,
            ..options(sha)
        };
        let err = run_batch_with(
            &cell(),
            &plan,
            &options,
            &dir,
            &AtomicBool::new(false),
            false,
        )
        .expect_err(field);
        assert!(err.is_bad_input(), "{field}: {err}");
        assert!(
            matches!(&err, BatchError::Resume(ResumeError::Mismatch { field: f, .. }) if *f == field),
            "{field}: {err}"
        );
        let message = err.to_string();
        assert!(message.contains(&format!("`{field}`")), "{message}");
        assert!(
            message.contains(path_str(&dir.join("batch.json"))),
            "{message}"
        );
        assert_eq!(read(&dir.join("trials.jsonl")), before, "{field}");
        assert!(dir.join("report.json").exists(), "{field}: report kept");
    }
}

/// Set in the child process of the test below: the directory its batch resumes into.
const CHILD_DIR: &str = "TWINCELL_TEST_RESUME_CHILD_DIR";
/// The test below, which its child process runs by this name.
const KILLED_FAKE_TEST: &str =
    "a_fake_batch_sigkilled_at_random_instants_resumes_to_the_uninterrupted_files";
const KILLED_FAKE_TRIALS: u32 = 120;

/// The child's cell: trials of a few ms each, finishing out of order on two jobs.
fn sleepy_cell() -> FakeCell {
    FakeCell {
        sleepy: true,
        ..cell()
    }
}

/// 20 fake batches, each run by a child process (this test binary again) that is SIGKILLed at
/// a random instant, from before it writes its manifest to after its last record, then resumed:
/// all end byte-identical to the uninterrupted run (timing aside), report.json included.
#[test]
fn a_fake_batch_sigkilled_at_random_instants_resumes_to_the_uninterrupted_files() {
    let plan = plan(KILLED_FAKE_TRIALS, None);
    if let Some(dir) = std::env::var_os(CHILD_DIR) {
        // The child: what `twincell run --resume DIR` does, until it is killed.
        resume_with(&sleepy_cell(), Path::new(&dir), &plan).expect("child batch");
        return;
    }
    let whole = out_dir("fake-kill-whole");
    run_batch(
        &sleepy_cell(),
        &plan,
        &whole,
        &AtomicBool::new(false),
        false,
    )
    .expect("batch");
    let expected_trials = trials_text_without_timing(&whole);
    let expected_report = report_without_timing(&whole);

    let mut rng = SimRng::new(20_261_203);
    let mut on_disk = Vec::new();
    for run in 0..20 {
        let dir = out_dir(&format!("fake-kill-{run}"));
        // Once 0 to all records are on disk, up to about two trials' time later.
        let after_lines = rng.below(u64::from(KILLED_FAKE_TRIALS) + 1) as usize;
        let delay = Duration::from_micros(rng.below(6_000));
        let mut child = Command::new(std::env::current_exe().expect("test binary"))
            .args(["--exact", KILLED_FAKE_TEST, "--nocapture"])
            .env(CHILD_DIR, &dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawns");
        wait_for_lines(&mut child, &dir, after_lines);
        std::thread::sleep(delay);
        let finished = sigkill(child);
        let lines = lines_on_disk(&dir);
        on_disk.push((lines, finished));

        resume_with(&sleepy_cell(), &dir, &plan).expect("resumes");
        assert_eq!(
            trials_text_without_timing(&dir),
            expected_trials,
            "run {run} killed with {lines} trials on disk"
        );
        assert_eq!(report_without_timing(&dir), expected_report, "run {run}");
    }
    eprintln!("(trials on disk, finished first): {on_disk:?}");
    // The kills must have landed inside batches, not only before or after them.
    let mid_batch = on_disk
        .iter()
        .filter(|&&(lines, finished)| {
            (1..KILLED_FAKE_TRIALS as usize).contains(&lines) && !finished
        })
        .count();
    assert!(
        mid_batch >= 10,
        "only {mid_batch} kills mid-batch: {on_disk:?}"
    );
}

#[test]
fn resume_refuses_another_batch_with_exit_2_naming_the_field() {
    let scenario = common::scenario_path("smoke.toml");
    let scenario = path_str(&scenario);
    let dir = out_dir("cli-mismatch");
    let base = [
        "run",
        scenario,
        "--perception",
        "oracle",
        "--trials",
        "1",
        "--jobs",
        "1",
    ];
    let (code, _, stderr) = twincell(&[&base[..], &["--out", path_str(&dir)]].concat());
    assert_eq!(code, 0, "{stderr}");
    let before = read(&dir.join("trials.jsonl"));

    let edited = common::out_dir("resume", "cli-mismatch-scenario").join("smoke.toml");
    fs::write(
        &edited,
        common::portable_text("smoke.toml") + "\n# edited\n",
    )
    .expect("write");
    let edited = path_str(&edited);
    // Each field as the command line sets it: the scenario file's bytes, its trials by
    // default, and the flags.
    let cases: [(&str, Vec<&str>); 6] = [
        ("seed", vec![scenario, "--seed", "8", "--trials", "1"]),
        (
            "perception",
            vec![scenario, "--perception", "camera", "--trials", "1"],
        ),
        ("scenario_trials", vec![scenario, "--trials", "3"]),
        ("shard", vec![scenario, "--trials", "1", "--shard", "0/2"]),
        ("scenario_sha256", vec![edited, "--trials", "1"]),
        ("scenario_trials", vec![scenario]),
    ];
    for (field, args) in cases {
        let mut args = [&["run"][..], &args[..]].concat();
        if !args.contains(&"--perception") {
            args.extend(["--perception", "oracle"]);
        }
        args.extend(["--resume", path_str(&dir)]);
        let (code, _, stderr) = twincell(&args);
        assert_eq!(code, 2, "{field}: {stderr}");
        assert!(stderr.contains(&format!("`{field}`")), "{field}: {stderr}");
        assert!(
            stderr.contains(path_str(&dir.join("batch.json"))),
            "{stderr}"
        );
        assert_eq!(read(&dir.join("trials.jsonl")), before, "{field}");
    }
    // --out and --resume name the directory twice.
    let (code, _, stderr) = twincell(&[&base[..], &["--out", "x", "--resume", "y"]].concat());
    assert_eq!(code, 2, "{stderr}");
}

/// paper_50 (oracle, 50 trials) through the real binary, SIGKILLed at a random instant
/// mid-batch and resumed, ends byte-identical to the uninterrupted run (timing aside),
/// report.json included. The uninterrupted run is the one tests/motion_limits.rs checks too,
/// run once for both.
#[test]
fn paper_50_sigkilled_mid_batch_then_resumed_gives_the_uninterrupted_files() {
    let scenario = common::scenario_path("paper_50.toml");
    let args = |dir: &Path, flag: &str| {
        [
            "run",
            path_str(&scenario),
            "--perception",
            "oracle",
            "--jobs",
            "2",
            flag,
            path_str(dir),
        ]
        .map(str::to_owned)
    };
    let whole = common::shared_batch::paper_50_oracle();
    let full = Duration::from_secs_f64(
        common::report(&whole)["timing"]["batch_wall_s"]
            .as_f64()
            .expect("the batch's wall time"),
    );
    let expected_trials = trials_text_without_timing(&whole);
    assert_eq!(expected_trials.lines().count(), 50);

    // After 1 to 45 records, plus up to a record's mean time: inside the batch, at a place
    // within a trial drawn from a fixed seed.
    let mut rng = SimRng::new(20_261_201);
    let after_lines = 1 + rng.below(45) as usize;
    let delay = full.mul_f64(rng.uniform() / 50.0);
    let dir = out_dir("kill");
    let mut child = Command::new(bin())
        .args(args(&dir, "--resume"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawns");
    wait_for_lines(&mut child, &dir, after_lines);
    std::thread::sleep(delay);
    let finished = sigkill(child);
    let lines = lines_on_disk(&dir);
    eprintln!(
        "uninterrupted: {full:?}; killed {delay:?} after record {after_lines}: {lines} on disk"
    );
    assert!(
        !finished && (1..50).contains(&lines),
        "the kill missed the batch: {lines} records, finished {finished}"
    );

    let (code, _, stderr) = twincell(&args(&dir, "--resume").each_ref().map(String::as_str));
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(trials_text_without_timing(&dir), expected_trials);
    assert_eq!(report_without_timing(&dir), report_without_timing(&whole));
}
