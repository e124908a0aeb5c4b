//! Rerun recordings: `twincell run --record` writes a recording that the Rerun CLI of the
//! matching version verifies, with the entities the README promises; recording changes no trial
//! record; the recording holds the same data for any number of jobs; the perception panel.
//!
//! Verification runs `scripts/verify_rrd.sh`, which installs `rerun-sdk` into a virtual
//! environment on first use. When it cannot, these tests fail: they never skip.
#![cfg(feature = "record")]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{root, twincell, without_timing};
use twincell::batch::{FailureReason, TrialRecord};
use twincell::cell::{Cell, CellModel};
use twincell::perception::BoreDetector;
use twincell::perception::calibration::MeasureOnPlane;
use twincell::record::RerunRecorder;
use twincell::render::{CameraRig, Renderer, RendererOptions, Shot};
use twincell::rng::SimRng;
use twincell::scenario::{Scenario, SensorSection};
use twincell::task::TrialObserverFactory;
use twincell::task::{BoreView, CellView, DetectionView, PerceptionFrame};

fn out_dir(name: &str) -> PathBuf {
    common::out_dir("record", name)
}

/// Runs `scripts/verify_rrd.sh` with `args`; panics with its output when it fails.
fn verify(args: &[&str]) {
    let output = Command::new(root().join("scripts/verify_rrd.sh"))
        .args(args)
        .output()
        .expect("verify_rrd.sh runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    eprintln!("{text}");
    assert!(
        output.status.success(),
        "verify_rrd.sh {args:?} failed:\n{text}"
    );
}

/// Runs two smoke trials with oracle perception, `extra` appended; asserts success.
fn run_smoke(out: &Path, extra: &[&str]) {
    let scenario = common::scenario_path("smoke.toml");
    let mut args = vec![
        "run",
        scenario.to_str().expect("utf-8 path"),
        "--trials",
        "2",
        "--perception",
        "oracle",
        "--out",
        out.to_str().expect("utf-8 path"),
    ];
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = twincell(&args);
    assert_eq!(code, 0, "twincell {args:?}\n{stdout}\n{stderr}");
}

#[test]
fn recording_verifies_and_changes_no_record_for_any_jobs() {
    let plain = out_dir("plain");
    run_smoke(&plain, &["--jobs", "2"]);
    let one = out_dir("jobs1");
    let one_rrd = one.join("smoke.rrd");
    run_smoke(
        &one,
        &["--jobs", "1", "--record", one_rrd.to_str().expect("utf-8")],
    );
    let two = out_dir("jobs2");
    let two_rrd = two.join("smoke.rrd");
    run_smoke(
        &two,
        &["--jobs", "2", "--record", two_rrd.to_str().expect("utf-8")],
    );

    let expected = without_timing(&plain);
    assert_eq!(expected.len(), 2);
    assert_eq!(without_timing(&one), expected, "--record --jobs 1");
    assert_eq!(without_timing(&two), expected, "--record --jobs 2");

    let size = std::fs::metadata(&one_rrd)
        .expect("recording written")
        .len();
    eprintln!("smoke recording: {size} bytes for 2 trials");
    assert!(size > 100_000, "recording of {size} bytes is too small");
    let mut expected_entities = Vec::new();
    for trial in ["0000", "0001"] {
        for entity in [
            "cell=ViewCoordinates:xyz",
            "cell/part_00=Mesh3D:vertex_positions",
            "cell/part_00=Transform3D:translation",
            "cell/bottle_00=Mesh3D:vertex_positions",
            "cell/bottle_00=Transform3D:translation",
            "cell/belt=Mesh3D:vertex_positions",
            "cell/shoulder_Link=Transform3D:translation",
            "cell/finger_left_Link=Mesh3D:vertex_positions",
            "cell/finger_right_Link=Transform3D:translation",
            "cell/camera=Pinhole:image_from_camera",
            "joints_rad=Scalars:scalars",
            "gripper/opening_mm=Scalars:scalars",
            "gripper/grip_force_n=Scalars:scalars",
            "gripper/force_limit_n=Scalars:scalars",
            "log=TextLog:text",
        ] {
            expected_entities.push(format!("/trials/{trial}/{entity}"));
        }
    }
    expected_entities.extend(
        [
            "/outcomes=TextLog:text",
            "/metrology/roundness_mm/true=Scalars:scalars",
            "/metrology/roundness_mm/measured=Scalars:scalars",
            "/metrology/bore_diameter_mm/true=Scalars:scalars",
            "/metrology/bore_diameter_mm/measured=Scalars:scalars",
        ]
        .map(String::from),
    );
    let mut args = vec![one_rrd.to_str().expect("utf-8").to_string()];
    args.extend(expected_entities);
    verify(&args.iter().map(String::as_str).collect::<Vec<_>>());
    // The same data whatever the number of jobs.
    verify(&[
        "--same-as",
        one_rrd.to_str().expect("utf-8"),
        two_rrd.to_str().expect("utf-8"),
    ]);
}

#[test]
fn bad_record_paths_are_bad_input() {
    let out = out_dir("bad");
    let scenario = common::scenario_path("smoke.toml");
    let scenario = scenario.to_str().expect("utf-8");
    let out_arg = out.to_str().expect("utf-8");
    let run_recording_to = |record: &str| {
        twincell(&[
            "run",
            scenario,
            "--trials",
            "1",
            "--perception",
            "oracle",
            "--out",
            out_arg,
            "--record",
            record,
        ])
    };
    let (code, _, stderr) = run_recording_to("smoke.txt");
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("--record") && stderr.contains(".rrd"),
        "{stderr}"
    );
    let missing = out.join("no/such/dir/smoke.rrd");
    let (code, _, stderr) = run_recording_to(missing.to_str().expect("utf-8"));
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("no/such/dir/smoke.rrd"), "{stderr}");
}

