//! Batches several test files check, run once per build of the binary and kept in the tests'
//! temporary folder: the test binaries are separate processes, so a batch made by one is
//! found on disk by the next instead of being run again.

use std::fs::{self, File};
use std::hash::{DefaultHasher, Hash, Hasher};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use twincell::batch::TrialRecord;

use super::{bin, path_str, read, scenario_path};

/// The file that says a batch directory is complete, holding the key it was made under.
const COMPLETE: &str = "complete";

/// What a kept batch depends on: the binary (its size and modification time) and the
/// scenario files' bytes.
fn key(args: &[&str], files: &[PathBuf]) -> String {
    let mut hasher = DefaultHasher::new();
    args.hash(&mut hasher);
    let binary = fs::metadata(bin()).unwrap_or_else(|e| panic!("{}: {e}", bin().display()));
    binary.len().hash(&mut hasher);
    binary.modified().ok().hash(&mut hasher);
    for file in files {
        read(file).hash(&mut hasher);
    }
    format!("{:016x}", hasher.finish())
}

/// The output directory of `twincell run ARGS --out DIR` under the name `name`: run now when
/// no complete one made by this binary from these scenario files is kept, else the kept one.
/// The directory is shared: read it, never write into it.
fn kept_batch(name: &str, args: &[&str], files: &[PathBuf]) -> PathBuf {
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("shared");
    fs::create_dir_all(&root).unwrap_or_else(|e| panic!("{}: {e}", root.display()));
    // One maker at a time, across the tests of a process and across processes.
    let lock_path = root.join(format!("{name}.lock"));
    let lock = File::create(&lock_path).unwrap_or_else(|e| panic!("{}: {e}", lock_path.display()));
    lock.lock()
        .unwrap_or_else(|e| panic!("lock {}: {e}", lock_path.display()));
    let dir = root.join(name);
    let key = key(args, files);
    if fs::read_to_string(dir.join(COMPLETE)).is_ok_and(|k| k == key) {
        return dir;
    }
    let _ = fs::remove_dir_all(&dir);
    let status = Command::new(bin())
        .args(args)
        .args(["--out", path_str(&dir)])
        .stdout(Stdio::null())
        .status()
        .expect("runs");
    assert!(status.success(), "twincell {args:?}: {status}");
    fs::write(dir.join(COMPLETE), &key).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    dir
}

/// The paper's batch, `run scenarios/paper_50.toml --perception oracle --jobs 2` (50 trials,
/// seed 731): its output directory.
pub fn paper_50_oracle() -> PathBuf {
    let scenario = scenario_path("paper_50.toml");
    let args = [
        "run",
        path_str(&scenario),
        "--perception",
        "oracle",
        "--jobs",
        "2",
    ];
    kept_batch("paper_50-oracle", &args, std::slice::from_ref(&scenario))
}

/// The records in `dir/trials.jsonl`.
pub fn records(dir: &Path) -> Vec<TrialRecord> {
    read(&dir.join("trials.jsonl"))
        .lines()
        .map(|line| serde_json::from_str(line).expect("a trial record"))
        .collect()
}
