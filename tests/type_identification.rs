//! Naming a part's type by measurement, over the whole family of tubes the cell is for (bores
//! 8-90 mm, outer/bore 1.15-3, heights 30-120 mm, 1-10 types, cameras 0.35-1.2 m above the
//! belt): every catalogue that validation accepts names each of its types from any reading
//! within the tolerance, and every catalogue it refuses has a reading that fits two types.
//! Also the scenario side: one type is a catalogue, two alike are refused naming both.

mod common;

use std::path::Path;

use toml::{Table, Value};
use twincell::perception::identify::{SizeReading, TypeCall, TypeSize, identify};
use twincell::rng::SimRng;
use twincell::scenario::{Scenario, SizedType, first_confusion};

/// A drawn catalogue and the camera's depth to each type's end face.
fn draw_catalogue(rng: &mut SimRng) -> Vec<SizedType> {
    let count = 1 + rng.below(10) as usize;
    let camera_above_belt_m = rng.range(0.35, 1.2);
    // Half the catalogues keep the default tolerance, half set their own.
    let tolerance_mm = if rng.uniform() < 0.5 {
        1.0
    } else {
        rng.range(0.1, 3.0)
    };
    (0..count)
        .map(|_| {
            let bore_mm = rng.range(8.0, 90.0);
            let height_m = rng.range(0.030, 0.120);
            SizedType {
                bore_mm,
                outer_mm: bore_mm * rng.range(1.15, 3.0),
                tolerance_mm,
                depth_m: camera_above_belt_m - height_m,
            }
        })
        .collect()
}

fn sizes(types: &[SizedType]) -> Vec<TypeSize> {
    types
        .iter()
        .map(|t| TypeSize {
            bore_m: t.bore_mm / 1e3,
            outer_m: t.outer_mm / 1e3,
            tolerance_m: t.tolerance_mm / 1e3,
        })
        .collect()
}

/// The end face of a part of type `truth` read as `[bore, outer]` mm on its own plane, read
/// on every type's plane (the image is the same; the scale goes as the plane's depth).
fn readings(types: &[SizedType], truth: usize, on_own_plane_mm: [f64; 2]) -> Vec<SizeReading> {
    types
        .iter()
        .map(|t| {
            let k = t.depth_m / types[truth].depth_m;
            SizeReading {
                bore_m: on_own_plane_mm[0] * k / 1e3,
                outer_m: Some(on_own_plane_mm[1] * k / 1e3),
            }
        })
        .collect()
}

/// The middle of the overlap of `[a - ta, a + ta]` and `[b - tb, b + tb]`.
fn overlap_middle(a: f64, ta: f64, b: f64, tb: f64) -> f64 {
    ((a - ta).max(b - tb) + (a + ta).min(b + tb)) / 2.0
}

#[test]
fn drawn_catalogues_name_every_type_or_are_refused_with_a_reading_that_fits_two() {
    let mut rng = SimRng::new(24);
    let (mut separable, mut refused, mut checked_readings) = (0, 0, 0);
    for _ in 0..3000 {
        let types = draw_catalogue(&mut rng);
        let sizes = sizes(&types);
        match first_confusion(&types) {
            None => {
                separable += 1;
                for (truth, t) in types.iter().enumerate() {
                    for draw in 0..8 {
                        // Errors anywhere inside the tolerance, the corners included.
                        let mut error = || match draw {
                            0 => 0.0,
                            1 | 2 => {
                                if draw == 1 {
                                    0.999
                                } else {
                                    -0.999
                                }
                            }
                            _ => rng.range(-0.999, 0.999),
                        };
                        let (eb, eo) = (error(), error());
                        let read = [
                            t.bore_mm + eb * t.tolerance_mm,
                            t.outer_mm + eo * t.tolerance_mm,
                        ];
                        let call = identify(&sizes, &readings(&types, truth, read));
                        assert_eq!(call, TypeCall::Identified(truth), "{types:?} {read:?}");
                        checked_readings += 1;
                    }
                }
            }
            Some(c) => {
                refused += 1;
                let (a, b) = (&types[c.first], &types[c.second]);
                let k = b.depth_m / a.depth_m;
                // A reading on a's plane within a's tolerance that is within b's on b's plane.
                let read = [
                    overlap_middle(a.bore_mm, a.tolerance_mm, b.bore_mm / k, b.tolerance_mm / k),
                    overlap_middle(
                        a.outer_mm,
                        a.tolerance_mm,
                        b.outer_mm / k,
                        b.tolerance_mm / k,
                    ),
                ];
                let call = identify(&sizes, &readings(&types, c.first, read));
                let TypeCall::Ambiguous(fitting) = call else {
                    panic!("{types:?}: {c:?} but {read:?} gives {call:?}");
                };
                assert!(fitting.contains(&c.first) && fitting.contains(&c.second));
                assert!(c.gaps_mm[0] <= c.needed_mm && c.gaps_mm[1] <= c.needed_mm);
            }
        }
        // A reading far outside every type fits none.
        let far = [200.0, 300.0];
        assert!(matches!(
            identify(&sizes, &readings(&types, 0, far)),
            TypeCall::NoFit { .. }
        ));
    }
    eprintln!(
        "{separable} catalogues separable ({checked_readings} readings named right), {refused} refused"
    );
    // The draw covers both outcomes.
    assert!(separable > 1000 && refused > 100, "{separable} {refused}");
}

