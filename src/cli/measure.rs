//! `twincell measure IMAGE... [--json] [--compare [--truth FILE]]`: bore metrology on images.
//!
//! Output (`--json`): `{"images":[{"file":F,"circles":[{"cx","cy","r","roundness"}],"ms":T}]}`,
//! pixels, x right, y down, pixel centres at integers; `roundness` is `Rmax - Rmin` about the
//! fitted centre; `ms` is the pipeline's time on that image (decoding excluded, one thread).
//! Each circle also carries its one-sigma uncertainties `sigma_c`, `sigma_r`, `sigma_roundness`.
//!
//! An image that cannot be read does not stop the others: its entry is `{"file":F,"error":WHY}`,
//! the reason also goes to stderr naming the file, and the process exits with code 2 after
//! printing every result.
//!
//! `--compare` runs the seed paper's alternatives (mean/median/Gaussian filter x adaptive-mean/
//! Otsu/isodata threshold, all with sub-pixel edges, plus the paper's classic integer-contour and
//! Canny pipelines) on the same images and scores them against ground truth. Truth comes from
//! `--truth FILE` (the measure output schema: `{"images":[{"file":F,"circles":[{"cx","cy","r",
//! "roundness"}]}]}`, matched by path as given or by file name) or, without it, from a sidecar
//! `IMAGE.truth.json` holding `{"circles":[...]}` next to each image. A detection matches a truth
//! circle when their centres are closer than 0.3 r.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use image::GrayImage;
use serde::{Deserialize, Serialize};
use twincell::perception::bore::{BoreDetector, BoreDetectorParams, EdgeMode};
use twincell::perception::filters::FilterMethod;
use twincell::perception::synthetic::TruthCircle;
use twincell::perception::threshold::ThresholdMethod;

use crate::cli::{BadInput, EXIT_BAD_INPUT};

/// Arguments of `twincell measure`.
#[derive(Debug, clap::Args)]
pub struct MeasureArgs {
    /// Images to measure (PNG, grey or colour; colour is converted to luma).
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Print JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Compare the paper's filter x threshold alternatives against ground truth.
    #[arg(long)]
    pub compare: bool,
    /// Ground truth for --compare (default: IMAGE.truth.json beside each image).
    #[arg(long, requires = "compare")]
    pub truth: Option<PathBuf>,
}

/// One circle of the contract.
#[derive(Debug, Serialize)]
struct CircleOut {
    cx: f64,
    cy: f64,
    r: f64,
    roundness: f64,
    sigma_c: f64,
    sigma_r: f64,
    sigma_roundness: f64,
}

/// One image of the contract: circles and time, or an error.
#[derive(Debug, Serialize)]
struct ImageOut {
    file: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    circles: Option<Vec<CircleOut>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    ms: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
}

#[derive(Debug, Serialize)]
struct MeasureOut {
    images: Vec<ImageOut>,
}

/// Runs `twincell measure`.
pub fn run(args: &MeasureArgs) -> anyhow::Result<ExitCode> {
    if args.compare {
        return run_compare(args);
    }
    let detector = BoreDetector::default();
    let mut images = Vec::with_capacity(args.images.len());
    let mut any_bad = false;
    for path in &args.images {
        let file = path.display().to_string();
        let entry = match load_gray(path) {
            Ok(image) => match time_detect(&detector, &image) {
                Ok((bores, ms)) => ImageOut {
                    file,
                    circles: Some(
                        bores
                            .iter()
                            .map(|b| CircleOut {
                                cx: b.centre_px[0],
                                cy: b.centre_px[1],
                                r: b.radius_px,
                                roundness: b.roundness_px,
                                sigma_c: b.centre_sigma_px,
                                sigma_r: b.radius_sigma_px,
                                sigma_roundness: b.roundness_sigma_px,
                            })
                            .collect(),
                    ),
                    ms: Some(ms),
                    error: None,
                },
                Err(reason) => bad_entry(file, reason, &mut any_bad),
            },
            Err(reason) => bad_entry(file, reason, &mut any_bad),
        };
        images.push(entry);
    }
    let out = MeasureOut { images };
    let mut stdout = std::io::stdout().lock();
    if args.json {
        serde_json::to_writer(&mut stdout, &out)?;
        writeln!(stdout)?;
    } else {
        for image in &out.images {
            match (&image.circles, image.ms) {
                (Some(circles), Some(ms)) => {
                    writeln!(
                        stdout,
                        "{}: {} bore(s), {ms:.2} ms",
                        image.file,
                        circles.len()
                    )?;
                    for c in circles {
                        writeln!(
                            stdout,
                            "  centre ({:.3}, {:.3}) +-{:.3} px  r {:.3} +-{:.3} px  \
                             roundness {:.3} +-{:.3} px",
                            c.cx, c.cy, c.sigma_c, c.r, c.sigma_r, c.roundness, c.sigma_roundness
                        )?;
                    }
                }
                _ => writeln!(
                    stdout,
                    "{}: error: {}",
                    image.file,
                    image.error.as_deref().unwrap_or("unknown")
                )?,
            }
        }
    }
    Ok(if any_bad {
        ExitCode::from(EXIT_BAD_INPUT)
    } else {
        ExitCode::SUCCESS
    })
}

/// Records a bad image: message on stderr (once), an `error` entry in the output.
fn bad_entry(file: String, reason: String, any_bad: &mut bool) -> ImageOut {
    eprintln!("error: {file}: {reason}");
    *any_bad = true;
    ImageOut {
        file,
        circles: None,
        ms: None,
        error: Some(reason),
    }
}

fn load_gray(path: &Path) -> Result<GrayImage, String> {
    image::open(path)
        .map(|i| i.to_luma8())
        .map_err(|e| format!("cannot read image: {e}"))
}

fn time_detect(
    detector: &BoreDetector,
    image: &GrayImage,
) -> Result<(Vec<twincell::perception::Bore>, f64), String> {
    let start = Instant::now();
    let bores = detector.detect(image).map_err(|e| e.to_string())?;
    Ok((bores, start.elapsed().as_secs_f64() * 1e3))
}

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

fn run_compare(args: &MeasureArgs) -> anyhow::Result<ExitCode> {
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
            let (bores, ms) = time_detect(&detector, image).map_err(BadInput)?;
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
