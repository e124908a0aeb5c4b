//! `twincell calibrate SCENARIO.toml`: the metrology's measurement-system study for the
//! scenario's camera (see docs/calibrate.md).
//!
//! Each shot builds the cell as a trial does from its own seed stream (a part of the catalogue,
//! its true roundness drawn over `[0, parts.max_roundness_mm]`, its lateral offset, the
//! bottles), stands the part where the belt stops it (its leading edge at the photo-eye's
//! beam), and draws the frame's realism (lights, stains, pose jitter, sensor effects). The
//! station's [`MetrologyStudy`] measures it against the truth. `--out FILE` writes the band as
//! a scenario file that extends the studied one and sets `roundness_uncertainty_mm`:
//! `twincell run FILE` runs the same cell judged with the camera's own band.

use std::path::{Component, Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, anyhow};
use clap::Args;
use nalgebra::Vector3;
use serde::Serialize;
use twincell::cell::{Cell, CellModel};
use twincell::render::{CameraRig, ObjectKind, Renderer, RendererOptions, Scene, Shot};
use twincell::rng::SimRng;
use twincell::scenario::{Override, Scenario};
use twincell::station::{ErrorSummary, KnownPart, MetrologyStudy, ShotErrors, StudySummary};

use super::BadInput;

/// Salt that keeps the study's shot streams apart from trials and other shots of the seed.
const CALIBRATE_SALT: u64 = 0x4341_4C49_4252;
/// Most shots one study takes.
const MAX_SHOTS: u32 = 100_000;

/// Arguments of `twincell calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// The scenario file (TOML).
    scenario: PathBuf,
    /// Shots to render and measure (at least 2).
    #[arg(long, default_value_t = 200)]
    shots: u32,
    /// Seed of the shots (default: the scenario's).
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: all cores); the figures do not depend on it.
    #[arg(long)]
    jobs: Option<usize>,
    /// Print the study as JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Override a scenario key before the study, as `twincell run --set` does (repeatable),
    /// e.g. `camera.position_m=[-0.3,-0.45,1.3]` to study another mount.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<Override>,
    /// Write the band to FILE: a scenario file that extends SCENARIO and sets
    /// `roundness_uncertainty_mm` to the study's U (run it with `twincell run FILE`). Not with
    /// `--set`: the band file extends the file alone.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
}

/// The study as printed with `--json`.
#[derive(Debug, Serialize)]
struct CalibrationReport {
    scenario: String,
    file: String,
    seed: u64,
    camera: CameraSummary,
    #[serde(flatten)]
    summary: StudySummary,
    /// The band the study gives: `roundness_uncertainty_mm` (U rounded up to 1 µm).
    band_roundness_uncertainty_mm: Option<f64>,
    /// The scenario's band before the study.
    scenario_roundness_uncertainty_mm: f64,
    /// Types whose `diameter_tolerance_mm` is narrower than the diameters' U.
    narrow_tolerances: Vec<String>,
}

#[derive(Debug, Serialize)]
struct CameraSummary {
    resolution_px: [u32; 2],
    horizontal_fov_deg: f64,
    roi_scale: u32,
    /// Angle of the optical axis from vertical.
    tilt_deg: f64,
    /// Distance from the camera to the point it looks at, m.
    distance_m: f64,
}

/// Runs `twincell calibrate`.
pub fn run(args: &CalibrateArgs) -> Result<ExitCode> {
    if !(2..=MAX_SHOTS).contains(&args.shots) {
        return Err(BadInput(format!(
            "--shots: {} is not in [2, {MAX_SHOTS}] (the spread needs two shots)",
            args.shots
        ))
        .into());
    }
    if args.jobs == Some(0) {
        return Err(BadInput("--jobs: must be at least 1".into()).into());
    }
    if args.out.is_some() && !args.set.is_empty() {
        return Err(BadInput(
            "--out with --set: the band file extends the scenario file alone, so it would not \
             hold the overrides; write them into a scenario file and calibrate that"
                .into(),
        )
        .into());
    }
    let path = &args.scenario;
    let scenario = Scenario::load_with(path, &args.set).map_err(|e| BadInput(e.to_string()))?;
    let model = CellModel::new(scenario.clone(), path)
        .map_err(|e| BadInput(format!("{}: {e}", path.display())))?;
    let rig = CameraRig::from_scenario(&scenario)
        .map_err(|e| BadInput(format!("{}: {e}", path.display())))?;
    let seed = args.seed.unwrap_or(scenario.seed);
    let study = MetrologyStudy::new(&scenario, rig);
    let jobs = args
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from))
        .min(args.shots as usize);
    let errors = measure_all(&model, &rig, &study, seed, args.shots, jobs)?;
    let summary = StudySummary::of(&errors);
    let report = report(&scenario, path, seed, &summary);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_table(&report);
    }
    let Some(out) = &args.out else {
        return Ok(ExitCode::SUCCESS);
    };
    let Some(band) = report.band_roundness_uncertainty_mm else {
        return Err(anyhow!(
            "no band written: {} of {} shots measured a bore",
            summary.shots - summary.not_measured,
            summary.shots
        ));
    };
    if band > scenario.roundness_tolerance_mm {
        return Err(anyhow!(
            "no band written: U {band:.3} mm exceeds roundness_tolerance_mm {} mm; this camera \
             cannot judge roundness at that tolerance",
            scenario.roundness_tolerance_mm
        ));
    }
    write_band(out, path, &report, band)?;
    Ok(ExitCode::SUCCESS)
}