#[test]
fn a_reading_outside_the_tolerance_is_not_named_that_type() {
    let mut rng = SimRng::new(240);
    for _ in 0..2000 {
        let types = draw_catalogue(&mut rng);
        let sizes = sizes(&types);
        let truth = rng.below(types.len() as u64) as usize;
        let t = &types[truth];
        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
        let off = t.tolerance_mm * rng.range(1.001, 3.0) * sign;
        let read = if rng.uniform() < 0.5 {
            [t.bore_mm + off, t.outer_mm]
        } else {
            [t.bore_mm, t.outer_mm + off]
        };
        let call = identify(&sizes, &readings(&types, truth, read));
        assert_ne!(call, TypeCall::Identified(truth), "{types:?} {read:?}");
        if let TypeCall::Ambiguous(fitting) = call {
            assert!(!fitting.contains(&truth));
        }
    }
}

/// The paper's scenario as a TOML table, with its catalogue replaced by `types`
/// (name, bore, outer, height).
fn with_types(types: &[(&str, f64, f64, f64)]) -> Table {
    let text = common::read(&common::scenario_path("paper_50.toml"));
    let mut table: Table = toml::from_str(&text).expect("TOML");
    let parts = types
        .iter()
        .map(|(name, bore, outer, height)| {
            let mut t = Table::new();
            t.insert("name".into(), Value::String((*name).into()));
            t.insert("bore_diameter_mm".into(), Value::Float(*bore));
            t.insert("outer_diameter_mm".into(), Value::Float(*outer));
            t.insert("height_mm".into(), Value::Float(*height));
            Value::Table(t)
        })
        .collect();
    table.insert("part_types".into(), Value::Array(parts));
    // One bin takes every accepted type.
    let Some(Value::Array(bins)) = table.get_mut("bins") else {
        panic!("bins");
    };
    let names: Vec<Value> = types.iter().map(|t| Value::String(t.0.into())).collect();
    for bin in bins.iter_mut() {
        if let Value::Table(bin) = bin
            && bin.contains_key("accepts")
        {
            bin.insert("accepts".into(), Value::Array(Vec::new()));
        }
    }
    if let Some(Value::Table(first)) = bins.iter_mut().find(
        |b| matches!(b, Value::Table(t) if t.get("reject").and_then(Value::as_bool) != Some(true)),
    ) {
        first.insert("accepts".into(), Value::Array(names));
    }
    table
}

fn load(table: &Table) -> Result<Scenario, String> {
    let text = toml::to_string(table).expect("serialise");
    Scenario::from_toml(&text, Path::new("own.toml")).map_err(|e| e.to_string())
}

