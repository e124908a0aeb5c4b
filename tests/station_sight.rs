//! The camera's sight of the pick station past the arm at home (`cell::StationSight`): its
//! verdict agrees with what the renderer draws, cameras drawn over the whole envelope; a camera
//! the arm hides is refused by `twincell run` with the key and the link named (exit 2), where it
//! used to fail every trial as `not_detected`; every shipped scenario's camera sees the whole
//! station.

mod common;

use std::path::Path;

use nalgebra::Point3;
use twincell::cell::{CellModel, MIN_EYE_CLEARANCE_M, StationSight};
use twincell::render::{CameraRig, Exposure, Renderer, RendererOptions, Scene, Shot};
use twincell::rng::SimRng;
use twincell::scenario::{CAMERA_ENVELOPE, CameraSection, Scenario, SensorSection};

/// `base` (a shipped scenario's text) with a camera `distance_m` from the pick station, its
/// axis `tilt_deg` from vertical towards `azimuth_deg` (from +x), looking at the station.
fn with_camera(base: &str, tilt_deg: f64, azimuth_deg: f64, distance_m: f64) -> Scenario {
    let path = common::scenario_path(base);
    let text = common::read(&path);
    let station = CameraSection::pick_station(&common::scenario(base).conveyor);
    let (t, a) = (tilt_deg.to_radians(), azimuth_deg.to_radians());
    let eye = [
        station[0] + distance_m * t.sin() * a.cos(),
        station[1] + distance_m * t.sin() * a.sin(),
        station[2] + distance_m * t.cos(),
    ];
    let keys = format!(
        "[camera]\nposition_m = [{:?}, {:?}, {:?}]\nlook_at_m = [{:?}, {:?}, {:?}]\n\
         resolution_px = [640, 480]\n",
        eye[0], eye[1], eye[2], station[0], station[1], station[2]
    );
    let mine = path.with_file_name("mine.toml");
    Scenario::from_toml(&format!("{text}\n{keys}"), &mine)
        .unwrap_or_else(|e| panic!("tilt {tilt_deg} azimuth {azimuth_deg}: {e}"))
}

/// The scene's robot links alone, as the camera at the pick station sees them: an id image
/// whose non-zero pixels are a link.
fn robot_ids(
    model: &CellModel,
    renderer: &mut Renderer,
) -> (image::ImageBuffer<image::Luma<u32>, Vec<u32>>, CameraRig) {
    let scenario = model.scenario();
    let rig = CameraRig::from_scenario(scenario).unwrap_or_else(|e| panic!("rig: {e}"));
    let shot = Shot::pick_station(model, &rig, &SensorSection::ideal(), 0)
        .unwrap_or_else(|e| panic!("shot: {e}"));
    let links = Scene {
        objects: shot
            .scene
            .objects
            .iter()
            .filter(|o| o.name.ends_with("_Link"))
            .cloned()
            .collect(),
        blur: None,
    };
    assert!(links.objects.len() >= 6, "links: {}", links.objects.len());
    let exposure: Exposure = shot.exposure.clone();
    let gpu = renderer.upload(&links);
    let ids = renderer
        .render_ids(&gpu, &exposure)
        .unwrap_or_else(|e| panic!("{e}"));
    (ids, rig)
}

/// Whether a link covers the pixel where `point` projects, or any of its eight neighbours
/// (`any`), or all nine (`!any`).
fn link_at(
    ids: &image::ImageBuffer<image::Luma<u32>, Vec<u32>>,
    rig: &CameraRig,
    point: &Point3<f64>,
    any: bool,
) -> bool {
    let Some([u, v]) = rig.calibration.project(point) else {
        panic!("{point:?} projects nowhere");
    };
    let (u, v) = (u.floor() as i64, v.floor() as i64);
    let mut covered = Vec::new();
    for dv in -1..=1 {
        for du in -1..=1 {
            let (x, y) = (u + du, v + dv);
            let inside = (0..i64::from(ids.width())).contains(&x)
                && (0..i64::from(ids.height())).contains(&y);
            covered.push(inside && ids.get_pixel(x as u32, y as u32).0[0] != 0);
        }
    }
    if any {
        covered.iter().any(|c| *c)
    } else {
        covered.iter().all(|c| *c)
    }
}

