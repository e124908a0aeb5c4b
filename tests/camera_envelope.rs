//! The camera envelope (issue 24): a `[camera]` anywhere in it is accepted, with the pick station
//! seen where the optical axis points and the roll turning the image; a camera just outside it is
//! refused, naming the file, the key and the envelope (exit 2 from the CLI).

mod common;

use std::path::Path;

use nalgebra::Point3;
use twincell::render::CameraRig;
use twincell::rng::SimRng;
use twincell::scenario::{CAMERA_ENVELOPE, CameraSection, Scenario};

/// The paper's scenario with a `[camera]` section of `keys` (TOML lines).
fn with_camera(keys: &str) -> Result<Scenario, twincell::scenario::ScenarioError> {
    let path = common::scenario_path("paper_50.toml");
    let text = common::read(&path);
    Scenario::from_toml(&format!("{text}\n[camera]\n{keys}"), Path::new("mine.toml"))
}

/// Camera keys for a camera `distance_m` from the pick station, its axis `tilt_deg` from
/// vertical towards `azimuth_deg` (from +x), looking at the station.
fn camera_keys(
    station: [f64; 3],
    tilt_deg: f64,
    azimuth_deg: f64,
    distance_m: f64,
    roll_deg: f64,
    fov_deg: f64,
    resolution: [u32; 2],
) -> String {
    let (t, a) = (tilt_deg.to_radians(), azimuth_deg.to_radians());
    let eye = [
        station[0] + distance_m * t.sin() * a.cos(),
        station[1] + distance_m * t.sin() * a.sin(),
        station[2] + distance_m * t.cos(),
    ];
    format!(
        "position_m = [{:?}, {:?}, {:?}]\nlook_at_m = [{:?}, {:?}, {:?}]\nroll_deg = {roll_deg:?}\n\
         horizontal_fov_deg = {fov_deg:?}\nresolution_px = [{}, {}]\n",
        eye[0], eye[1], eye[2], station[0], station[1], station[2], resolution[0], resolution[1]
    )
}

fn station() -> [f64; 3] {
    CameraSection::pick_station(&common::paper_50().conveyor)
}

#[test]
fn cameras_drawn_over_the_whole_envelope_are_accepted_and_see_the_station() {
    let e = CAMERA_ENVELOPE;
    let station = station();
    let mut rng = SimRng::new(2424);
    for k in 0..300 {
        // The corners of every range come first, then draws inside.
        let corner = |i: u32, low: f64, high: f64| if (k >> i) & 1 == 0 { low } else { high };
        let (tilt, distance, fov, roll, resolution) = if k < 32 {
            (
                corner(0, 0.0, e.max_tilt_deg),
                corner(1, e.distance_m[0], e.distance_m[1]),
                corner(2, e.horizontal_fov_deg[0], e.horizontal_fov_deg[1]),
                corner(3, e.roll_deg[0], e.roll_deg[1]),
                if (k >> 4) & 1 == 0 {
                    e.min_resolution_px
                } else {
                    e.max_resolution_px
                },
            )
        } else {
            let w = rng.range(640.0, 2048.0) as u32;
            (
                rng.range(0.0, e.max_tilt_deg),
                rng.range(e.distance_m[0], e.distance_m[1]),
                rng.range(e.horizontal_fov_deg[0], e.horizontal_fov_deg[1]),
                rng.range(e.roll_deg[0], e.roll_deg[1]),
                [w, (w * 3 / 4).max(480)],
            )
        };
        let azimuth = rng.range(0.0, 360.0);
        let keys = camera_keys(station, tilt, azimuth, distance, roll, fov, resolution);
        let scenario = with_camera(&keys).unwrap_or_else(|err| panic!("{keys}: {err}"));
        let (t, d) = scenario.camera.tilt_and_distance(&scenario.conveyor);
        assert!(
            (t - tilt).abs() < 1e-6 && (d - distance).abs() < 1e-9,
            "{keys}"
        );
        let rig = CameraRig::from_scenario(&scenario).unwrap_or_else(|err| panic!("{err}"));
        let Some([u, v]) = rig.calibration.project(&Point3::from(station)) else {
            panic!("{keys}: the station is behind the camera");
        };
        assert!(
            (u - rig.calibration.cx_px).abs() < 1e-6 && (v - rig.calibration.cy_px).abs() < 1e-6,
            "{keys}: the station is at ({u}, {v})"
        );
    }
}

