//! An installed binary runs anywhere: the release binary installed into a temporary root as
//! `cargo install` lays it out (copied from the tests' build: a real `cargo install` rebuilds
//! the crate with another feature set, minutes on 2 cores), the binary moved out of that root,
//! and a 2-trial camera batch run from a scenario file copied elsewhere while the source tree is
//! hidden under an empty directory (a private mount namespace). The detector's network and the
//! arm's URDF are built into the binary; a scenario's own `[robot] urdf` is read relative to
//! the scenario file, and `--model` still names another network.

mod common;

use std::path::Path;
use std::process::Command;

use serde_json::Value;

/// The source tree.
const SOURCE: &str = env!("CARGO_MANIFEST_DIR");

/// Runs `command` inside a private mount namespace in which `hidden` is an empty directory
/// (the user's own namespace where the machine allows no other). Returns exit code, stdout,
/// stderr.
fn run_with_hidden(hidden: &Path, cwd: &Path, command: &[&str]) -> (i32, String, String) {
    let script = r#"mount -t tmpfs none "$1" && shift && exec "$@""#;
    let mut last = String::new();
    for flags in [&["--mount"][..], &["--mount", "--map-root-user"][..]] {
        let output = Command::new("unshare")
            .args(flags)
            .args(["sh", "-c", script, "sh"])
            .arg(hidden)
            .args(command)
            .current_dir(cwd)
            .output()
            .unwrap_or_else(|e| panic!("unshare (util-linux) runs: {e}"));
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        // unshare or mount refused: try the next way; anything else is the command's own.
        if stderr.contains("unshare failed") || stderr.contains("mount:") {
            last = stderr;
            continue;
        }
        return (
            output.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&output.stdout).into_owned(),
            stderr,
        );
    }
    panic!("cannot hide the source tree in a mount namespace: {last}");
}

#[test]
fn an_installed_binary_runs_a_copied_scenario_with_the_source_tree_out_of_sight() {
    let work = std::env::temp_dir().join(format!("twincell-install-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&work);
    let root = work.join("root");
    std::fs::create_dir_all(root.join("bin")).unwrap_or_else(|e| panic!("{e}"));
    std::fs::copy(env!("CARGO_BIN_EXE_twincell"), root.join("bin/twincell"))
        .unwrap_or_else(|e| panic!("install into {}: {e}", root.display()));

    // The binary alone, away from the root it was installed into.
    let bin_dir = work.join("elsewhere/bin");
    std::fs::create_dir_all(&bin_dir).unwrap_or_else(|e| panic!("{e}"));
    let bin = bin_dir.join("twincell");
    std::fs::rename(root.join("bin/twincell"), &bin).unwrap_or_else(|e| panic!("move: {e}"));
    std::fs::remove_dir_all(&root).unwrap_or_else(|e| panic!("{e}"));

    // A user's cell: the main job's scenario copied out, with its arm's URDF beside it.
    let cell = work.join("cell");
    std::fs::create_dir_all(&cell).unwrap_or_else(|e| panic!("{e}"));
    let scenario = cell.join("my_cell.toml");
    std::fs::copy(Path::new(SOURCE).join("scenarios/paper_50.toml"), &scenario)
        .unwrap_or_else(|e| panic!("{e}"));
    std::fs::copy(
        Path::new(SOURCE).join("assets/urdf/aubo_i5.urdf"),
        cell.join("robot.urdf"),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let bin_str = bin.to_str().unwrap_or_else(|| panic!("path"));

    // Camera mode: the shipped detector, built in.
    let (code, stdout, stderr) = run_with_hidden(
        Path::new(SOURCE),
        &cell,
        &[
            bin_str,
            "run",
            "my_cell.toml",
            "--trials",
            "2",
            "--jobs",
            "2",
            "--out",
            "out",
            "--json",
        ],
    );
    assert_eq!(code, 0, "camera batch: stdout {stdout}\nstderr {stderr}");
    let report: Value = serde_json::from_str(
        &std::fs::read_to_string(cell.join("out/report.json")).unwrap_or_else(|e| panic!("{e}")),
    )
    .unwrap_or_else(|e| panic!("report.json: {e}"));
    assert_eq!(report["trials"], 2, "{report}");
    assert_eq!(report["perception"], "camera", "{report}");
    let lines = std::fs::read_to_string(cell.join("out/trials.jsonl"))
        .unwrap_or_else(|e| panic!("{e}"))
        .lines()
        .count();
    assert_eq!(lines, 2);

    // The scenario's own URDF, relative to the scenario file.
    let text = std::fs::read_to_string(&scenario).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        text.contains("\n[robot]\n"),
        "paper_50.toml has a [robot] table"
    );
    let with_urdf = text.replacen("\n[robot]\n", "\n[robot]\nurdf = \"robot.urdf\"\n", 1);
    std::fs::write(cell.join("my_arm.toml"), with_urdf).unwrap_or_else(|e| panic!("{e}"));
    let (code, stdout, stderr) = run_with_hidden(
        Path::new(SOURCE),
        &cell,
        &[
            bin_str,
            "run",
            "my_arm.toml",
            "--trials",
            "2",
            "--perception",
            "oracle",
            "--out",
            "out_urdf",
        ],
    );
    assert_eq!(code, 0, "oracle batch with robot.urdf: {stdout}\n{stderr}");
    assert!(cell.join("out_urdf/report.json").is_file());
    // The shipped arm's URDF, read from beside the scenario, is the built-in arm: the records
    // are the first ones of paper_50's oracle batch (kept for the tests, run by the built-in).
    let paper = common::trials_text_without_timing(&common::shared_batch::paper_50_oracle());
    let first_two: String = paper.split_inclusive('\n').take(2).collect();
    assert_eq!(
        common::trials_text_without_timing(&cell.join("out_urdf")),
        first_two
    );

    // `--model` still names another network: a missing one is refused by name.
    let (code, _, stderr) = run_with_hidden(
        Path::new(SOURCE),
        &cell,
        &[
            bin_str,
            "run",
            "my_cell.toml",
            "--trials",
            "1",
            "--model",
            "nowhere/net.onnx",
            "--out",
            "out_model",
        ],
    );
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("nowhere/net"), "{stderr}");
    let _ = std::fs::remove_dir_all(&work);
}
