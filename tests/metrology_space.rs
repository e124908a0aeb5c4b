//! `twincell measure` as a general roundness instrument: the bore detector on scenes drawn over
//! the whole space of issue 14 ([`twincell::perception::scene_space`]): walls of 1.15 to 3 times
//! the bore, bores from 12 px to a third of the image height, one to six tubes touching or cut by
//! the border, dark and mid-grey belts, no noise to heavy noise, stains, dirt and bottles; and on
//! the same space under heavy noise of four kinds, one at a time and all at once
//! ([`twincell::perception::scene_heavy`]: Gaussian σ up to 16, salt and pepper up to 3 %, light
//! gradients up to 0.5, oil over up to a third of a rim), each an image set of its own seeds.
//!
//! Asserts, over the whole bores: recall 1.0, precision 1.0, mean centre error, radius MAE and
//! roundness MAE within bounds; and that no bore cut by the border is reported as a whole one.
//! Prints the figures per wall-ratio band, per bore size and per noise band:
//! `cargo test --release --locked --test metrology_space -- --nocapture`.

use twincell::perception::BoreDetector;
use twincell::perception::scene_heavy::{NoiseBand, heavy_scene};
use twincell::perception::scene_space::{SpaceBore, SpaceScene, space_scene};

/// Scenes drawn for the whole space; each has one to six tubes.
const SCENES: u64 = 220;
/// Scenes drawn per heavy noise band.
const HEAVY_SCENES: u64 = 90;
/// First seed of the heavy bands' image sets (band `i` starts at `(i + 1)` times this): apart
/// from the suite's seeds and the bench's. `TWINCELL_HEAVY_SEED_BASE` draws other sets.
const HEAVY_SEED_BASE: u64 = 100_000;
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
            "{name:<18} {:>5} {:>5} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>8.3}",
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

const HEADER: &str = "group               bores found   centre    r MAE    r max  rnd MAE  rnd max";

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

/// What the detector made of a set of scenes.
#[derive(Default)]
struct Outcome {
    all: Tally,
    by_ratio: Vec<Tally>,
    by_size: Vec<Tally>,
    false_positives: usize,
    cut_truths: usize,
    cut_reported_whole: usize,
    cut_skipped_with_reason: usize,
    failures: Vec<String>,
}

/// The index of the band `v` falls in (the last one past them all).
fn band(bands: &[(f64, f64)], v: f64) -> usize {
    bands
        .iter()
        .position(|&(lo, hi)| (lo..hi).contains(&v))
        .unwrap_or(bands.len() - 1)
}

/// Measures the scenes of `seeds` drawn by `draw`, rendering them on every core.
fn evaluate(seeds: Vec<u64>, draw: impl Fn(u64) -> SpaceScene + Sync) -> Outcome {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let chunk = seeds.len().div_ceil(threads).max(1);
    let parts: Vec<Outcome> = std::thread::scope(|scope| {
        let workers: Vec<_> = seeds
            .chunks(chunk)
            .map(|part| scope.spawn(|| evaluate_serially(part, &draw)))
            .collect();
        workers
            .into_iter()
            .map(|w| w.join().expect("worker"))
            .collect()
    });
    let mut total = Outcome {
        by_ratio: vec![Tally::default(); RATIO_BANDS.len()],
        by_size: vec![Tally::default(); SIZE_BANDS.len()],
        ..Outcome::default()
    };
    let merge = |into: &mut Tally, from: &Tally| {
        into.truths += from.truths;
        into.found += from.found;
        into.centre_err_px.extend(&from.centre_err_px);
        into.radius_err_px.extend(&from.radius_err_px);
        into.roundness_err_px.extend(&from.roundness_err_px);
    };
    for part in parts {
        merge(&mut total.all, &part.all);
        for (into, from) in total.by_ratio.iter_mut().zip(&part.by_ratio) {
            merge(into, from);
        }
        for (into, from) in total.by_size.iter_mut().zip(&part.by_size) {
            merge(into, from);
        }
        total.false_positives += part.false_positives;
        total.cut_truths += part.cut_truths;
        total.cut_reported_whole += part.cut_reported_whole;
        total.cut_skipped_with_reason += part.cut_skipped_with_reason;
        total.failures.extend(part.failures);
    }
    total
}

