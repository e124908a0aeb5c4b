//! The functions the fuzz targets feed, shared with the corpus replay test
//! (`tests/fuzz_corpora.rs` includes this file), so CI runs every corpus input through exactly
//! what the fuzzer ran. Each takes arbitrary bytes; returning at all is the pass: an error is
//! an answer, a panic or an abort is a bug.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Mutex, OnceLock};

use image::{DynamicImage, GrayImage};
use nalgebra::Isometry3;
use twincell::batch::{
    BatchOptions, BatchPlan, FailureReason, Perception, TrialRecord, TrialRunner, merge_shards,
    parse_trial_lines, run_batch_with,
};
use twincell::detect::Detector;
use twincell::perception::bore::BoreDetector;
use twincell::scenario::Scenario;
use twincell::sim::{SimArm, World, WorldParams};

/// Largest image the image targets process, pixels: bigger ones are decoded but not measured,
/// so that one input cannot stall the fuzzer for seconds (the CLI takes any size).
pub const MAX_PIXELS: u64 = 1 << 22;

/// A scenario file: parse and validate.
pub fn scenario_toml(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Scenario::from_toml(text, Path::new("fuzz.toml"));
    }
}

/// The image the bytes stand for: an encoded file (any format `image` reads) when the first
/// byte is even, else raw 8-bit pixels after a 2-byte width, so that every size and content
/// reaches the pipelines, not only what survives a decoder.
fn image_of(data: &[u8]) -> Option<DynamicImage> {
    let (&mode, rest) = data.split_first()?;
    let image = if mode % 2 == 0 {
        image::load_from_memory(rest).ok()?
    } else {
        let (head, pixels) = rest.split_at_checked(2)?;
        let width = u32::from(u16::from_le_bytes([head[0], head[1]])).max(1);
        let height = u32::try_from(pixels.len()).ok()? / width;
        let used = usize::try_from(width * height).ok()?;
        DynamicImage::ImageLuma8(GrayImage::from_raw(width, height, pixels[..used].to_vec())?)
    };
    (u64::from(image.width()) * u64::from(image.height()) <= MAX_PIXELS).then_some(image)
}

/// An image into `twincell measure`'s pipeline (bore finding and fits).
pub fn measure_image(data: &[u8]) {
    if let Some(image) = image_of(data) {
        let _ = BoreDetector::default().detect(&image.to_luma8());
    }
}

/// An image into `twincell detect`'s network (the shipped model).
pub fn detect_image(data: &[u8]) {
    static DETECTOR: OnceLock<Option<Mutex<Detector>>> = OnceLock::new();
    let detector = DETECTOR.get_or_init(|| Detector::load_default().ok().map(Mutex::new));
    let (Some(detector), Some(image)) = (detector, image_of(data)) else {
        return;
    };
    if let Ok(mut detector) = detector.lock() {
        let _ = detector.detect(&image.to_rgb8());
    }
}

/// A URDF as the project loads its arm: into a physics world.
pub fn urdf(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let mut world = World::new(WorldParams::default());
        let _ = SimArm::from_urdf_str(
            &mut world,
            text,
            Path::new("fuzz/urdf/fuzz.urdf"),
            Isometry3::identity(),
        );
    }
}

/// The batch the `--resume` input continues: 8 oracle trials of scenario `fuzz`, seed 1.
fn resume_plan() -> BatchPlan {
    BatchPlan {
        scenario_name: "fuzz".into(),
        scenario_seed: 1,
        perception: Perception::Oracle,
        trials: 8,
        jobs: Some(1),
        shard: None,
        min_success: None,
    }
}

/// A runner that fails every trial at once: the batch files are what is under test.
struct NoCell;

impl TrialRunner for NoCell {
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord {
        TrialRecord::failed(index, seed, FailureReason::Timeout, "fuzz")
    }
}

/// A scratch directory of this process for `name`, emptied.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir()
        .join(format!("twincell-fuzz-{}", std::process::id()))
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::create_dir_all(&dir);
    dir
}

/// Batch files: the bytes before the first NUL are a `report.json` (for `merge`) and a
/// `batch.json` (for `--resume`), the rest a `trials.jsonl`. Runs the line reader, `merge` of
/// that shard, and `run --resume` of that directory.
pub fn batch_files(data: &[u8]) {
    let (header, trials) = match data.iter().position(|&b| b == 0) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &[][..]),
    };
    let _ = parse_trial_lines(Path::new("trials.jsonl"), trials);

    let shard = scratch("shard");
    let _ = std::fs::write(shard.join("report.json"), header);
    let _ = std::fs::write(shard.join("trials.jsonl"), trials);
    let _ = merge_shards(&[shard], &scratch("merged"), None);

    let resumed = scratch("resumed");
    let _ = std::fs::write(resumed.join("batch.json"), header);
    let _ = std::fs::write(resumed.join("trials.jsonl"), trials);
    let options = BatchOptions {
        scenario_sha256: None,
        resume: true,
    };
    let cancel = AtomicBool::new(false);
    let _ = run_batch_with(&NoCell, &resume_plan(), &options, &resumed, &cancel, false);
}