/// Stages and measures shots `0..shots` on `jobs` threads, each with its own renderer; shot
/// `i`'s draws come from the seed and `i` alone, so the result does not depend on `jobs`.
fn measure_all(
    model: &CellModel,
    rig: &CameraRig,
    study: &MetrologyStudy,
    seed: u64,
    shots: u32,
    jobs: usize,
) -> Result<Vec<ShotErrors>> {
    let scenario = model.scenario();
    let options = RendererOptions {
        msaa_samples: scenario.camera.msaa_samples,
        supersample: scenario.camera.supersample,
    };
    let worker = |first: usize| -> Result<Vec<(u32, ShotErrors)>> {
        let mut renderer = Renderer::new(options)?;
        let mut out = Vec::new();
        for index in (first as u32..shots).step_by(jobs) {
            let (shot, part) = stage(model, rig, seed, u64::from(index))?;
            let errors = study.measure(&mut renderer, scenario, &shot, &part)?;
            out.push((index, errors));
        }
        Ok(out)
    };
    let results: Vec<Result<Vec<(u32, ShotErrors)>>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..jobs)
            .map(|first| scope.spawn(move || worker(first)))
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(anyhow!("a study thread panicked")))
            })
            .collect()
    });
    let mut errors = vec![ShotErrors::default(); shots as usize];
    for result in results {
        for (index, shot) in result? {
            errors[index as usize] = shot;
        }
    }
    Ok(errors)
}

/// Shot `index` of the study: the cell built as for a trial, its part standing where the belt
/// stops it (leading edge at the photo-eye's beam, the drawn lateral offset kept) with the
/// bottles keeping their offsets from it, and the frame's realism drawn.
fn stage(model: &CellModel, rig: &CameraRig, seed: u64, index: u64) -> Result<(Shot, KnownPart)> {
    let scenario = model.scenario();
    let mut rng = SimRng::derive(seed ^ CALIBRATE_SALT, index);
    let cell = Cell::build(model, &mut rng)?;
    let (scene, object_index) = Scene::at_photo_eye(&cell, scenario)
        .ok_or_else(|| anyhow!("shot {index}: the cell has no part to stage"))?;
    let ObjectKind::Part(part) = &scene.objects[object_index].kind else {
        return Err(anyhow!("shot {index}: the staged object is not a part"));
    };
    let height_m = scenario.part_types[part.type_index].height_mm / 1e3;
    let known = KnownPart {
        object_index,
        bore_diameter_m: part.bore.mean_diameter_m(),
        outer_diameter_m: 2.0 * part.outer_radius_m,
        roundness_m: part.bore.roundness_m(),
        end_face_z_m: cell.belt_top_z + height_m,
    };
    let shot = Shot::of_scene(scenario, rig, &scenario.sensor, scene, &mut rng);
    Ok((shot, known))
}

fn report(
    scenario: &Scenario,
    path: &Path,
    seed: u64,
    summary: &StudySummary,
) -> CalibrationReport {
    let camera = &scenario.camera;
    let (eye, target) = camera.eye_and_target(&scenario.conveyor);
    let axis = Vector3::from(target) - Vector3::from(eye);
    let tilt_deg = (-axis.z / axis.norm()).clamp(-1.0, 1.0).acos().to_degrees();
    let diameter_u = [summary.bore_diameter, summary.outer_diameter]
        .iter()
        .flatten()
        .map(|s| s.expanded_uncertainty_mm)
        .fold(0.0, f64::max);
    let narrow_tolerances = scenario
        .part_types
        .iter()
        .filter(|t| t.diameter_tolerance_mm() < diameter_u)
        .map(|t| {
            format!(
                "type {}: diameter_tolerance_mm {} is narrower than the diameters' U {diameter_u:.3} mm; \
                 its parts may go unidentified",
                t.name,
                t.diameter_tolerance_mm()
            )
        })
        .collect();
    CalibrationReport {
        scenario: scenario.name.clone(),
        file: path.display().to_string(),
        seed,
        camera: CameraSummary {
            resolution_px: camera.resolution_px,
            horizontal_fov_deg: camera.horizontal_fov_deg,
            roi_scale: camera.roi_scale,
            tilt_deg,
            distance_m: axis.norm(),
        },
        summary: *summary,
        band_roundness_uncertainty_mm: summary
            .roundness
            .map(|r| (r.expanded_uncertainty_mm * 1e3).ceil() / 1e3),
        scenario_roundness_uncertainty_mm: scenario.roundness_uncertainty_mm,
        narrow_tolerances,
    }
}