fn evaluate_serially(seeds: &[u64], draw: &impl Fn(u64) -> SpaceScene) -> Outcome {
    let detector = BoreDetector::default();
    let mut out = Outcome {
        by_ratio: vec![Tally::default(); RATIO_BANDS.len()],
        by_size: vec![Tally::default(); SIZE_BANDS.len()],
        ..Outcome::default()
    };
    for &seed in seeds {
        let drawn = draw(seed);
        let image = drawn.scene.render();
        let report = detector
            .detect_report(&image)
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        for truth in &drawn.bores {
            if !truth.whole {
                out.cut_truths += 1;
                out.cut_reported_whole += report
                    .bores
                    .iter()
                    .filter(|b| near(b.centre_px, truth))
                    .count();
                out.cut_skipped_with_reason += usize::from(
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
                out.failures.push(format!(
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
            out.all.add(errors);
            out.by_ratio[band(&RATIO_BANDS, truth.wall_ratio)].add(errors);
            out.by_size[band(&SIZE_BANDS, truth.truth.r)].add(errors);
        }
        for b in &report.bores {
            if !drawn.bores.iter().any(|t| near(b.centre_px, t)) {
                out.false_positives += 1;
                out.failures.push(format!(
                    "seed {seed}: false positive at ({:.1}, {:.1}) r {:.1}",
                    b.centre_px[0], b.centre_px[1], b.radius_px
                ));
            }
        }
    }
    out
}

impl Outcome {
    fn print_groups(&self) {
        eprintln!("{HEADER}");
        for (tally, (lo, hi)) in self.by_ratio.iter().zip(RATIO_BANDS) {
            eprintln!(
                "{}",
                tally.row(&format!("ratio {lo:.2}-{:.2}", hi.min(3.0)))
            );
        }
        for (tally, (lo, hi)) in self.by_size.iter().zip(SIZE_BANDS) {
            eprintln!("{}", tally.row(&format!("r {lo:.0}-{hi:.0} px")));
        }
    }

    fn print_summary(&self) {
        eprintln!(
            "false positives {}; cut bores reported whole {}, skipped with a reason {} of {}",
            self.false_positives,
            self.cut_reported_whole,
            self.cut_skipped_with_reason,
            self.cut_truths
        );
    }
}

#[test]
fn whole_bores_over_the_whole_space_are_found_and_measured() {
    let out = evaluate((0..SCENES).collect(), |seed| {
        space_scene(seed, SIZE.0, SIZE.1)
    });
    for f in &out.failures {
        eprintln!("{f}");
    }
    eprintln!(
        "{SCENES} scenes at {}x{}: {} whole bores, {} cut by the border",
        SIZE.0, SIZE.1, out.all.truths, out.cut_truths
    );
    out.print_groups();
    eprintln!("{}", out.all.row("all"));
    out.print_summary();
    let all = &out.all;
    assert!(all.truths >= 500, "only {} whole bores drawn", all.truths);
    assert!(
        out.cut_truths >= 20,
        "only {} cut bores drawn",
        out.cut_truths
    );
    assert_eq!(all.found, all.truths, "recall must be 1.0");
    assert_eq!(out.false_positives, 0, "precision must be 1.0");
    assert_eq!(out.cut_reported_whole, 0, "a cut bore was fitted as whole");
    assert!(mean(&all.centre_err_px) <= 0.1);
    assert!(mean(&all.radius_err_px) <= 0.1);
    assert!(mean(&all.roundness_err_px) <= 0.3);
}

#[test]
fn whole_bores_under_heavy_noise_are_found_and_measured() {
    let mut rows = Vec::new();
    let mut failed = Vec::new();
    let base = std::env::var("TWINCELL_HEAVY_SEED_BASE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(HEAVY_SEED_BASE);
    for (i, noise) in NoiseBand::ALL.into_iter().enumerate() {
        let first = base * (i as u64 + 1);
        let out = evaluate((first..first + HEAVY_SCENES).collect(), |seed| {
            heavy_scene(seed, SIZE.0, SIZE.1, noise)
        });
        for f in &out.failures {
            eprintln!("{}: {f}", noise.name());
        }
        eprintln!(
            "{}: {HEAVY_SCENES} scenes at {}x{}, seeds {first}..{}: {} whole bores, {} cut",
            noise.name(),
            SIZE.0,
            SIZE.1,
            first + HEAVY_SCENES,
            out.all.truths,
            out.cut_truths
        );
        out.print_groups();
        out.print_summary();
        rows.push(format!(
            "{} fp {} cut-as-whole {}",
            out.all.row(noise.name()),
            out.false_positives,
            out.cut_reported_whole
        ));
        let all = &out.all;
        let checks = [
            (all.truths >= 150, "at least 150 whole bores drawn"),
            (out.cut_truths >= 10, "at least 10 cut bores drawn"),
            (all.found == all.truths, "recall 1.0"),
            (out.false_positives == 0, "precision 1.0"),
            (out.cut_reported_whole == 0, "no cut bore fitted as whole"),
            (mean(&all.centre_err_px) <= 0.1, "centre error <= 0.1 px"),
            (mean(&all.radius_err_px) <= 0.1, "radius MAE <= 0.1 px"),
            (
                mean(&all.roundness_err_px) <= 0.3,
                "roundness MAE <= 0.3 px",
            ),
        ];
        failed.extend(
            checks
                .iter()
                .filter(|(ok, _)| !ok)
                .map(|(_, what)| format!("{}: {what}", noise.name())),
        );
    }
    eprintln!("{HEADER}   (per noise band)");
    for row in &rows {
        eprintln!("{row}");
    }
    assert!(failed.is_empty(), "{failed:#?}");
}
