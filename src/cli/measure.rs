//! `twincell measure IMAGE... [--json] [--compare [--truth FILE]]`: bore metrology on images.
//!
//! Output (`--json`): `{"images":[{"file":F,"circles":[{"cx","cy","r","roundness"}],"ms":T}]}`,
//! pixels, x right, y down, pixel centres at integers; `roundness` is `Rmax - Rmin` about the
//! fitted centre; `ms` is the pipeline's time on that image (decoding excluded, one thread).
//! Each circle also carries its one-sigma uncertainties `sigma_c`, `sigma_r`, `sigma_roundness`.
//!
//! Bores cut by the image border are never fitted as whole: each image lists them under
//! `skipped` (`cx`, `cy`, `r` of the visible arc's circle, `visible_share`, `reason`).
//!
//! Millimetres: `--px-per-mm S` (a telecentric or fronto-parallel view: `cx_mm = cx / S` in the
//! image frame), or `--calibration FILE` (the camera JSON `twincell render` writes: its
//! `calibration` object, or such an object alone) with `--plane-height-m H` (the end faces'
//! height in that camera's world; the edge points are back-projected onto that plane and fitted
//! there: `cx_mm`, `cy_mm` in the world frame). Each circle then carries `r_mm`,
//! `roundness_mm`, `cx_mm`, `cy_mm` and `sigma_roundness_mm`. With `--tolerance-mm T` it also
//! carries a `verdict` on its roundness against `T`: `conforming` when `roundness + band <= T`,
//! `not_conforming` when `roundness - band > T`, `undecided` in between (ISO 14253-1's decision
//! rule with a guard band). The band is `--guard-band-mm G` when given; by default, per circle,
//! twice the combined standard uncertainty `sqrt(sigma_roundness^2 + u_model^2)`, where
//! `u_model` = [`millimetres::ROUNDNESS_MODEL_UNCERTAINTY_PX`] pixels is the detector's roundness error on
//! the synthetic suite (`tests/metrology_space.rs`), converted to mm at the circle's scale.
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

mod compare;
mod millimetres;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use image::GrayImage;
use serde::Serialize;
use twincell::perception::bore::{BoreDetector, BoreDetectorParams, SkippedBore};

use crate::cli::{BadInput, EXIT_BAD_INPUT};
use millimetres::{Scale, circle_out, positive, scale_of};

/// Arguments of `twincell measure`.
#[derive(Debug, clap::Args)]
pub struct MeasureArgs {
    /// Images to measure: PNG (8 or 16 bit, grey, RGB, RGBA), JPEG, BMP or TIFF; colour is
    /// converted to luma.
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Image scale on the end faces, pixels per millimetre: adds `*_mm` fields.
    #[arg(long, value_name = "S", conflicts_with = "calibration")]
    pub px_per_mm: Option<f64>,
    /// Camera JSON as `twincell render` writes it (`shot.json`): adds `*_mm` fields measured on
    /// the end-face plane; needs --plane-height-m.
    #[arg(long, value_name = "FILE", requires = "plane_height_m")]
    pub calibration: Option<PathBuf>,
    /// Height of the tubes' end faces in the calibration's world frame, metres.
    #[arg(long, value_name = "H", requires = "calibration")]
    pub plane_height_m: Option<f64>,
    /// Roundness tolerance, mm: adds a conformity `verdict` to each circle.
    #[arg(long, value_name = "T")]
    pub tolerance_mm: Option<f64>,
    /// Half-width of the undecided band around the tolerance, mm (default: twice each circle's
    /// combined roundness uncertainty).
    #[arg(long, value_name = "G", requires = "tolerance_mm")]
    pub guard_band_mm: Option<f64>,
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
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    mm: Option<millimetres::CircleMm>,
}

/// A bore seen but not measured.
#[derive(Debug, Serialize)]
struct SkippedOut {
    cx: f64,
    cy: f64,
    r: f64,
    visible_share: f64,
    reason: &'static str,
}

impl From<&SkippedBore> for SkippedOut {
    fn from(s: &SkippedBore) -> Self {
        Self {
            cx: s.centre_px[0],
            cy: s.centre_px[1],
            r: s.radius_px,
            visible_share: s.visible_share,
            reason: s.reason.describe(),
        }
    }
}

/// One image of the contract: circles and time, or an error.
#[derive(Debug, Serialize)]
struct ImageOut {
    file: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    circles: Option<Vec<CircleOut>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    skipped: Option<Vec<SkippedOut>>,
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
        return compare::run_compare(args);
    }
    let scale = scale_of(args)?;
    if let Some(t) = args.tolerance_mm {
        if scale.is_none() {
            return Err(BadInput(
                "--tolerance-mm needs a scale: --px-per-mm or --calibration".to_string(),
            )
            .into());
        }
        positive("--tolerance-mm", t)?;
    }
    if let Some(g) = args.guard_band_mm
        && !(g.is_finite() && g >= 0.0)
    {
        return Err(BadInput(format!("--guard-band-mm: {g} is not a length >= 0")).into());
    }
    let mut images = Vec::with_capacity(args.images.len());
    let mut any_bad = false;
    for path in &args.images {
        let file = path.display().to_string();
        let measured = load_gray(path).and_then(|image| {
            if let Some(Scale::Camera(_, w, h)) = scale
                && image.dimensions() != (w, h)
            {
                return Err(format!(
                    "image is {}x{} px but the calibration's width_px x height_px is {w}x{h}",
                    image.width(),
                    image.height()
                ));
            }
            let (w, h) = image.dimensions();
            time_detect(
                &BoreDetector::new(BoreDetectorParams::for_image(w, h)),
                &image,
            )
        });
        let entry = match measured {
            Ok((report, ms)) => ImageOut {
                file,
                circles: Some(
                    report
                        .bores
                        .iter()
                        .map(|b| circle_out(b, scale, args))
                        .collect(),
                ),
                skipped: Some(report.skipped.iter().map(SkippedOut::from).collect()),
                ms: Some(ms),
                error: None,
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
                        if let Some(mm) = &c.mm {
                            write!(
                                stdout,
                                "    centre ({:.4}, {:.4}) mm  r {:.4} mm  roundness {:.4} mm",
                                mm.cx_mm, mm.cy_mm, mm.r_mm, mm.roundness_mm
                            )?;
                            match (mm.verdict, mm.guard_band_mm) {
                                (Some(v), Some(g)) => {
                                    writeln!(stdout, "  {} (band {g:.4} mm)", v.name())?
                                }
                                _ => writeln!(stdout)?,
                            }
                        }
                    }
                    for s in image.skipped.iter().flatten() {
                        writeln!(
                            stdout,
                            "  skipped near ({:.1}, {:.1}) r ~{:.1} px: {}",
                            s.cx, s.cy, s.r, s.reason
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
        skipped: None,
        ms: None,
        error: Some(reason),
    }
}

pub(super) fn load_gray(path: &Path) -> Result<GrayImage, String> {
    image::open(path)
        .map(|i| i.to_luma8())
        .map_err(|e| format!("cannot read image: {e}"))
}

pub(super) fn time_detect(
    detector: &BoreDetector,
    image: &GrayImage,
) -> Result<(twincell::perception::BoreReport, f64), String> {
    let start = Instant::now();
    let report = detector.detect_report(image).map_err(|e| e.to_string())?;
    Ok((report, start.elapsed().as_secs_f64() * 1e3))
}
