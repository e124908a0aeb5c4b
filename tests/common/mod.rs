//! Helpers shared by the integration tests. Each test crate uses some of them.
#![allow(dead_code)]

pub mod fake_cell;
pub mod shared_batch;

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use twincell::render::{Renderer, RendererOptions};
use twincell::scenario::Scenario;

/// The binary under test: cargo's, or `TWINCELL_BIN` when set (a copy taken right after the
/// build, for machines where several checkouts share one target directory and its binary).
pub fn bin() -> PathBuf {
    std::env::var_os("TWINCELL_BIN").map_or_else(
        || PathBuf::from(env!("CARGO_BIN_EXE_twincell")),
        PathBuf::from,
    )
}

/// Runs the binary under test ([`bin`]); returns its exit code, stdout and stderr.
pub fn twincell(args: &[&str]) -> (i32, String, String) {
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

/// `dir/NAME.toml`: the shipped scenario `base` (its path under `scenarios/`) extended by
/// `body` (TOML keys and tables).
pub fn extending(dir: &Path, name: &str, base: &str, body: &str) -> PathBuf {
    let file = dir.join(format!("{name}.toml"));
    let text = format!("extends = {:?}\n{body}", path_str(&scenario_path(base)));
    std::fs::write(&file, text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    file
}

/// Runs `scenario` with oracle perception on 2 jobs into `out`; panics with its output unless
/// it exits 0.
pub fn run_oracle(scenario: &Path, out: &Path) {
    let (code, stdout, stderr) = twincell(&[
        "run",
        path_str(scenario),
        "--perception",
        "oracle",
        "--jobs",
        "2",
        "--out",
        path_str(out),
    ]);
    assert_eq!(code, 0, "{stdout}{stderr}");
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

/// The path `group/name` under the tests' temporary folder, removed and not created: for
/// commands that must create their output directory themselves or find none.
pub fn absent_dir(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A path as the `&str` a command line takes.
pub fn path_str(path: &Path) -> &str {
    path.to_str().expect("UTF-8 path")
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

/// `DIR/trials.jsonl` with each line's `"timing":{...}` object cut out and its bytes otherwise
/// untouched, for comparisons byte for byte.
pub fn trials_text_without_timing(dir: &Path) -> String {
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

/// `DIR/report.json` without its wall-clock `timing`.
pub fn report_without_timing(dir: &Path) -> Value {
    let mut report = report(dir);
    report
        .as_object_mut()
        .expect("object")
        .remove("timing")
        .expect("timing");
    report
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

/// A renderer with `scenario`'s camera options (MSAA, supersampling).
pub fn renderer(scenario: &Scenario) -> Renderer {
    match Renderer::new(RendererOptions {
        msaa_samples: scenario.camera.msaa_samples,
        supersample: scenario.camera.supersample,
    }) {
        Ok(r) => r,
        Err(e) => panic!("no renderer: {e}"),
    }
}