/// A perception frame built here from a rendered pick-station shot: the shot's true objects as
/// detections and the bore detector's measurements against the truth.
fn perception_frame(scenario: &Scenario) -> PerceptionFrame {
    let rig = CameraRig::from_scenario(scenario).expect("camera");
    let shot = Shot::pick_station(
        &CellModel::with_urdf(scenario.clone(), None).expect("cell model"),
        &rig,
        &SensorSection::ideal(),
        0,
    )
    .expect("shot");
    let mut renderer = Renderer::new(RendererOptions::default()).expect("a renderer");
    let image = shot.render(&mut renderer).expect("render");
    let truths = shot.truth(scenario);
    let detector = BoreDetector::default();
    let gray = image::DynamicImage::ImageRgb8(image.clone()).to_luma8();
    let found = detector.detect(&gray).expect("detect");
    let truth = truths
        .iter()
        .find_map(|t| t.bore)
        .expect("the part is in view");
    let calibration = rig
        .calibration
        .with_end_face_height(truth.end_face_height_m);
    let bores = found
        .iter()
        .map(|bore| {
            let plane = calibration
                .measure_on_plane(bore, detector.params.max_upr)
                .ok();
            BoreView {
                centre_px: bore.centre_px,
                radius_px: bore.radius_px,
                contour_px: bore.edge_points_px.clone(),
                measured_roundness_mm: plane.map(|p| p.roundness_m * 1e3),
                true_roundness_mm: Some(truth.roundness_mm),
                measured_diameter_mm: plane.map(|p| p.diameter_m * 1e3),
                true_diameter_mm: Some(truth.radius_mm * 2.0),
            }
        })
        .collect();
    let detections = truths
        .iter()
        .map(|t| DetectionView {
            class_name: t.class.clone(),
            score: 1.0,
            box_px: [
                t.bbox_px[0] as f32,
                t.bbox_px[1] as f32,
                t.bbox_px[2] as f32 + 1.0,
                t.bbox_px[3] as f32 + 1.0,
            ],
        })
        .collect();
    PerceptionFrame {
        image,
        detections,
        bores,
        station: Some(scenario.part_types[0].name.clone()),
    }
}

#[test]
fn perception_panel_is_recorded() {
    let scenario = common::scenario("smoke.toml");
    let frame = perception_frame(&scenario);
    assert!(!frame.bores.is_empty(), "the detector found no bore");
    assert!(frame.detections.len() >= 2, "the part and the bottle");

    let out = out_dir("perception");
    let path = out.join("perception.rrd");
    let recorder = RerunRecorder::save(&path, "perception-test").expect("recorder");
    let mut observer = recorder.observer(3);
    let mut rng = SimRng::new(11);
    let cell = Cell::build(
        &CellModel::with_urdf(scenario.clone(), None).expect("model"),
        &mut rng,
    )
    .expect("cell");
    let view = CellView {
        cell: &cell,
        phase: twincell::outcome::Phase::Perceive,
        joint_command_rad: scenario.robot.home_q_rad,
        grip_force_limit_n: scenario.gripper.grip_force_n,
    };
    observer.begin_trial(3, &scenario, &view);
    observer.sample(0.0, &view);
    observer.perception(0.0, &frame);
    observer.finish_trial(&TrialRecord::failed(
        3,
        11,
        FailureReason::NotDetected,
        "a perception test, not a trial",
    ));
    drop(observer);
    recorder.finish().expect("recording written");
    verify(&[
        path.to_str().expect("utf-8"),
        "/trials/0003/cell/camera=Pinhole:image_from_camera",
        "/trials/0003/cell/camera/image=Image:buffer",
        "/trials/0003/cell/camera/detections=Boxes2D:half_sizes",
        "/trials/0003/cell/camera/detections=Boxes2D:labels",
        "/trials/0003/cell/camera/bore_contours=LineStrips2D:strips",
        "/trials/0003/cell/camera/bore_circles=LineStrips2D:labels",
        "/trials/0003/cell/camera/bore_centres=Points2D:positions",
        "/trials/0003/log=TextLog:text",
        "/outcomes=TextLog:text",
    ]);
}
