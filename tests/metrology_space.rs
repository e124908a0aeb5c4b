//! `twincell measure` as a general roundness instrument: the bore detector on scenes drawn over
//! the whole space of issue 14 ([`twincell::perception::scene_space`]): walls of 1.15 to 3 times
//! the bore, bores from 12 px to a third of the image height, one to six tubes touching or cut by
//! the border, dark and mid-grey belts, no noise to heavy noise, stains, dirt and bottles.
//!
//! Asserts, over the whole bores: recall 1.0, precision 1.0, mean centre error <= 0.1 px, radius
//! MAE <= 0.1 px, roundness MAE <= 0.3 px; and that no bore cut by the border is reported as a
//! whole one. Prints the figures per wall-ratio band and per bore size:
//! `cargo test --release --locked --test metrology_space -- --nocapture`.

use twincell::perception::BoreDetector;
use twincell::perception::scene_space::{SpaceBore, space_scene};

/// Scenes drawn; each has one to six tubes.
const SCENES: u64 = 220;
/// Frame size.
const SIZE: (u32, u32) = (640, 480);

/// Errors of one group of bores.
#[derive(Debug, Default, Clone)]
struct Tally {
    truths: usize,
    found: usize,
    centre_err_px: Vec<f64>,
    radius_err_px: Vec<f64>,
    roundness_err_px: Vec<f64>,
}

impl Tally {
    fn add(&mut self, found: Option<[f64; 3]>) {
        self.truths += 1;
        if let Some([c, r, q]) = found {
            self.found += 1;
            self.centre_err_px.push(c);
            self.radius_err_px.push(r);
            self.roundness_err_px.push(q);
        }
    }

    fn row(&self, name: &str) -> String {
        format!(
            "{name:<16} {:>5} {:>5} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>8.3}",
            self.truths,
            self.found,
            mean(&self.centre_err_px),
            mean(&self.radius_err_px),
            max(&self.radius_err_px),
            mean(&self.roundness_err_px),
            max(&self.roundness_err_px),
        )
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

/// Whether a measured or skipped centre belongs to a true bore.
fn near(centre: [f64; 2], truth: &SpaceBore) -> bool {
    (centre[0] - truth.truth.cx).hypot(centre[1] - truth.truth.cy) < 0.3 * truth.truth.r
}

const RATIO_BANDS: [(f64, f64); 4] = [(1.15, 1.5), (1.5, 1.8), (1.8, 2.2), (2.2, 3.0 + 1e-9)];
const SIZE_BANDS: [(f64, f64); 4] = [(12.0, 20.0), (20.0, 40.0), (40.0, 80.0), (80.0, 170.0)];

#[test]
fn whole_bores_over_the_whole_space_are_found_and_measured() {
    let detector = BoreDetector::default();
    let mut all = Tally::default();
    let mut by_ratio = vec![Tally::default(); RATIO_BANDS.len()];
    let mut by_size = vec![Tally::default(); SIZE_BANDS.len()];
    let (mut false_positives, mut cut_reported_whole) = (0usize, 0usize);
    let (mut cut_truths, mut cut_skipped_with_reason) = (0usize, 0usize);
    let mut failures = Vec::new();
    for seed in 0..SCENES {
        let drawn = space_scene(seed, SIZE.0, SIZE.1);
        let image = drawn.scene.render();
        let report = detector
            .detect_report(&image)
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        for truth in &drawn.bores {
            if !truth.whole {
                cut_truths += 1;
                cut_reported_whole += report
                    .bores
                    .iter()
                    .filter(|b| near(b.centre_px, truth))
                    .count();
                cut_skipped_with_reason += usize::from(
                    report
                        .skipped
                        .iter()
                        .any(|s| (s.radius_px - truth.truth.r).abs() < 0.2 * truth.truth.r),
                );
                continue;
            }
            let found = report.bores.iter().find(|b| near(b.centre_px, truth));
            let errors = found.map(|b| {
                let t = &truth.truth;
                [
                    (b.centre_px[0] - t.cx).hypot(b.centre_px[1] - t.cy),
                    (b.radius_px - t.r).abs(),
                    (b.roundness_px - t.roundness).abs(),
                ]
            });
            if errors.is_none_or(|[c, r, q]| c > 0.3 || r > 0.3 || q > 0.8) {
                failures.push(format!(
                    "seed {seed}: r {:.1} ratio {:.2} at ({:.1}, {:.1}) roundness {:.2}: {}",
                    truth.truth.r,
                    truth.wall_ratio,
                    truth.truth.cx,
                    truth.truth.cy,
                    truth.truth.roundness,
                    match (found, errors) {
                        (Some(b), Some([c, r, q])) => format!(
                            "centre err {c:.3} radius err {r:.3} roundness {:.3} (err {q:.3})",
                            b.roundness_px
                        ),
                        _ => "missed".to_string(),
                    }
                ));
            }
            all.add(errors);
            let band = |bands: &[(f64, f64)], v: f64| {
                bands
                    .iter()
                    .position(|&(lo, hi)| (lo..hi).contains(&v))
                    .unwrap_or(bands.len() - 1)
            };
            by_ratio[band(&RATIO_BANDS, truth.wall_ratio)].add(errors);
            by_size[band(&SIZE_BANDS, truth.truth.r)].add(errors);
        }
        for b in &report.bores {
            if !drawn.bores.iter().any(|t| near(b.centre_px, t)) {
                false_positives += 1;
                failures.push(format!(
                    "seed {seed}: false positive at ({:.1}, {:.1}) r {:.1}",
                    b.centre_px[0], b.centre_px[1], b.radius_px
                ));
            }
        }
    }
    for f in &failures {
        eprintln!("{f}");
    }
    eprintln!(
        "{SCENES} scenes at {}x{}: {} whole bores, {cut_truths} cut by the border",
        SIZE.0, SIZE.1, all.truths
    );
    eprintln!(
        "{:<16} {:>5} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8}",
        "group", "bores", "found", "centre", "r MAE", "r max", "rnd MAE", "rnd max"
    );
    for (tally, (lo, hi)) in by_ratio.iter().zip(RATIO_BANDS) {
        eprintln!(
            "{}",
            tally.row(&format!("ratio {lo:.2}-{:.2}", hi.min(3.0)))
        );
    }
    for (tally, (lo, hi)) in by_size.iter().zip(SIZE_BANDS) {
        eprintln!("{}", tally.row(&format!("r {lo:.0}-{hi:.0} px")));
    }
    eprintln!("{}", all.row("all"));
    eprintln!(
        "false positives {false_positives}; cut bores reported whole {cut_reported_whole}, \
         skipped with a reason {cut_skipped_with_reason} of {cut_truths}"
    );
    assert!(all.truths >= 500, "only {} whole bores drawn", all.truths);
    assert!(cut_truths >= 20, "only {cut_truths} cut bores drawn");
    assert_eq!(all.found, all.truths, "recall must be 1.0");
    assert_eq!(false_positives, 0, "precision must be 1.0");
    assert_eq!(cut_reported_whole, 0, "a cut bore was fitted as whole");
    assert!(mean(&all.centre_err_px) <= 0.1);
    assert!(mean(&all.radius_err_px) <= 0.1);
    assert!(mean(&all.roundness_err_px) <= 0.3);
}
