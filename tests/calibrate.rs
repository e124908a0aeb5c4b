//! `twincell calibrate`: the metrology's measurement-system study, through the real binary.

mod common;
use common::{out_dir, path_str, read, root, scenario_path, twincell};

use serde_json::Value;
use twincell::rng::SimRng;
use twincell::scenario::Scenario;

/// Runs the study on `scenario` with `shots` shots and returns its JSON.
fn study(scenario: &str, shots: u32, jobs: u32) -> Value {
    let shots = shots.to_string();
    let jobs = jobs.to_string();
    let args = [
        "calibrate",
        scenario,
        "--shots",
        &shots,
        "--jobs",
        &jobs,
        "--json",
    ];
    let (code, stdout, stderr) = twincell(&args);
    assert_eq!(code, 0, "{scenario}: {stderr}");
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{scenario}: {e}: {stdout}"))
}

/// The expanded uncertainty of `quantity` in a study's JSON, mm.
fn u_of(study: &Value, quantity: &str) -> f64 {
    study[quantity]["expanded_uncertainty_mm"]
        .as_f64()
        .unwrap_or_else(|| panic!("no U of {quantity}: {study}"))
}

/// A scenario file in `dir` that extends paper_50 with `body` (TOML sections).
fn variant(dir: &std::path::Path, name: &str, body: &str) -> String {
    let path = dir.join(format!("{name}.toml"));
    let base = scenario_path("paper_50.toml");
    let text = format!("extends = {:?}\n{body}", path_str(&base));
    std::fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    path_str(&path).to_owned()
}

#[test]
fn a_small_study_gives_finite_bias_and_uncertainty_on_any_jobs() {
    let paper = scenario_path("paper_50.toml");
    let one = study(path_str(&paper), 8, 1);
    for quantity in ["roundness", "bore_diameter", "outer_diameter"] {
        let row = &one[quantity];
        let n = row["n"].as_u64().unwrap_or(0);
        assert!(n >= 2, "{quantity}: {row}");
        for key in ["bias_mm", "sd_mm", "expanded_uncertainty_mm", "max_abs_mm"] {
            let value = row[key].as_f64().unwrap_or(f64::NAN);
            assert!(value.is_finite(), "{quantity}.{key}: {row}");
        }
        assert!(u_of(&one, quantity) > 0.0, "{quantity}: {row}");
    }
    let band = one["band_roundness_uncertainty_mm"].as_f64().unwrap_or(0.0);
    assert!(band >= u_of(&one, "roundness") && band > 0.0, "{one}");
    // The draws come from the seed and the shot's index alone.
    assert_eq!(one, study(path_str(&paper), 8, 2));
}

#[test]
fn the_overhead_camera_lies_within_the_shipped_band() {
    let paper = scenario_path("paper_50.toml");
    let report = study(path_str(&paper), 200, 2);
    let shipped = twincell::scenario::DEFAULT_ROUNDNESS_UNCERTAINTY_MM;
    let u = u_of(&report, "roundness");
    eprintln!("overhead camera, 200 shots: U {u:.4} mm against the shipped {shipped} mm");
    // The shipped band was measured with the roundness read on the raw low-passed profile
    // (0.0164 mm in tests/closed_loop.rs, now 0.0104 mm; this study 0.0177 mm). With the edge noise taken out
    // of each harmonic (`perception::roundness_noise`) the study reads 0.0119 mm: the shipped
    // band still covers the camera, at 1.7 times its U. Bounded here: within the shipped band
    // and above half of it, until the shipped band is measured again.
    assert!(u <= 1.2 * shipped && u >= 0.5 * shipped, "{report}");
    assert_eq!(report["not_measured"].as_u64(), Some(0), "{report}");
}

