//! Accuracy of the bore detector on seeded synthetic scenes with known truth.
//!
//! Run with `cargo test --release --test perception_accuracy -- --nocapture` to see the figures.

use twincell::perception::synthetic::{Difficulty, TruthCircle, random_scene};
use twincell::perception::{Bore, BoreDetector};

/// Errors of one difficulty level, over all its scenes.
#[derive(Debug, Default)]
struct Tally {
    truths: usize,
    found: usize,
    false_positives: usize,
    bottle_reports: usize,
    centre_err_px: Vec<f64>,
    radius_err_px: Vec<f64>,
    roundness_err_px: Vec<f64>,
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

fn matches(bore: &Bore, truth: &TruthCircle) -> bool {
    (bore.centre_px[0] - truth.cx).hypot(bore.centre_px[1] - truth.cy) < 0.3 * truth.r
}

fn run(difficulty: Difficulty, seeds: std::ops::Range<u64>, width: u32, height: u32) -> Tally {
    let detector = BoreDetector::default();
    let mut tally = Tally::default();
    for seed in seeds {
        let scene = random_scene(seed, width, height, difficulty);
        let truth = scene.truth();
        let image = scene.render();
        let bores = detector
            .detect(&image)
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        tally.truths += truth.len();
        for t in &truth {
            let Some(b) = bores.iter().find(|b| matches(b, t)) else {
                eprintln!("seed {seed} {difficulty:?}: missed {t:?}");
                continue;
            };
            tally.found += 1;
            tally
                .centre_err_px
                .push((b.centre_px[0] - t.cx).hypot(b.centre_px[1] - t.cy));
            tally.radius_err_px.push((b.radius_px - t.r).abs());
            tally
                .roundness_err_px
                .push((b.roundness_px - t.roundness).abs());
        }
        for b in &bores {
            if !truth.iter().any(|t| matches(b, t)) {
                tally.false_positives += 1;
                let on_bottle = scene.bottles.iter().any(|bottle| {
                    let c = match bottle {
                        twincell::perception::synthetic::Bottle::Standing { centre_px, .. }
                        | twincell::perception::synthetic::Bottle::Lying { centre_px, .. } => {
                            centre_px
                        }
                    };
                    (c[0] - b.centre_px[0]).hypot(c[1] - b.centre_px[1]) < 120.0
                });
                if on_bottle {
                    tally.bottle_reports += 1;
                }
                eprintln!(
                    "seed {seed} {difficulty:?}: false positive at ({:.1}, {:.1}) r {:.1}",
                    b.centre_px[0], b.centre_px[1], b.radius_px
                );
            }
        }
    }
    eprintln!(
        "{difficulty:?} {width}x{height}: {} bores, recall {}/{}, false positives {} (on bottles {}), \
         centre err mean {:.3} max {:.3} px, radius err mean {:.3} max {:.3} px, \
         roundness err mean {:.3} max {:.3} px",
        tally.truths,
        tally.found,
        tally.truths,
        tally.false_positives,
        tally.bottle_reports,
        mean(&tally.centre_err_px),
        max(&tally.centre_err_px),
        mean(&tally.radius_err_px),
        max(&tally.radius_err_px),
        mean(&tally.roundness_err_px),
        max(&tally.roundness_err_px),
    );
    tally
}

fn assert_accuracy(tally: &Tally) {
    assert_eq!(tally.found, tally.truths, "recall must be 100%");
    assert_eq!(
        tally.false_positives, 0,
        "no false positives, bottles included"
    );
    assert!(
        mean(&tally.centre_err_px) <= 0.1,
        "centre error {}",
        mean(&tally.centre_err_px)
    );
    assert!(
        mean(&tally.radius_err_px) <= 0.1,
        "radius error {}",
        mean(&tally.radius_err_px)
    );
    assert!(
        mean(&tally.roundness_err_px) <= 0.3,
        "roundness error {}",
        mean(&tally.roundness_err_px)
    );
}

#[test]
fn clean_scenes() {
    assert_accuracy(&run(Difficulty::Clean, 0..30, 640, 480));
}

#[test]
fn moderate_noise_gradients_stains_and_bottles() {
    assert_accuracy(&run(Difficulty::Moderate, 100..140, 640, 480));
}

#[test]
fn heavy_noise_salt_and_pepper_vignetting_stains_and_bottles() {
    assert_accuracy(&run(Difficulty::Heavy, 200..240, 640, 480));
}

#[test]
fn large_frames() {
    assert_accuracy(&run(Difficulty::Moderate, 300..310, 1280, 960));
}