#[test]
fn one_type_is_a_catalogue_and_two_alike_are_refused_naming_both_and_the_margin() {
    let one = load(&with_types(&[("hub_16", 16.0, 30.0, 60.0)]));
    assert!(one.is_ok(), "{one:?}");
    let err = load(&with_types(&[
        ("hub_16", 16.0, 30.0, 60.0),
        ("hub_16b", 16.5, 30.5, 60.0),
    ]))
    .expect_err("alike types");
    assert!(err.contains("own.toml"), "{err}");
    assert!(err.contains("part_types"), "{err}");
    assert!(
        err.contains("\"hub_16\"") && err.contains("\"hub_16b\""),
        "{err}"
    );
    assert!(err.contains("more than 2.00 mm"), "{err}");
    // The same sizes with a tolerance tight enough are told apart.
    let mut tight = with_types(&[("hub_16", 16.0, 30.0, 60.0), ("hub_16b", 16.5, 30.5, 60.0)]);
    if let Some(Value::Array(parts)) = tight.get_mut("part_types") {
        for part in parts.iter_mut() {
            if let Value::Table(part) = part {
                part.insert("diameter_tolerance_mm".into(), Value::Float(0.2));
            }
        }
    }
    assert!(load(&tight).is_ok());
}

#[test]
fn a_tolerance_outside_its_range_and_the_reserved_name_are_refused() {
    let mut table = with_types(&[("hub_16", 16.0, 30.0, 60.0)]);
    if let Some(Value::Array(parts)) = table.get_mut("part_types")
        && let Some(Value::Table(part)) = parts.first_mut()
    {
        part.insert("diameter_tolerance_mm".into(), Value::Float(0.01));
    }
    let err = load(&table).expect_err("tiny tolerance");
    assert!(err.contains("part_types[0].diameter_tolerance_mm"), "{err}");
    let err = load(&with_types(&[("unidentified", 16.0, 30.0, 60.0)])).expect_err("name");
    assert!(err.contains("part_types[0].name"), "{err}");
}

/// The tube family starts at 30 mm tall (the detector's training family); shorter is refused,
/// naming the key.
#[test]
fn tubes_from_30_mm_tall_are_a_catalogue_and_shorter_ones_are_refused() {
    for height in [30.0, 31.5, 120.0] {
        let loaded = load(&with_types(&[("ring", 12.0, 30.0, height)]));
        assert!(loaded.is_ok(), "{height} mm: {loaded:?}");
    }
    for height in [29.9, 20.0] {
        let err = load(&with_types(&[("ring", 12.0, 30.0, height)])).expect_err("too short");
        assert!(
            err.contains("part_types[0].height_mm"),
            "{height} mm: {err}"
        );
        assert!(err.contains("[30, 200]"), "{height} mm: {err}");
    }
}

#[test]
fn the_paper_catalogue_is_told_apart_and_type_by_defaults_to_measurement() {
    let paper = common::paper_50();
    assert!(first_confusion(&paper.sized_types()).is_none());
    assert_eq!(
        paper.perception.type_by,
        twincell::scenario::TypeBy::Measurement
    );
    let mut table = with_types(&[("hub_16", 16.0, 30.0, 60.0)]);
    let mut perception = Table::new();
    perception.insert("type_by".into(), Value::String("detector".into()));
    table.insert("perception".into(), Value::Table(perception.clone()));
    assert_eq!(
        load(&table).map(|s| s.perception.type_by),
        Ok(twincell::scenario::TypeBy::Detector)
    );
    perception.insert("type_by".into(), Value::String("colour".into()));
    table.insert("perception".into(), Value::Table(perception));
    let err = load(&table).expect_err("unknown way");
    assert!(err.contains("type_by") || err.contains("colour"), "{err}");
}