#[test]
fn a_coarser_or_noisier_camera_gets_a_wider_band() {
    let dir = out_dir("calibrate", "cameras");
    let mut rng = SimRng::new(24);
    let resolutions = [[1280, 960], [1600, 1200], [2048, 1536]];
    for draw in 0..2 {
        let [w, h] = resolutions[rng.below(resolutions.len() as u64) as usize];
        let fov = rng.range(38.0, 60.0);
        let noise = rng.range(0.0, 3.0);
        let camera = |w: u32, h: u32, noise: f64| {
            format!(
                "[camera]\nresolution_px = [{w}, {h}]\nhorizontal_fov_deg = {fov}\n\
                 [sensor]\nnoise_sigma = {noise}\n"
            )
        };
        let base = variant(&dir, &format!("base{draw}"), &camera(w, h, noise));
        let coarse = variant(&dir, &format!("coarse{draw}"), &camera(w / 2, h / 2, noise));
        let noisy = variant(&dir, &format!("noisy{draw}"), &camera(w, h, noise + 16.0));
        let shots = 60;
        let u_base = u_of(&study(&base, shots, 2), "roundness");
        let u_coarse = u_of(&study(&coarse, shots, 2), "roundness");
        let u_noisy = u_of(&study(&noisy, shots, 2), "roundness");
        eprintln!(
            "{w}x{h} {fov:.0}° noise {noise:.1}: U {u_base:.4} mm, half resolution {u_coarse:.4}, \
             noise +16 {u_noisy:.4}"
        );
        assert!(
            u_coarse > u_base,
            "{w}x{h} {fov:.1}°: {u_coarse} vs {u_base}"
        );
        assert!(u_noisy > u_base, "{w}x{h} {fov:.1}°: {u_noisy} vs {u_base}");
    }
}

#[test]
fn a_steeply_tilted_camera_finds_the_bores_the_closed_loop_finds() {
    // The study's bore finder is widened for the part's angle from the vertical as the closed
    // loop's is: without it, at 30-35 degrees it measured no bore in 16-70 % of the shots.
    let dir = out_dir("calibrate", "tilted");
    let mut rng = SimRng::new(35);
    let station = [0.05, -0.45, 0.70];
    for draw in 0..2 {
        let tilt = rng.range(30.0_f64, 35.0).to_radians();
        // Upstream along the belt, away from the robot across it, or anywhere between.
        let azimuth = rng.range(180.0_f64, 270.0).to_radians();
        let distance = 0.58;
        let position = [
            station[0] + distance * tilt.sin() * azimuth.cos(),
            station[1] + distance * tilt.sin() * azimuth.sin(),
            station[2] + distance * tilt.cos(),
        ];
        let body = format!(
            "[camera]\nposition_m = [{}, {}, {}]\nlook_at_m = [{}, {}, {}]\n",
            position[0], position[1], position[2], station[0], station[1], station[2]
        );
        let file = variant(&dir, &format!("tilt{draw}"), &body);
        let shots = 60;
        let report = study(&file, shots, 2);
        let missed = report["not_measured"].as_u64().unwrap_or(u64::MAX);
        eprintln!(
            "tilt {:.1}°, azimuth {:.0}°: {missed} of {shots} shots not measured, roundness U {:.4} mm",
            tilt.to_degrees(),
            azimuth.to_degrees(),
            u_of(&report, "roundness")
        );
        assert!(missed * 10 <= u64::from(shots), "{report}");
    }
}

