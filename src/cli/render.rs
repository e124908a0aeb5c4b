//! `twincell render SCENARIO --out DIR` and `twincell dataset SCENARIO --count N --out DIR`: the
//! cell's camera, headless.
//!
//! `render` writes `DIR/shot.png` and `DIR/shot.json`: the calibration perception gets, the
//! camera pose the frame was really taken from (with the scenario's pose jitter), and per labelled
//! object its class, pixel box (inclusive first/last column and row) and, for parts, the bore's
//! projected centre, mean radius and roundness in pixels and its true radius and roundness in mm.
//! `dataset` writes an Ultralytics/YOLO dataset (see [`twincell::render::dataset`]); with
//! `--family`, drawn over the tube family and the camera envelope (see
//! [`twincell::render::family`]).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use serde::Serialize;
use twincell::cell::CellModel;
use twincell::render::{CameraRig, ObjectTruth, Renderer, RendererOptions, Shot, dataset};
use twincell::scenario::Scenario;

use super::BadInput;
use twincell::camera::CameraJson;

/// Arguments of `twincell render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The scenario file (TOML).
    scenario: PathBuf,
    /// Output directory.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Which shot of the scenario's stream to render.
    #[arg(long, default_value_t = 0)]
    index: u64,
    /// Image width and height in pixels, overriding the scenario's `camera.resolution_px`.
    #[arg(long, value_names = ["W", "H"], num_args = 2)]
    resolution: Option<Vec<u32>>,
}

/// Arguments of `twincell dataset`.
#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// The scenario file (TOML).
    scenario: PathBuf,
    /// Number of images.
    #[arg(long)]
    count: u64,
    /// Output directory.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Image width and height in pixels, overriding the scenario's `camera.resolution_px`.
    #[arg(long, value_names = ["W", "H"], num_args = 2)]
    resolution: Option<Vec<u32>>,
    /// Draw each image's camera over the camera envelope and its tubes over the whole tube
    /// family (classes `tube` and `foreign`, a JSON of the draw beside each label file), in the
    /// scenario's cell, bottles and sensor realism.
    #[arg(long)]
    family: bool,
    /// With `--family`: in half of the images, set a bottle down between a tube and the camera
    /// (0.5-0.9 of its end face left in view), and leave out any tube less than half in view.
    #[arg(long, requires = "family")]
    occlude: bool,
}

#[derive(Debug, Serialize)]
struct ShotJson<'a> {
    scenario: &'a str,
    seed: u64,
    index: u64,
    image: &'a str,
    calibration: CameraJson,
    rendered_camera: CameraJson,
    objects: &'a [ObjectTruth],
}

/// Loads the scenario and the camera at the asked resolution.
fn load(scenario_path: &Path, resolution: Option<&Vec<u32>>) -> Result<(Scenario, CameraRig)> {
    let mut scenario = Scenario::load(scenario_path).map_err(|e| BadInput(e.to_string()))?;
    if let Some(size) = resolution {
        let &[w, h] = size.as_slice() else {
            return Err(BadInput("--resolution: needs W and H".into()).into());
        };
        scenario.camera.resolution_px = [w, h];
        scenario
            .validate(scenario_path)
            .map_err(|e| BadInput(format!("--resolution: {e}")))?;
    }
    let rig = CameraRig::from_scenario(&scenario)
        .map_err(|e| BadInput(format!("{}: {e}", scenario_path.display())))?;
    Ok((scenario, rig))
}

fn renderer_for(scenario: &Scenario) -> Result<Renderer> {
    let renderer = Renderer::new(RendererOptions {
        msaa_samples: scenario.camera.msaa_samples,
        supersample: scenario.camera.supersample,
    })?;
    eprintln!("camera: rendering on {}", renderer.adapter_name());
    Ok(renderer)
}

/// Runs `twincell render`.
pub fn run_render(args: &RenderArgs) -> Result<ExitCode> {
    let (scenario, rig) = load(&args.scenario, args.resolution.as_ref())?;
    let model = CellModel::new(scenario.clone(), &args.scenario)
        .map_err(|e| BadInput(format!("{}: {e}", args.scenario.display())))?;
    let mut renderer = renderer_for(&scenario)?;
    let shot = Shot::pick_station(&model, &rig, &scenario.sensor, args.index)?;
    let image = shot.render(&mut renderer)?;
    let truths = shot.truth(&scenario);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let image_path = args.out.join("shot.png");
    image
        .save(&image_path)
        .with_context(|| format!("cannot write {}", image_path.display()))?;
    let json = ShotJson {
        scenario: &scenario.name,
        seed: scenario.seed,
        index: args.index,
        image: "shot.png",
        calibration: CameraJson::new(&rig.calibration, rig.width_px, rig.height_px),
        rendered_camera: CameraJson::new(&shot.exposure.camera, rig.width_px, rig.height_px),
        objects: &truths,
    };
    let json_path = args.out.join("shot.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&json)? + "\n")
        .with_context(|| format!("cannot write {}", json_path.display()))?;
    println!(
        "wrote {} and {} ({} labelled objects)",
        image_path.display(),
        json_path.display(),
        truths.len()
    );
    Ok(ExitCode::SUCCESS)
}

/// Runs `twincell dataset`.
pub fn run_dataset(args: &DatasetArgs) -> Result<ExitCode> {
    if args.count == 0 {
        return Err(BadInput("--count: must be at least 1".into()).into());
    }
    let (scenario, rig) = load(&args.scenario, args.resolution.as_ref())?;
    let model = CellModel::new(scenario.clone(), &args.scenario)
        .map_err(|e| BadInput(format!("{}: {e}", args.scenario.display())))?;
    let mut renderer = renderer_for(&scenario)?;
    let start = Instant::now();
    let summary = if args.family {
        dataset::export_family(
            &model,
            &rig,
            &mut renderer,
            args.count,
            args.occlude,
            &args.out,
        )?
    } else {
        dataset::export(&model, &rig, &mut renderer, args.count, &args.out)?
    };
    println!(
        "wrote {} train + {} val images to {} in {:.1} s; objects per class: {}",
        summary.train,
        summary.val,
        args.out.display(),
        start.elapsed().as_secs_f64(),
        summary
            .objects_per_class
            .iter()
            .map(|(name, n)| format!("{name} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(ExitCode::SUCCESS)
}
