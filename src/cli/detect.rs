//! `twincell detect IMAGE... [--json] [--model FILE]`: the part detector on images.
//!
//! Output (`--json`): `{"images":[{"file":F,"ms":T,"detections":[{"class":NAME,"score":S,
//! "box":[x0,y0,x1,y1]}]}]}`, boxes in image pixels (edges; x right, y down), best first; `ms` is
//! the detector's time on that image (decoding the file excluded). An image that cannot be read
//! does not stop the others: its entry is `{"file":F,"error":WHY}`, the reason also goes to
//! stderr naming the file, and the process exits with code 2 after printing every result.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use serde::Serialize;
use twincell::detect::Detector;

use crate::cli::{BadInput, EXIT_BAD_INPUT};

/// Arguments of `twincell detect`.
#[derive(Debug, clap::Args)]
pub struct DetectArgs {
    /// Images to look at (PNG).
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Print JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// The network (ONNX, with its model card beside it); default: the shipped one.
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// Write the first image's network input and raw output (little-endian f32 files plus
    /// shapes.json) to DIR, for training/parity.py.
    #[arg(long, value_name = "DIR", hide = true)]
    pub dump_raw: Option<PathBuf>,
}

#[derive(Debug, Serialize)]
struct DetectionOut<'a> {
    class: &'a str,
    score: f32,
    #[serde(rename = "box")]
    box_px: [f32; 4],
}

#[derive(Debug, Serialize)]
struct ImageOut<'a> {
    file: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    ms: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    detections: Option<Vec<DetectionOut<'a>>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
}

fn write_f32(path: &Path, values: impl Iterator<Item = f32>) -> anyhow::Result<()> {
    let bytes: Vec<u8> = values.flat_map(f32::to_le_bytes).collect();
    std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))
}

/// Writes the network input and raw output for `image` under `dir`.
fn dump_raw(detector: &mut Detector, image: &image::RgbImage, dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let (input, _) = detector.preprocess(image)?;
    let output = detector.run_raw(&input)?;
    write_f32(&dir.join("input.f32"), input.iter().copied())?;
    write_f32(&dir.join("output.f32"), output.iter().copied())?;
    let shapes = serde_json::json!({ "input": input.shape(), "output": output.shape() });
    let path = dir.join("shapes.json");
    std::fs::write(&path, shapes.to_string() + "\n")
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Runs `twincell detect`.
pub fn run(args: &DetectArgs) -> anyhow::Result<ExitCode> {
    let mut detector = match &args.model {
        Some(path) => Detector::load(path),
        None => Detector::load_default(),
    }
    .map_err(|e| BadInput(e.to_string()))?;
    let names = detector.class_names().to_vec();
    let mut images = Vec::with_capacity(args.images.len());
    let mut any_bad = false;
    for (index, path) in args.images.iter().enumerate() {
        let file = path.display().to_string();
        let image = match image::open(path) {
            Ok(image) => image.to_rgb8(),
            Err(e) => {
                eprintln!("error: {file}: {e}");
                any_bad = true;
                images.push(ImageOut {
                    file,
                    ms: None,
                    detections: None,
                    error: Some(e.to_string()),
                });
                continue;
            }
        };
        if index == 0
            && let Some(dir) = &args.dump_raw
        {
            dump_raw(&mut detector, &image, dir)?;
        }
        let start = Instant::now();
        let found = detector
            .detect(&image)
            .with_context(|| format!("{file}: detection failed"))?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let detections = found
            .iter()
            .map(|d| DetectionOut {
                class: &names[d.class_id],
                score: d.score,
                box_px: d.box_px,
            })
            .collect();
        images.push(ImageOut {
            file,
            ms: Some(ms),
            detections: Some(detections),
            error: None,
        });
    }
    let mut stdout = std::io::stdout().lock();
    if args.json {
        serde_json::to_writer(&mut stdout, &serde_json::json!({ "images": images }))?;
        writeln!(stdout)?;
    } else {
        for image in &images {
            match (&image.detections, image.ms) {
                (Some(detections), Some(ms)) => {
                    writeln!(
                        stdout,
                        "{}: {} object(s), {ms:.1} ms",
                        image.file,
                        detections.len()
                    )?;
                    for d in detections {
                        let [x0, y0, x1, y1] = d.box_px;
                        writeln!(
                            stdout,
                            "  {:<10} {:.3}  box ({x0:.1}, {y0:.1}) - ({x1:.1}, {y1:.1})",
                            d.class, d.score
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