#[test]
fn bad_shots_or_a_bad_scenario_exit_2_naming_the_cause() {
    let paper = scenario_path("paper_50.toml");
    let paper = path_str(&paper);
    for shots in ["1", "0", "-3", "many"] {
        let shots = format!("--shots={shots}");
        let (code, _, stderr) = twincell(&["calibrate", paper, &shots]);
        assert_eq!(code, 2, "{shots}: {stderr}");
        assert!(stderr.contains("shots"), "{shots}: {stderr}");
    }
    let dir = out_dir("calibrate", "bad");
    let bad = variant(&dir, "bad", "[camera]\nhorizontal_fov_deg = -5.0\n");
    let (code, _, stderr) = twincell(&["calibrate", &bad, "--shots", "4"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("bad.toml") && stderr.contains("horizontal_fov_deg"),
        "{stderr}"
    );
    let missing = dir.join("missing.toml");
    let (code, _, stderr) = twincell(&["calibrate", path_str(&missing), "--shots", "4"]);
    assert_eq!(code, 2, "{stderr}");
}

/// `--set` studies a camera the file does not hold, as `run --set` would run it: the same shots
/// through a tilted mount give the mount's tilt and the figures a file with that mount gives;
/// a bad key exits 2 naming it, and `--out` with `--set` is refused (the band file could not
/// hold the overrides).
#[test]
fn set_studies_another_mount_as_a_file_holding_it_does() {
    let dir = out_dir("calibrate", "set");
    let paper = scenario_path("paper_50.toml");
    let paper = path_str(&paper);
    let mut rng = SimRng::new(2412);
    let tilt = rng.range(10.0_f64, 35.0);
    let azimuth = rng.range(0.0_f64, 360.0).to_radians();
    let station = [0.05, -0.45, 0.70];
    let distance = rng.range(0.5, 0.8);
    let position = [
        station[0] + distance * tilt.to_radians().sin() * azimuth.cos(),
        station[1] + distance * tilt.to_radians().sin() * azimuth.sin(),
        station[2] + distance * tilt.to_radians().cos(),
    ];
    let value = format!("[{}, {}, {}]", position[0], position[1], position[2]);
    let set = format!("camera.position_m={value}");
    let look = format!(
        "camera.look_at_m=[{}, {}, {}]",
        station[0], station[1], station[2]
    );
    let args = [
        "calibrate",
        paper,
        "--shots",
        "6",
        "--jobs",
        "2",
        "--json",
        "--set",
        &set,
        "--set",
        &look,
    ];
    let (code, stdout, stderr) = twincell(&args);
    assert_eq!(code, 0, "{stderr}");
    let with_set: Value = serde_json::from_str(&stdout).expect("JSON");
    let read_tilt = with_set["camera"]["tilt_deg"].as_f64().unwrap_or(f64::NAN);
    assert!((read_tilt - tilt).abs() < 0.01, "tilt {tilt}: {with_set}");
    let body = format!(
        "[camera]\nposition_m = {value}\nlook_at_m = [{}, {}, {}]\n",
        station[0], station[1], station[2]
    );
    let file = variant(&dir, "mount", &body);
    let from_file = study(&file, 6, 2);
    for quantity in ["roundness", "bore_diameter", "outer_diameter"] {
        assert_eq!(with_set[quantity], from_file[quantity], "{quantity}");
    }
    let (code, _, stderr) =
        twincell(&["calibrate", paper, "--shots", "4", "--set", "camera.fov=50"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("camera.fov"), "{stderr}");
    let band = dir.join("band.toml");
    let (code, _, stderr) = twincell(&[
        "calibrate",
        paper,
        "--shots",
        "4",
        "--set",
        &set,
        "--out",
        path_str(&band),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("--out") && stderr.contains("--set"),
        "{stderr}"
    );
    assert!(!band.exists());
}

#[test]
fn run_reads_the_band_the_study_writes() {
    let dir = out_dir("calibrate", "band");
    let band_path = dir.join("bands").join("paper_50.band.toml");
    let paper = scenario_path("paper_50.toml");
    let (code, stdout, stderr) = twincell(&[
        "calibrate",
        path_str(&paper),
        "--shots",
        "6",
        "--jobs",
        "2",
        "--json",
        "--out",
        path_str(&band_path),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let report: Value = serde_json::from_str(&stdout).expect("study JSON");
    let band = report["band_roundness_uncertainty_mm"]
        .as_f64()
        .expect("a band");
    let loaded = Scenario::load(&band_path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(loaded.roundness_uncertainty_mm, band);
    // Everything but the band is the studied scenario's.
    let mut expected = Scenario::load(&paper).unwrap_or_else(|e| panic!("{e}"));
    expected.roundness_uncertainty_mm = band;
    assert_eq!(loaded, expected);

    let run_dir = dir.join("run");
    let (code, _, stderr) = twincell(&[
        "run",
        path_str(&band_path),
        "--trials",
        "2",
        "--jobs",
        "1",
        "--perception",
        "oracle",
        "--out",
        path_str(&run_dir),
    ]);
    assert_eq!(code, 0, "{stderr}");
    for line in read(&run_dir.join("trials.jsonl")).lines() {
        let trial: Value = serde_json::from_str(line).expect("trial JSON");
        let part = &trial["part"];
        let r = part["true_roundness_mm"].as_f64().expect("roundness");
        let clear = (r - loaded.roundness_tolerance_mm).abs() > band;
        assert_eq!(part["clear_cut"].as_bool(), Some(clear), "{line}");
    }

    // A band file edited to a value out of range is refused before any trial, naming the file
    // and the key.
    let text = read(&band_path);
    let edited = text.replace(
        &format!("roundness_uncertainty_mm = {band}"),
        "roundness_uncertainty_mm = -0.01",
    );
    assert_ne!(edited, text, "{text}");
    std::fs::write(&band_path, edited).expect("band file written");
    let (code, _, stderr) = twincell(&[
        "run",
        path_str(&band_path),
        "--trials",
        "1",
        "--out",
        path_str(&dir.join("refused")),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("paper_50.band.toml") && stderr.contains("roundness_uncertainty_mm"),
        "{stderr}"
    );
    assert!(root().join("scenarios/paper_50.toml").exists());
}
