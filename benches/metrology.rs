//! Bore metrology timings per frame, one thread, stage by stage (`cargo bench --bench metrology`).
//!
//! Also writes the frames it times (and a set of frames with truth sidecars for accuracy
//! comparisons) under `target/metrology-frames/`, then, in the same run, has
//! `benches/opencv_metrology.py` time OpenCV's equivalent stages on exactly those images and
//! prints the ratio of twincell's whole pipeline to OpenCV's median + adaptive threshold + Canny +
//! findContours, both timed the same way: the median of 200 per-call times, and their minimum (the
//! call no other process interrupted, steadier on a loaded machine), each summed over the frames.
//!
//! The timed frames (`timed_NN.png`) are [`TIMED_FRAMES`] scenes drawn over the whole space of
//! [`twincell::perception::scene_space`] with at least three tubes each: walls thin and thick,
//! dark and grey belts, noise, stains, dirt, bottles.
//!
//! The script runs under the first Python of: `$TWINCELL_OPENCV_PYTHON`, the virtual environment
//! `~/.cache/twincell/venv` (`python3 -m venv ~/.cache/twincell/venv &&
//! ~/.cache/twincell/venv/bin/pip install opencv-python-headless numpy`), `python3`. Without
//! OpenCV the comparison is skipped with a note.

use std::hint::black_box;
use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group};
use image::GrayImage;
use twincell::perception::BoreDetector;
use twincell::perception::contours::{find_contours, find_contours_imageproc};
use twincell::perception::filters::median_3x3;
use twincell::perception::scene_space::space_scene;
use twincell::perception::synthetic::{Difficulty, random_scene};
use twincell::perception::threshold::adaptive_mean_threshold;

/// Frames written for the accuracy comparison, per size.
const ACCURACY_FRAMES: u64 = 20;
/// Frames timed per size.
const TIMED_FRAMES: usize = 8;

fn frames_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/metrology-frames")
}

/// Writes the timed frames and the accuracy set for one size; returns the timed frames.
fn write_frames(width: u32, height: u32) -> Vec<GrayImage> {
    let dir = frames_dir().join(format!("{width}x{height}"));
    let _ = std::fs::create_dir_all(&dir);
    for seed in 0..ACCURACY_FRAMES {
        let scene = random_scene(1000 + seed, width, height, Difficulty::Moderate);
        let path = dir.join(format!("scene_{seed:02}.png"));
        let _ = scene.render().save(&path);
        let truth = serde_json::json!({ "circles": scene.truth() });
        let _ = std::fs::write(format!("{}.truth.json", path.display()), truth.to_string());
    }
    let mut frames = Vec::new();
    let mut seed = 0;
    while frames.len() < TIMED_FRAMES {
        let drawn = space_scene(5000 + seed, width, height);
        seed += 1;
        if drawn.scene.tubes.len() < 3 {
            continue;
        }
        let image = drawn.scene.render();
        let path = dir.join(format!("timed_{:02}.png", frames.len()));
        let _ = image.save(&path);
        let truth = serde_json::json!({ "circles": drawn.scene.truth() });
        let _ = std::fs::write(format!("{}.truth.json", path.display()), truth.to_string());
        frames.push(image);
    }
    frames
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
        let frames = write_frames(width, height);
        let image = frames[0].clone();
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
        group.bench_function("pipeline_all_timed_frames", |b| {
            b.iter(|| {
                for frame in &frames {
                    black_box(detector.detect(black_box(frame)).ok());
                }
            })
        });
        group.bench_function("canny_imageproc", |b| {
            b.iter(|| imageproc::edges::canny(black_box(&filtered), 50.0, 150.0))
        });
        group.finish();
    }
}

/// Median and minimum of `repeats` per-call times of `f`, ms: the statistics the OpenCV script
/// uses. On a loaded machine the median still counts calls that other processes interrupted; the
/// minimum is the call that ran alone.
fn median_and_min_ms(repeats: usize, mut f: impl FnMut()) -> (f64, f64) {
    let mut times: Vec<f64> = (0..repeats)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    (times[repeats / 2], times[0])
}

/// The Python that runs the OpenCV script (see the module documentation).
fn python() -> PathBuf {
    if let Some(path) = std::env::var_os("TWINCELL_OPENCV_PYTHON") {
        return PathBuf::from(path);
    }
    let venv = std::env::var_os("HOME")
        .map(|home| PathBuf::from(home).join(".cache/twincell/venv/bin/python"));
    venv.filter(|p| p.exists())
        .unwrap_or_else(|| PathBuf::from("python3"))
}

/// Times OpenCV on the frames just written and prints the whole-pipeline ratio per size.
fn compare_with_opencv() {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("benches/opencv_metrology.py");
    let python = python();
    let output = match Command::new(&python).arg(&script).arg("--json").output() {
        Ok(o) if o.status.success() => o,
        Ok(o) => {
            eprintln!(
                "OpenCV comparison skipped: {} {} failed: {}",
                python.display(),
                script.display(),
                String::from_utf8_lossy(&o.stderr).trim()
            );
            return;
        }
        Err(e) => {
            eprintln!(
                "OpenCV comparison skipped: cannot run {}: {e}",
                python.display()
            );
            return;
        }
    };
    let report: serde_json::Value = match serde_json::from_slice(&output.stdout) {
        Ok(v) => v,
        Err(e) => {
            eprintln!("OpenCV comparison skipped: unreadable script output: {e}");
            return;
        }
    };
    let detector = BoreDetector::default();
    println!(
        "OpenCV {} (1 thread) vs twincell, median per-call ms",
        report["opencv"]
    );
    for (width, height) in [(640u32, 480u32), (1280, 960)] {
        let size = format!("{width}x{height}");
        let (mut ours, mut ours_min) = (0.0, 0.0);
        for k in 0..TIMED_FRAMES {
            let path = frames_dir().join(&size).join(format!("timed_{k:02}.png"));
            let Ok(image) = image::open(&path).map(|i| i.to_luma8()) else {
                eprintln!("cannot read {}", path.display());
                continue;
            };
            let (median, min) = median_and_min_ms(200, || {
                black_box(detector.detect(black_box(&image)).ok());
            });
            ours += median;
            ours_min += min;
        }
        let timing = &report["sizes"][&size]["timing_ms"];
        for (stage, ms) in timing.as_object().into_iter().flatten() {
            println!(
                "  {size} opencv {stage:<40} {:8.3}",
                ms.as_f64().unwrap_or(f64::NAN)
            );
        }
        let chain = |timing: &serde_json::Value| {
            timing["chain_median_adaptive_canny_contours"]
                .as_f64()
                .unwrap_or(f64::NAN)
        };
        let (theirs, theirs_min) = (
            chain(timing),
            chain(&report["sizes"][&size]["timing_min_ms"]),
        );
        println!(
            "  {size} twincell whole pipeline {ours:8.3} ms over {TIMED_FRAMES} frames; ratio to \
             OpenCV's chain {:.2}",
            ours / theirs
        );
        println!(
            "  {size} minima: OpenCV's chain {theirs_min:8.3} ms, twincell whole pipeline \
             {ours_min:8.3} ms; ratio {:.2}",
            ours_min / theirs_min
        );
        println!(
            "  {size} OpenCV classic pipeline accuracy: {}",
            report["sizes"][&size]["classic_accuracy"]
        );
    }
}

criterion_group!(benches, metrology);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    compare_with_opencv();
}
