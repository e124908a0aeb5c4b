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

#[test]
fn bottles_are_never_bores_even_when_they_look_like_a_dark_disc_in_a_bright_ring() {
    use twincell::perception::contours::{BorderKind, find_contours};
    use twincell::perception::synthetic::{Bottle, Illumination, Noise};
    let detector = BoreDetector::default();
    let mut bottle_holes = 0;
    for seed in 0..20u64 {
        let mut scene = random_scene(500 + seed, 640, 480, Difficulty::Moderate);
        let f = seed as f64;
        // Dark caps (40-90) inside translucent bodies, and lying capsules with dark caps.
        scene.bottles = vec![
            Bottle::Standing {
                centre_px: [90.0, 90.0],
                body_radius_px: 60.0 + f,
                cap_radius_px: 20.0 + 0.3 * f,
                cap_level: 40.0 + 2.5 * f,
            },
            Bottle::Lying {
                centre_px: [540.0, 380.0],
                length_px: 180.0,
                width_px: 60.0,
                angle_rad: 0.1 * f,
                cap_level: 40.0 + 2.5 * f,
            },
        ];
        scene.tubes.retain(|t| {
            let clear = |c: [f64; 2], r: f64| {
                (t.centre_px[0] - c[0]).hypot(t.centre_px[1] - c[1]) > t.outer_radius_px + r
            };
            clear([90.0, 90.0], 90.0) && clear([540.0, 380.0], 110.0)
        });
        scene.illumination = Illumination {
            gradient_x: 0.3,
            gradient_y: -0.2,
            vignetting: 0.2,
        };
        scene.noise = Noise {
            sigma: 6.0,
            salt_pepper: 0.01,
        };
        let image = scene.render();
        let truth = scene.truth();
        // The bottles do reach the geometric tests: their caps leave hole borders.
        let binary = detector
            .params
            .threshold
            .apply(&detector.params.filter.apply(&image));
        bottle_holes += find_contours(&binary)
            .iter()
            .filter(|c| c.kind == BorderKind::Hole && c.points_px.len() > 40)
            .filter(|c| {
                let [x, y] = c.points_px[0];
                (f64::from(x) - 90.0).hypot(f64::from(y) - 90.0) < 90.0
                    || (f64::from(x) - 540.0).hypot(f64::from(y) - 380.0) < 110.0
            })
            .count();
        let bores = detector
            .detect(&image)
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        for b in &bores {
            assert!(
                truth.iter().any(|t| matches(b, t)),
                "seed {seed}: reported a bore at ({:.1}, {:.1}) r {:.1}",
                b.centre_px[0],
                b.centre_px[1],
                b.radius_px
            );
        }
        assert_eq!(bores.len(), truth.len(), "seed {seed}: every tube found");
    }
    eprintln!("bottle hole borders that reached the geometric tests: {bottle_holes}");
    assert!(bottle_holes > 0);
}

/// Oil stains with soft rims lying across the bore edge (as on the rendered end faces) neither
/// hide the bore nor read as out-of-roundness: the edge is the sharp step, not the stain's ramp,
/// and arcs whose rim is stained are bridged by the robust outline of the rest.
#[test]
fn soft_stains_across_the_bore_edge_add_no_roundness() {
    use twincell::perception::synthetic::{Illumination, Noise, Stain};
    let detector = BoreDetector::default();
    let mut tally = Tally::default();
    let mut bridged = 0usize;
    for seed in 0..40u64 {
        let mut scene = random_scene(700 + seed, 640, 480, Difficulty::Clean);
        let mut rng = twincell::rng::SimRng::new(seed);
        scene.stains = Vec::new();
        for tube in &scene.tubes {
            // One to three overlapping lobes centred near the bore edge, as a rendered stain.
            let angle = rng.range(0.0, std::f64::consts::TAU);
            let r = tube.bore.mean_radius_px() + rng.range(0.0, 6.0);
            let wall = tube.outer_radius_px - tube.bore.mean_radius_px();
            for _ in 0..1 + rng.below(3) {
                let radius = rng.range(4.0, 12.0_f64.min(0.8 * wall).max(5.0));
                let spread = rng.range(-2.0, 2.0);
                scene.stains.push(Stain {
                    centre_px: [
                        tube.centre_px[0] + (r + spread) * angle.cos() + rng.range(-2.0, 2.0),
                        tube.centre_px[1] + (r + spread) * angle.sin() + rng.range(-2.0, 2.0),
                    ],
                    radius_px: radius,
                    harmonics: vec![],
                    transmission: rng.range(0.55, 0.8),
                    soft_px: 0.6 * radius,
                });
            }
        }
        scene.illumination = Illumination {
            gradient_x: 0.1,
            gradient_y: -0.1,
            vignetting: 0.1,
        };
        scene.noise = Noise {
            sigma: 2.0,
            salt_pepper: 0.0,
        };
        let truth = scene.truth();
        let bores = detector
            .detect(&scene.render())
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        tally.truths += truth.len();
        for t in &truth {
            let Some(b) = bores.iter().find(|b| matches(b, t)) else {
                eprintln!("seed {seed}: missed {t:?}");
                continue;
            };
            tally.found += 1;
            bridged += usize::from(!b.bridge_points_px.is_empty());
            tally
                .centre_err_px
                .push((b.centre_px[0] - t.cx).hypot(b.centre_px[1] - t.cy));
            tally.radius_err_px.push((b.radius_px - t.r).abs());
            tally
                .roundness_err_px
                .push((b.roundness_px - t.roundness).abs());
        }
        tally.false_positives += bores
            .iter()
            .filter(|b| !truth.iter().any(|t| matches(b, t)))
            .count();
    }
    eprintln!(
        "soft stains: recall {}/{}, {bridged} bores bridged, centre err mean {:.3} px, radius err \
         mean {:.3} px, roundness err mean {:.3} max {:.3} px",
        tally.found,
        tally.truths,
        mean(&tally.centre_err_px),
        mean(&tally.radius_err_px),
        mean(&tally.roundness_err_px),
        max(&tally.roundness_err_px)
    );
    assert_accuracy(&tally);
    assert!(bridged > 0, "no stain reached an edge");
    assert!(
        // The worst bore moved from 0.55 to 0.62 px when the threshold gained its Otsu floor
        // (issue 14: thick rims); the mean did not move.
        mean(&tally.roundness_err_px) <= 0.1 && max(&tally.roundness_err_px) <= 0.65,
        "roundness error mean {} max {}",
        mean(&tally.roundness_err_px),
        max(&tally.roundness_err_px)
    );
}
