//! Bore metrology timings per frame, one thread, stage by stage (`cargo bench --bench metrology`).
//!
//! Also writes the frames it times (and a set of frames with truth sidecars for accuracy
//! comparisons) under `target/metrology-frames/`, so `benches/opencv_metrology.py` times OpenCV on
//! exactly the same images.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use image::GrayImage;
use twincell::perception::BoreDetector;
use twincell::perception::contours::{find_contours, find_contours_imageproc};
use twincell::perception::filters::median_3x3;
use twincell::perception::synthetic::{Difficulty, random_scene};
use twincell::perception::threshold::adaptive_mean_threshold;

/// Frames written for the accuracy comparison, per size.
const ACCURACY_FRAMES: u64 = 20;
/// Seed of the timed frame: a heavy scene (noise, stains, bottles) with several tubes.
const TIMED_SEED: u64 = 42;

fn frames_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/metrology-frames")
}

/// Writes the timed frame and the accuracy set for one size; returns the timed frame.
fn write_frames(width: u32, height: u32) -> GrayImage {
    let dir = frames_dir().join(format!("{width}x{height}"));
    let _ = std::fs::create_dir_all(&dir);
    for seed in 0..ACCURACY_FRAMES {
        let scene = random_scene(1000 + seed, width, height, Difficulty::Moderate);
        let path = dir.join(format!("scene_{seed:02}.png"));
        let _ = scene.render().save(&path);
        let truth = serde_json::json!({ "circles": scene.truth() });
        let _ = std::fs::write(format!("{}.truth.json", path.display()), truth.to_string());
    }
    let timed = random_scene(TIMED_SEED, width, height, Difficulty::Heavy);
    let image = timed.render();
    let _ = image.save(dir.join("timed.png"));
    let truth = serde_json::json!({ "circles": timed.truth() });
    let _ = std::fs::write(dir.join("timed.png.truth.json"), truth.to_string());
    image
}

fn metrology(c: &mut Criterion) {
    let detector = BoreDetector::default();
    let params = detector.params;
    let twincell::perception::threshold::ThresholdMethod::AdaptiveMean {
        block_radius_px,
        delta,
    } = params.threshold
    else {
        return;
    };
    for (width, height) in [(640u32, 480u32), (1280, 960)] {
        let image = write_frames(width, height);
        let filtered = median_3x3(&image);
        let binary = adaptive_mean_threshold(&filtered, block_radius_px, delta);
        let contours = find_contours(&binary);
        let mut group = c.benchmark_group(format!("metrology_{width}x{height}"));
        group
            .sample_size(30)
            .warm_up_time(Duration::from_millis(500))
            .measurement_time(Duration::from_secs(2));
        group.bench_function("median3", |b| b.iter(|| median_3x3(black_box(&image))));
        group.bench_function("median3_imageproc", |b| {
            b.iter(|| imageproc::filter::median_filter(black_box(&image), 1, 1))
        });
        group.bench_function("adaptive_mean", |b| {
            b.iter(|| adaptive_mean_threshold(black_box(&filtered), block_radius_px, delta))
        });
        group.bench_function("adaptive_mean_imageproc", |b| {
            b.iter(|| {
                imageproc::contrast::adaptive_threshold(
                    black_box(&filtered),
                    block_radius_px,
                    delta,
                )
            })
        });
        group.bench_function("contours", |b| b.iter(|| find_contours(black_box(&binary))));
        group.bench_function("contours_imageproc", |b| {
            b.iter(|| find_contours_imageproc(black_box(&binary)))
        });
        group.bench_function("measure_candidates", |b| {
            b.iter(|| detector.measure_contours(black_box(&filtered), &binary, &contours))
        });
        group.bench_function("pipeline", |b| {
            b.iter(|| detector.detect(black_box(&image)))
        });
        group.bench_function("canny_imageproc", |b| {
            b.iter(|| imageproc::edges::canny(black_box(&filtered), 50.0, 150.0))
        });
        group.finish();
    }
}

criterion_group!(benches, metrology);
criterion_main!(benches);
