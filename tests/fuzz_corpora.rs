//! Replays the committed fuzz corpora (`fuzz/corpus/TARGET/*`, minimised by cargo-fuzz)
//! through the very functions the fuzz targets call, so every input the fuzzer kept -- and
//! every crash it found, once fixed -- stays a regression test in the normal test run.

#[path = "../fuzz/src/entries.rs"]
mod entries;

use std::path::Path;

fn replay(target: &str, entry: fn(&[u8])) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.expect("directory entry").path())
        .filter(|path| path.is_file())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no corpus in {}", dir.display());
    for file in &files {
        let data = std::fs::read(file).expect("corpus file");
        // A panic here names the input that reproduces it.
        eprintln!("{}", file.display());
        entry(&data);
    }
}

#[test]
fn scenario_toml_corpus() {
    replay("scenario_toml", entries::scenario_toml);
}

#[test]
fn measure_image_corpus() {
    replay("measure_image", entries::measure_image);
}

#[test]
fn detect_image_corpus() {
    replay("detect_image", entries::detect_image);
}

#[test]
fn urdf_corpus() {
    replay("urdf", entries::urdf);
}

#[test]
fn batch_files_corpus() {
    replay("batch_files", entries::batch_files);
}