/// Cameras drawn over the whole envelope (tilt 0-35° towards every side, 0.35-1.2 m from the
/// station), half of them on the robot's side of the belt where the arm may stand between: the
/// sight check calls the station's centre hidden exactly where the renderer draws a robot link
/// over it.
#[test]
fn the_sight_check_agrees_with_the_rendered_robot_over_the_envelope() {
    let e = CAMERA_ENVELOPE;
    let mut renderer = match Renderer::new(RendererOptions {
        msaa_samples: 1,
        supersample: 1,
    }) {
        Ok(r) => r,
        Err(err) => panic!("no renderer: {err}"),
    };
    let mut rng = SimRng::new(4141);
    let (mut hidden, mut clear, mut touching) = (0, 0, 0);
    for k in 0..96 {
        // Every other camera leans towards the belt's +y side, where the robot stands.
        let (tilt, azimuth) = if k % 2 == 0 {
            (rng.range(10.0, e.max_tilt_deg), rng.range(45.0, 135.0))
        } else {
            (rng.range(0.0, e.max_tilt_deg), rng.range(0.0, 360.0))
        };
        let distance = rng.range(e.distance_m[0], e.distance_m[1]);
        let scenario = with_camera("paper_50.toml", tilt, azimuth, distance);
        let [px, py, pz] = CameraSection::pick_station(&scenario.conveyor);
        let high = scenario
            .part_types
            .iter()
            .map(|p| p.height_mm / 1000.0)
            .fold(0.0, f64::max);
        let model = CellModel::with_urdf(scenario, None).expect("cell model");
        let sight = StationSight::of(&model).expect("sight");
        let (ids, rig) = robot_ids(&model, &mut renderer);
        let center = Point3::new(px, py, pz + high);
        let what = format!(
            "camera {k}: tilt {tilt:.1} azimuth {azimuth:.0} at {distance:.2} m: {sight:?}"
        );
        if sight.eye_clearance_m < MIN_EYE_CLEARANCE_M {
            // The camera stands in the arm: refused for that, whatever the lines say (the
            // renderer clips what lies within its near plane).
            touching += 1;
            let refusal = sight
                .check()
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(
                refusal.contains("camera.position_m") && refusal.contains("_Link"),
                "{what}: {refusal}"
            );
        } else if sight.center_blocked {
            hidden += 1;
            assert!(
                link_at(&ids, &rig, &center, true),
                "{what}: no link drawn there"
            );
            assert!(sight.check().is_err(), "{what}");
            assert!(sight.link.is_some(), "{what}");
        } else {
            clear += 1;
            assert!(
                !link_at(&ids, &rig, &center, false),
                "{what}: a link drawn there"
            );
            assert!(sight.check().is_ok(), "{what}");
        }
        assert_eq!(
            sight.partial_warning().is_some(),
            sight.blocked > 0 && sight.check().is_ok(),
            "{what}"
        );
    }
    eprintln!("{hidden} cameras hidden by the arm, {clear} clear, {touching} in the arm");
    assert!(hidden >= 8 && clear >= 8, "{hidden} hidden, {clear} clear");
}

/// The camera of every shipped scenario sees every end face at its pick station.
#[test]
fn every_shipped_camera_sees_the_whole_station() {
    let mut files = Vec::new();
    for dir in ["scenarios", "scenarios/suite"] {
        for entry in std::fs::read_dir(common::root().join(dir)).expect("scenarios") {
            let path = entry.expect("entry").path();
            if path.extension().is_some_and(|x| x == "toml") {
                files.push(path);
            }
        }
    }
    files.sort();
    assert!(files.len() >= 11, "{files:?}");
    for path in files {
        let scenario = Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let model = CellModel::new(scenario, &path).expect("cell model");
        let sight = StationSight::of(&model).expect("sight");
        assert_eq!(sight.blocked, 0, "{}: {sight:?}", path.display());
    }
}

/// A camera mounted on the robot's side, where the forearm at home stands between it and the
/// station: `run` refuses it before the first trial, naming the file, the key and the link.
#[test]
fn run_refuses_a_camera_the_arm_hides() {
    let dir = common::out_dir("station_sight", "hidden");
    let scenario = common::extending(
        &dir,
        "hidden",
        "paper_50.toml",
        "name = \"hidden\"\ntrials = 2\n[camera]\n\
         position_m = [0.05, -0.196, 1.244]\nlook_at_m = [0.05, -0.45, 0.70]\n",
    );
    let out = dir.join("out");
    let (code, _, stderr) = common::twincell(&[
        "run",
        common::path_str(&scenario),
        "--out",
        common::path_str(&out),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("hidden.toml")
            && stderr.contains("camera.position_m")
            && stderr.contains("_Link")
            && stderr.contains("robot.home_q_rad"),
        "{stderr}"
    );
    assert!(!Path::new(&out).join("trials.jsonl").exists());
    // Oracle perception needs no camera: the same file runs.
    common::run_oracle(&scenario, &out);
}