#[test]
fn the_roll_turns_the_image_about_the_optical_axis() {
    let station = station();
    let along = Point3::new(station[0] + 0.05, station[1], station[2]);
    let see = |roll: f64| {
        let keys = camera_keys(station, 20.0, 90.0, 0.6, roll, 44.0, [1280, 960]);
        let scenario = with_camera(&keys).unwrap_or_else(|err| panic!("{err}"));
        let rig = CameraRig::from_scenario(&scenario).unwrap_or_else(|err| panic!("{err}"));
        let c = &rig.calibration;
        let Some([u, v]) = c.project(&along) else {
            panic!("behind")
        };
        (u - c.cx_px, v - c.cy_px)
    };
    let (u0, v0) = see(0.0);
    // Unrolled, +x along the belt runs to the image's right.
    assert!(u0 > 40.0 && v0.abs() < 1.0, "({u0}, {v0})");
    for roll in [30.0, 90.0, -120.0, 180.0] {
        let (u, v) = see(roll);
        // The camera turned clockwise (seen from behind) by the roll: the scene turns the other
        // way in the image, by the same angle, at the same distance from the centre.
        let turned = v.atan2(u).to_degrees();
        let expected = -roll;
        let diff = (turned - expected + 540.0).rem_euclid(360.0) - 180.0;
        assert!(diff.abs() < 0.01, "roll {roll}: at {turned} degrees");
        assert!((u.hypot(v) - u0.hypot(v0)).abs() < 1e-6, "roll {roll}");
    }
}

#[test]
fn cameras_just_outside_the_envelope_are_refused_naming_the_key_and_the_envelope() {
    let e = CAMERA_ENVELOPE;
    let s = station();
    let [fov_low, fov_high] = e.horizontal_fov_deg;
    let [d_low, d_high] = e.distance_m;
    let fine =
        |tilt, distance, roll, fov, res| camera_keys(s, tilt, 45.0, distance, roll, fov, res);
    let cases = [
        (
            fine(e.max_tilt_deg + 0.2, 0.6, 0.0, 44.0, [1280, 960]),
            "camera.look_at_m",
        ),
        (
            fine(10.0, d_low - 0.005, 0.0, 44.0, [1280, 960]),
            "camera.position_m",
        ),
        (
            fine(10.0, d_high + 0.005, 0.0, 44.0, [1280, 960]),
            "camera.position_m",
        ),
        (fine(10.0, 0.6, 180.5, 44.0, [1280, 960]), "camera.roll_deg"),
        (
            fine(10.0, 0.6, -180.5, 44.0, [1280, 960]),
            "camera.roll_deg",
        ),
        (
            fine(10.0, 0.6, 0.0, fov_low - 0.1, [1280, 960]),
            "camera.horizontal_fov_deg",
        ),
        (
            fine(10.0, 0.6, 0.0, fov_high + 0.1, [1280, 960]),
            "camera.horizontal_fov_deg",
        ),
        (
            fine(10.0, 0.6, 0.0, 44.0, [639, 480]),
            "camera.resolution_px",
        ),
        (
            fine(10.0, 0.6, 0.0, 44.0, [640, 479]),
            "camera.resolution_px",
        ),
        (
            fine(10.0, 0.6, 0.0, 44.0, [2049, 1536]),
            "camera.resolution_px",
        ),
        (
            fine(10.0, 0.6, 0.0, 44.0, [2048, 1537]),
            "camera.resolution_px",
        ),
        // Only a position: the default look-at point is the station.
        (
            format!(
                "position_m = [{:?}, {:?}, {:?}]\n",
                s[0] + 0.5,
                s[1],
                s[2] + 0.5
            ),
            "camera.position_m",
        ),
    ];
    for (keys, key) in cases {
        let err = match with_camera(&keys) {
            Ok(_) => panic!("accepted:\n{keys}"),
            Err(err) => err,
        };
        assert_eq!(err.key, key, "{keys}: {err}");
        let text = err.to_string();
        assert!(text.starts_with(&format!("mine.toml: {key}: ")), "{text}");
        assert!(text.contains("the camera envelope"), "{text}");
        assert!(
            text.contains("35 degrees") && text.contains("0.35-1.2 m"),
            "{text}"
        );
    }
}

#[test]
fn the_cli_exits_2_naming_the_file_the_key_and_the_envelope() {
    let dir = common::out_dir("camera_envelope", "cli");
    let path = dir.join("tilted_too_far.toml");
    let s = station();
    let keys = camera_keys(s, 40.0, 0.0, 0.6, 0.0, 44.0, [1280, 960]);
    let base = common::scenario_path("paper_50.toml");
    let text = format!("extends = {:?}\n[camera]\n{keys}", common::path_str(&base));
    std::fs::write(&path, text).expect("write scenario");
    let out = dir.join("out");
    let (code, _, stderr) = common::twincell(&[
        "run",
        common::path_str(&path),
        "--trials",
        "1",
        "--out",
        common::path_str(&out),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("tilted_too_far.toml"), "{stderr}");
    assert!(stderr.contains("camera.look_at_m"), "{stderr}");
    assert!(stderr.contains("the camera envelope"), "{stderr}");
}