fn print_table(report: &CalibrationReport) {
    let c = &report.camera;
    let s = &report.summary;
    println!(
        "calibrate {} ({}): {} shots, seed {}; camera {}x{}, {:.0}° field, roi_scale {}, tilt {:.1}°, {:.2} m away",
        report.scenario,
        report.file,
        s.shots,
        report.seed,
        c.resolution_px[0],
        c.resolution_px[1],
        c.horizontal_fov_deg,
        c.roi_scale,
        c.tilt_deg,
        c.distance_m
    );
    println!(
        "{:<16} {:>6} {:>10} {:>8} {:>12} {:>12}",
        "quantity", "n", "bias mm", "sd mm", "U (k=2) mm", "max |e| mm"
    );
    let rows: [(&str, Option<ErrorSummary>); 3] = [
        ("roundness", s.roundness),
        ("bore diameter", s.bore_diameter),
        ("outer diameter", s.outer_diameter),
    ];
    for (name, row) in rows {
        match row {
            Some(r) => println!(
                "{name:<16} {:>6} {:>+10.4} {:>8.4} {:>12.4} {:>12.4}",
                r.n, r.bias_mm, r.sd_mm, r.expanded_uncertainty_mm, r.max_abs_mm
            ),
            None => println!("{name:<16} {:>6} (too few measured)", 0),
        }
    }
    println!("shots with no bore measured: {}", s.not_measured);
    match report.band_roundness_uncertainty_mm {
        Some(band) => println!(
            "band: roundness_uncertainty_mm = {band} (the scenario's: {})",
            report.scenario_roundness_uncertainty_mm
        ),
        None => println!("band: none (too few bores measured)"),
    }
    for note in &report.narrow_tolerances {
        println!("note: {note}");
    }
}

/// Writes the band file: a scenario that extends the studied one (named relative to the band
/// file's folder) and sets `roundness_uncertainty_mm`.
fn write_band(
    out: &Path,
    scenario_path: &Path,
    report: &CalibrationReport,
    band: f64,
) -> Result<()> {
    let folder = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&folder)
        .with_context(|| format!("--out: cannot create {}", folder.display()))?;
    let base = std::fs::canonicalize(scenario_path)
        .with_context(|| format!("cannot resolve {}", scenario_path.display()))?;
    let folder = std::fs::canonicalize(&folder)
        .with_context(|| format!("--out: cannot resolve {}", folder.display()))?;
    if let Some(name) = out.file_name()
        && folder.join(name) == base
    {
        return Err(BadInput(format!(
            "--out: {} is the studied scenario; write the band beside it",
            out.display()
        ))
        .into());
    }
    let extends = relative_to(&base, &folder);
    let s = &report.summary;
    let line = |name: &str, row: Option<ErrorSummary>| match row {
        Some(r) => format!(
            "# {name}: bias {:+.4} mm, sd {:.4} mm, U (k=2) {:.4} mm over {} shots\n",
            r.bias_mm, r.sd_mm, r.expanded_uncertainty_mm, r.n
        ),
        None => format!("# {name}: too few measured\n"),
    };
    let text = format!(
        "# The metrology band of {}'s camera, written by `twincell calibrate` ({} shots, seed {}).\n\
         {}{}{}\
         # `twincell run` on this file runs that scenario judged with this band.\n\
         extends = {}\n\
         roundness_uncertainty_mm = {band}\n",
        report.file,
        s.shots,
        report.seed,
        line("roundness", s.roundness),
        line("bore diameter", s.bore_diameter),
        line("outer diameter", s.outer_diameter),
        toml::Value::String(extends.display().to_string()),
    );
    std::fs::write(out, text).with_context(|| format!("--out: cannot write {}", out.display()))?;
    eprintln!(
        "wrote {} (run it with `twincell run {}`)",
        out.display(),
        out.display()
    );
    Ok(())
}

/// `path` relative to the folder `from` (both absolute).
fn relative_to(path: &Path, from: &Path) -> PathBuf {
    let a: Vec<Component> = path.components().collect();
    let b: Vec<Component> = from.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut relative = PathBuf::new();
    for _ in common..b.len() {
        relative.push("..");
    }
    for part in &a[common..] {
        relative.push(part);
    }
    relative
}
