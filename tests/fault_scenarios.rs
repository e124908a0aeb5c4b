//! The `[faults]` section: the shipped fault suite loads, one kind per file, each saying only
//! what differs from its base; bad fault keys (a negative rate, a NaN duration, an unknown
//! kind or mode) are refused with the file, the key and the reason, and exit 2 through the CLI.

mod common;

use std::path::{Path, PathBuf};

use twincell::control::FaultPlan;
use twincell::outcome::FaultKind;
use twincell::scenario::{FAULT_KINDS, Override, Scenario};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    path
}

/// A file extending the shipped paper scenario with `faults`, in a fresh folder.
fn extending(group: &str, faults: &str) -> PathBuf {
    let dir = common::out_dir("fault_scenarios", group);
    let base = common::scenario_path("paper_50.toml");
    let text = format!("extends = {:?}\n{faults}", common::path_str(&base));
    write(&dir, "faulty.toml", &text)
}

#[test]
fn the_fault_suite_has_one_scenario_per_kind_each_extending_a_base() {
    let folder = common::scenario_path("faults");
    let mut kinds = Vec::new();
    for kind in FAULT_KINDS {
        let path = folder.join(format!("{kind}.toml"));
        let scenario = Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let text = common::read(&path);
        assert!(
            text.lines().any(|l| l.starts_with("extends = ")),
            "{}",
            path.display()
        );
        assert_eq!(scenario.trials, 50, "{}", path.display());
        // One kind each: drawn over many seeds, the file's plans name its kind and no other.
        let mut named = std::collections::BTreeSet::new();
        for seed in 0..400 {
            named.extend(
                FaultPlan::draw(&scenario, seed)
                    .kinds()
                    .into_iter()
                    .map(FaultKind::as_str),
            );
        }
        assert_eq!(named.into_iter().collect::<Vec<_>>(), [kind], "{kind}");
        kinds.push(kind);
    }
    // Beyond those, a file may set one kind's fault in another base (gripper_stream.toml: a
    // stream): it names its kind in its file name, and draws that kind and no other.
    let mut files = 0;
    for entry in std::fs::read_dir(&folder).expect("scenarios/faults") {
        let path = entry.expect("entry").path();
        files += 1;
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default();
        if kinds.contains(&stem) {
            continue;
        }
        let scenario = Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let kind = kinds
            .iter()
            .find(|k| stem.starts_with(&format!("{k}_")))
            .unwrap_or_else(|| panic!("{}: names no fault kind", path.display()));
        let mut named = std::collections::BTreeSet::new();
        for seed in 0..400 {
            named.extend(FaultPlan::draw(&scenario, seed).kinds());
        }
        let named: Vec<&str> = named.into_iter().map(FaultKind::as_str).collect();
        assert_eq!(named, [*kind], "{}", path.display());
    }
    assert!(files >= kinds.len());
}

#[test]
fn records_name_the_kinds_as_the_scenario_does() {
    assert_eq!(FaultKind::ALL.map(FaultKind::as_str), FAULT_KINDS);
}

#[test]
fn a_scenario_without_faults_is_unchanged_and_draws_no_faults() {
    let paper = common::paper_50();
    assert!(paper.faults.is_empty());
    for seed in 0..100 {
        assert!(FaultPlan::draw(&paper, seed).is_empty());
    }
    // An empty `[faults]` table is the same scenario.
    let empty = Scenario::load(&extending("empty", "[faults]\n")).expect("empty faults");
    assert_eq!(empty, paper);
}

#[test]
fn faults_take_their_defaults_and_overrides() {
    let path = extending("defaults", "[faults.gripper]\nrate = 0.25\n");
    let scenario = Scenario::load(&path).expect("defaults");
    let gripper = scenario.faults.gripper.as_ref().expect("gripper");
    assert_eq!(gripper.rate, 0.25);
    assert!(gripper.delay_range_s[0] <= gripper.delay_range_s[1]);
    let set: Override = "faults.arm.rate=0.5".parse().expect("override");
    let swept = Scenario::load_with(&path, &[set]).expect("a fault added by --set");
    assert_eq!(swept.faults.arm.as_ref().map(|a| a.rate), Some(0.5));
    let bad: Override = "faults.gripper.rate=-0.5".parse().expect("override");
    let error = Scenario::load_with(&path, &[bad]).expect_err("a negative rate by --set");
    assert_eq!(error.key, "faults.gripper.rate");
    assert!(error.reason.contains("--set"), "{error}");
}

/// Bad fault keys, each with the key the error must name and a word of its reason.
const BAD: [(&str, &str, &str); 9] = [
    (
        "[faults.gripper]\nrate = -0.2\n",
        "faults.gripper.rate",
        "must lie in [0, 1], got -0.2",
    ),
    (
        "[faults.camera]\nrate = 0.2\nduration_s = nan\n",
        "faults.camera.duration_s",
        "got NaN",
    ),
    (
        "[faults.arm]\nrate = 0.2\nduration_s = -1.0\n",
        "faults.arm.duration_s",
        "positive",
    ),
    (
        "[faults.laser]\nrate = 0.2\n",
        "faults.laser",
        "unknown fault kind `laser`",
    ),
    (
        "[faults.camera]\nrate = 0.2\nmode = \"flicker\"\n",
        "faults.camera.mode",
        "unknown kind `flicker`",
    ),
    (
        "[faults.belt]\nrate = 0.2\nmode = \"reverse\"\n",
        "faults.belt.mode",
        "unknown kind `reverse`",
    ),
    (
        "[faults.belt]\nrate = 0.2\nspeed_fraction = 1.0\n",
        "faults.belt.speed_fraction",
        "[0, 1)",
    ),
    (
        "[faults.gripper]\nrate = 0.2\ndelay_range_s = [1.0, 0.5]\n",
        "faults.gripper.delay_range_s",
        "least <= most",
    ),
    (
        "[faults.photo_eye]\nmissed_trigger_rate = inf\n",
        "faults.photo_eye.missed_trigger_rate",
        "got inf",
    ),
];

#[test]
fn bad_fault_keys_name_the_file_the_key_and_the_reason() {
    for (i, (faults, key, reason)) in BAD.iter().enumerate() {
        let path = extending(&format!("bad{i}"), faults);
        let error = Scenario::load(&path).expect_err(faults);
        assert_eq!(error.file, path, "{error}");
        assert_eq!(error.key, *key, "{error}");
        assert!(error.reason.contains(reason), "{error}");
        // The same section in a base is blamed on the base.
        let dir = path.parent().expect("folder");
        let child = write(
            dir,
            "child.toml",
            "extends = \"faulty.toml\"\nname = \"child\"\n",
        );
        let error = Scenario::load(&child).expect_err(faults);
        assert_eq!(error.file, path, "{error}");
        assert_eq!(error.key, *key, "{error}");
    }
}

#[test]
fn bad_fault_keys_exit_2_through_the_cli() {
    for (i, (faults, key, reason)) in BAD.iter().take(5).enumerate() {
        let path = extending(&format!("cli{i}"), faults);
        let out = common::absent_dir("fault_scenarios", &format!("cli{i}_out"));
        let (code, _, stderr) = common::twincell(&[
            "run",
            common::path_str(&path),
            "--trials",
            "1",
            "--perception",
            "oracle",
            "--out",
            common::path_str(&out),
        ]);
        assert_eq!(code, 2, "{faults}: {stderr}");
        for needed in [common::path_str(&path), key, reason] {
            assert!(
                stderr.contains(needed),
                "{faults}: no {needed:?} in {stderr}"
            );
        }
        assert!(!out.join("trials.jsonl").exists(), "no trial ran");
    }
}
