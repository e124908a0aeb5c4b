//! `twincell measure --compare`: the seed paper's filter x threshold alternatives and its
//! classic integer pipelines, scored against ground truth (see the parent module).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use serde::{Deserialize, Serialize};
use twincell::perception::bore::{BoreDetector, BoreDetectorParams, EdgeMode};
use twincell::perception::filters::FilterMethod;
use twincell::perception::synthetic::TruthCircle;
use twincell::perception::threshold::ThresholdMethod;

use super::{MeasureArgs, load_gray, time_detect};
use crate::cli::BadInput;

/// Truth file: the measure output schema.
#[derive(Debug, Deserialize)]
struct TruthFile {
    images: Vec<TruthImage>,
}

#[derive(Debug, Deserialize)]
struct TruthImage {
    file: String,
    circles: Vec<TruthCircle>,
}

/// Sidecar truth: `IMAGE.truth.json`.
#[derive(Debug, Deserialize)]
struct TruthSidecar {
    circles: Vec<TruthCircle>,
}

/// Scores of one pipeline variant over all images.
#[derive(Debug, Serialize)]
struct VariantScore {
    filter: &'static str,
    threshold: &'static str,
    edges: &'static str,
    truths: usize,
    found: usize,
    false_positives: usize,
    centre_err_px: f64,
    radius_err_px: f64,
    roundness_err_px: f64,
    roundness_err_max_px: f64,
    ms: f64,
}

/// The paper's alternatives, then its classic integer pipelines.
fn variants() -> Vec<BoreDetectorParams> {
    let base = BoreDetectorParams::default();
    let filters = [
        FilterMethod::Mean { radius_px: 1 },
        FilterMethod::Median { radius_px: 1 },
        FilterMethod::Gaussian { sigma_px: 1.0 },
    ];
    let thresholds = [
        base.threshold,
        ThresholdMethod::Otsu,
        ThresholdMethod::Isodata,
    ];
    let mut out: Vec<BoreDetectorParams> = filters
        .iter()
        .flat_map(|&filter| {
            thresholds.iter().map(move |&threshold| BoreDetectorParams {
                filter,
                threshold,
                ..base
            })
        })
        .collect();
    for edge_mode in [EdgeMode::IntegerContour, EdgeMode::Canny] {
        out.push(BoreDetectorParams { edge_mode, ..base });
    }
    out
}

fn load_truth(args: &MeasureArgs) -> anyhow::Result<Vec<Vec<TruthCircle>>> {
    let by_file: Option<BTreeMap<String, Vec<TruthCircle>>> = match &args.truth {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| BadInput(format!("{}: cannot read truth: {e}", path.display())))?;
            let file: TruthFile = serde_json::from_str(&text)
                .map_err(|e| BadInput(format!("{}: bad truth JSON: {e}", path.display())))?;
            Some(
                file.images
                    .into_iter()
                    .map(|i| (i.file, i.circles))
                    .collect(),
            )
        }
        None => None,
    };
    args.images
        .iter()
        .map(|image| {
            let shown = image.display().to_string();
            if let Some(map) = &by_file {
                let name = image
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                let found = map.get(&shown).or_else(|| {
                    map.iter()
                        .find(|(k, _)| Path::new(k).file_name().is_some_and(|f| *f == *name))
                        .map(|(_, v)| v)
                });
                return found.cloned().ok_or_else(|| {
                    BadInput(format!(
                        "{shown}: key `images[].file`: no truth for this image"
                    ))
                    .into()
                });
            }
            let sidecar = PathBuf::from(format!("{shown}.truth.json"));
            let text = std::fs::read_to_string(&sidecar).map_err(|e| {
                BadInput(format!(
                    "{}: cannot read truth sidecar: {e}",
                    sidecar.display()
                ))
            })?;
            let parsed: TruthSidecar = serde_json::from_str(&text)
                .map_err(|e| BadInput(format!("{}: bad truth JSON: {e}", sidecar.display())))?;
            Ok(parsed.circles)
        })
        .collect()
}

pub(super) fn run_compare(args: &MeasureArgs) -> anyhow::Result<ExitCode> {
    let truths = load_truth(args)?;
    let images = args
        .images
        .iter()
        .map(|p| load_gray(p).map_err(|e| BadInput(format!("{}: {e}", p.display()))))
        .collect::<Result<Vec<_>, _>>()?;
    let mut scores = Vec::new();
    for params in variants() {
        let detector = BoreDetector::new(params);
        let (mut centre, mut radius, mut roundness) = (Vec::new(), Vec::new(), Vec::new());
        let (mut truth_count, mut false_positives, mut total_ms) = (0, 0, 0.0);
        for (image, truth) in images.iter().zip(&truths) {
            let (report, ms) = time_detect(&detector, image).map_err(BadInput)?;
            let bores = report.bores;
            total_ms += ms;
            truth_count += truth.len();
            let matches = |b: &twincell::perception::Bore, t: &TruthCircle| {
                (b.centre_px[0] - t.cx).hypot(b.centre_px[1] - t.cy) < 0.3 * t.r
            };
            for t in truth {
                if let Some(b) = bores.iter().find(|b| matches(b, t)) {
                    centre.push((b.centre_px[0] - t.cx).hypot(b.centre_px[1] - t.cy));
                    radius.push((b.radius_px - t.r).abs());
                    roundness.push((b.roundness_px - t.roundness).abs());
                }
            }
            false_positives += bores
                .iter()
                .filter(|b| !truth.iter().any(|t| matches(b, t)))
                .count();
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        scores.push(VariantScore {
            filter: params.filter.name(),
            threshold: params.threshold.name(),
            edges: params.edge_mode.name(),
            truths: truth_count,
            found: centre.len(),
            false_positives,
            centre_err_px: mean(&centre),
            radius_err_px: mean(&radius),
            roundness_err_px: mean(&roundness),
            roundness_err_max_px: roundness.iter().copied().fold(0.0, f64::max),
            ms: total_ms / images.len().max(1) as f64,
        });
    }
    let mut stdout = std::io::stdout().lock();
    if args.json {
        serde_json::to_writer(&mut stdout, &serde_json::json!({ "variants": scores }))?;
        writeln!(stdout)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(
        stdout,
        "{:<9} {:<14} {:<16} {:>9} {:>4} {:>9} {:>9} {:>10} {:>10} {:>7}",
        "filter",
        "threshold",
        "edges",
        "recall",
        "fp",
        "centre",
        "radius",
        "roundness",
        "rnd max",
        "ms"
    )?;
    for s in &scores {
        writeln!(
            stdout,
            "{:<9} {:<14} {:<16} {:>4}/{:<4} {:>4} {:>9.3} {:>9.3} {:>10.3} {:>10.3} {:>7.2}",
            s.filter,
            s.threshold,
            s.edges,
            s.found,
            s.truths,
            s.false_positives,
            s.centre_err_px,
            s.radius_err_px,
            s.roundness_err_px,
            s.roundness_err_max_px,
            s.ms
        )?;
    }
    writeln!(
        stdout,
        "(mean absolute errors in px over matched bores; ms per image)"
    )
    .context("writing the table")?;
    Ok(ExitCode::SUCCESS)
}
