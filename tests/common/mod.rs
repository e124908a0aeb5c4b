//! Helpers shared by the integration tests. Each test crate uses some of them.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use twincell::scenario::Scenario;

/// Runs the `twincell` binary; returns its exit code, stdout and stderr.
pub fn twincell(args: &[&str]) -> (i32, String, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_twincell"))
        .args(args)
        .output()
        .expect("binary runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// The repository's root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A shipped scenario file, by its path under `scenarios/`.
pub fn scenario_path(name: &str) -> PathBuf {
    root().join("scenarios").join(name)
}

/// A shipped scenario, loaded.
pub fn scenario(name: &str) -> Scenario {
    let path = scenario_path(name);
    Scenario::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The paper's scenario, `scenarios/paper_50.toml`.
pub fn paper_50() -> Scenario {
    scenario("paper_50.toml")
}

/// An empty directory `group/name` under the tests' temporary folder.
pub fn out_dir(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    dir
}

/// A file's text.
pub fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `DIR/report.json`.
pub fn report(dir: &Path) -> Value {
    serde_json::from_str(&read(&dir.join("report.json"))).expect("report JSON")
}

/// `DIR/trials.jsonl` with every `timing` field removed, one line per trial.
pub fn without_timing(dir: &Path) -> Vec<String> {
    read(&dir.join("trials.jsonl"))
        .lines()
        .map(|line| {
            let mut value: Value = serde_json::from_str(line).expect("JSON line");
            value.as_object_mut().expect("object").remove("timing");
            value.to_string()
        })
        .collect()
}

/// A shipped scenario's text, its `extends` made absolute so that a copy written anywhere
/// loads the same scenario.
pub fn portable_text(name: &str) -> String {
    let path = scenario_path(name);
    let folder = path.parent().expect("a folder").to_path_buf();
    read(&path)
        .lines()
        .map(|line| match line.strip_prefix("extends = ") {
            Some(base) => {
                let base = folder.join(base.trim_matches('"'));
                let base = base.canonicalize().unwrap_or(base);
                format!("extends = {:?}", base.display().to_string())
            }
            None => line.to_owned(),
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}