/// A user's catalogue of own tube sizes the shipped detector was never trained on, run for real
/// in camera mode: the detector only has to find the tubes, the measurement names them. What it
/// must never do is name a wrong type; a part it cannot name goes to reject as `unidentified`.
/// The figures (success, unidentified, not detected) are printed, not tuned: over 50 trials on
/// seeds 731 and 1024 this catalogue scored 50/50 (docs/type-identification.md).
#[test]
fn a_catalogue_of_own_sizes_is_sorted_by_measurement_with_the_shipped_detector() {
    let scenario = common::root().join("tests/data/own_catalogues/own_wide_spread.toml");
    let scenario = scenario.to_str().expect("path");
    let out = common::out_dir("type_identification", "own_wide_spread");
    let out_str = out.to_str().expect("path");
    let (code, stdout, stderr) = common::twincell(&[
        "run", scenario, "--trials", "6", "--seed", "1024", "--jobs", "2", "--out", out_str,
    ]);
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    let records = common::read(&out.join("trials.jsonl"));
    let mut decided = 0;
    for line in records.lines() {
        let record: serde_json::Value = serde_json::from_str(line).expect("JSON line");
        let truth = record["part"]["part_type"].as_str().expect("a part");
        let Some(detected) = record["decision"]["detected_type"].as_str() else {
            continue;
        };
        decided += 1;
        assert!(
            detected == truth || detected == "unidentified",
            "a {truth} was named {detected}: {record}"
        );
    }
    let report: serde_json::Value =
        serde_json::from_str(&common::read(&out.join("report.json"))).expect("report");
    eprintln!(
        "own_wide_spread, 6 camera trials: {} successes, {} decided, {} unidentified",
        report["successes"], decided, report["sorting"]["unidentified"]
    );
    assert!(report["sorting"]["unidentified"].is_u64());
    // The paper's way cannot serve this catalogue: the detector has no class for its types.
    let (code, _, stderr) = common::twincell(&[
        "run",
        scenario,
        "--trials",
        "1",
        "--set",
        "perception.type_by=detector",
        "--out",
        out_str,
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("is not a class of the detector model"),
        "{stderr}"
    );
}

/// A user's camera that images the catalogue's smallest bores below the bore finder's default
/// floor (a 10-12 mm bore at about 8-10 frame px of radius): the station's floor comes from the
/// catalogue as that camera images it, so every sleeve is measured and named, none goes to
/// reject unidentified (on main before, 17 of 20 trials did, and their off-centre grasps
/// slipped). Over 20 trials, seed 5150: 19/20, the one failure a part inside the coarse
/// camera's measurement error of the tolerance (docs/type-identification.md).
#[test]
fn small_bores_on_a_far_coarse_camera_are_measured_and_named() {
    let (code, records) = run_catalogue("small_bores_far_camera", 6);
    assert!(code == 0 || code == 1, "{records:?}");
    let mut sleeves = 0;
    for record in &records {
        let truth = record["part"]["part_type"].as_str().expect("a part");
        let detected = record["decision"]["detected_type"].as_str();
        assert_eq!(detected, Some(truth), "{record}");
        sleeves += usize::from(truth.starts_with("sleeve"));
    }
    assert!(
        sleeves >= 2,
        "the draw holds {sleeves} sleeves: {records:?}"
    );
}

/// Rings 30-36 mm tall, the family's shortest (the scenario file's own catalogue), are named by
/// measurement and sorted, each held by the 22-28 mm of its side the pads reach, by friction:
/// 50/50 over 50 camera trials on seed 11, 20/20 on the file's seed (docs/type-identification.md).
#[test]
fn rings_30_mm_tall_are_named_picked_and_sorted() {
    let (code, records) = run_catalogue("short_rings", 4);
    assert_eq!(code, 0, "{records:?}");
    for record in &records {
        let truth = record["part"]["part_type"].as_str().expect("a part");
        assert_eq!(record["outcome"], "success", "{record}");
        assert_eq!(
            record["decision"]["detected_type"].as_str(),
            Some(truth),
            "{record}"
        );
    }
    assert_eq!(records.len(), 4, "{records:?}");
}

/// Runs `trials` camera trials of `tests/data/own_catalogues/NAME.toml` on its own seed: the
/// exit code and the records.
fn run_catalogue(name: &str, trials: u32) -> (i32, Vec<serde_json::Value>) {
    let scenario = common::root().join(format!("tests/data/own_catalogues/{name}.toml"));
    let scenario = scenario.to_str().expect("path");
    let out = common::out_dir("type_identification", name);
    let out_str = out.to_str().expect("path");
    let trials = trials.to_string();
    let (code, stdout, stderr) = common::twincell(&[
        "run", scenario, "--trials", &trials, "--jobs", "2", "--out", out_str,
    ]);
    assert!(code == 0 || code == 1, "{stdout}\n{stderr}");
    let records = common::read(&out.join("trials.jsonl"))
        .lines()
        .map(|line| serde_json::from_str(line).expect("JSON line"))
        .collect();
    (code, records)
}
