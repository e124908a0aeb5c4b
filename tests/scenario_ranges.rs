//! Physically absurd scenario values (a belt at 1e308 m/s, a bin 1 km wide) are refused with
//! the file, the key and the allowed range; the shipped values stay accepted.

mod common;

use std::path::Path;

use toml::{Table, Value};
use twincell::scenario::Scenario;

/// The smoke cell written out whole: the paper's file with smoke.toml's own keys.
fn smoke() -> Table {
    let text = common::read(&common::scenario_path("paper_50.toml"));
    let mut table: Table = toml::from_str(&text).expect("TOML");
    table.insert("name".into(), Value::String("smoke".into()));
    table.insert("seed".into(), Value::Integer(7));
    table.insert("trials".into(), Value::Integer(4));
    table
}

/// The value at a dotted `key` (`conveyor.speed_m_s`, `bins[1].size_m[0]`), created if missing.
fn slot<'a>(table: &'a mut Table, key: &str) -> &'a mut Value {
    let mut parts = key.split('.');
    let first = parts.next().expect("key");
    let mut value = entry(table, first);
    for part in parts {
        let Value::Table(inner) = value else {
            panic!("{key}: not a table")
        };
        value = entry(inner, part);
    }
    value
}

/// `name` or `name[i]` or `name[i][j]` inside `table`.
fn entry<'a>(table: &'a mut Table, part: &str) -> &'a mut Value {
    let mut pieces = part.split('[');
    let name = pieces.next().expect("name");
    let mut value = table
        .entry(name)
        .or_insert_with(|| Value::Table(Table::new()));
    for index in pieces {
        let index: usize = index.trim_end_matches(']').parse().expect("index");
        let Value::Array(items) = value else {
            panic!("{part}: not an array")
        };
        value = &mut items[index];
    }
    value
}

fn load(table: &Table) -> Result<Scenario, String> {
    let text = toml::to_string(table).expect("serialise");
    Scenario::from_toml(&text, Path::new("edited.toml")).map_err(|e| e.to_string())
}

/// Every bounded key with its accepted range `[low, high]` (low exclusive when `open`).
const RANGES: &[(&str, f64, f64, bool)] = &[
    ("conveyor.speed_m_s", 0.0, 5.0, true),
    ("conveyor.length_m", 0.0, 50.0, true),
    ("conveyor.width_m", 0.0, 2.0, true),
    ("conveyor.friction", 0.0, 5.0, true),
    ("conveyor.spawn_upstream_m", 0.0, 50.0, true),
    ("conveyor.belt_center_m[0]", -10.0, 10.0, false),
    ("robot.base_xyz_m[1]", -10.0, 10.0, false),
    ("robot.pedestal_side_m", 0.0, 2.0, true),
    ("gripper.pad_friction", 0.0, 5.0, true),
    ("gripper.pad_preslide_mm", 0.0, 5.0, false),
    ("roundness_tolerance_mm", 0.0, 5.0, true),
    ("part_types[2].bore_diameter_mm", 0.0, 100.0, true),
    ("part_types[0].outer_diameter_mm", 0.0, 100.0, true),
    ("part_types[5].density_kg_m3", 100.0, 25_000.0, false),
    ("bottle.radius_m", 0.0, 0.2, true),
    ("bottle.height_m", 0.0, 0.5, true),
    ("bottle.mass_kg", 0.0, 5.0, true),
    ("bins[1].size_m[0]", 0.0, 2.0, true),
    ("bins[3].wall_height_m", 0.0, 1.0, true),
    ("bins[0].floor_center_m[2]", -10.0, 10.0, false),
    ("task.wait_timeout_s", 0.0, 3600.0, true),
    ("task.trial_timeout_s", 0.0, 86_400.0, true),
    ("task.slip_tolerance_m", 0.0, 1.0, true),
    ("task.bottle_tolerance_m", 0.0, 1.0, true),
    ("camera.position_m[2]", -10.0, 10.0, false),
    ("min_success", 0.0, 1.0, false),
];

#[test]
fn absurd_values_are_refused_with_key_and_range() {
    let base = smoke();
    load(&base).expect("smoke.toml is valid");
    for &(key, low, high, _) in RANGES {
        let range = format!("{high}]");
        let absurd = [
            1e308,
            -1e308,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            high * (1.0 + 1e-9) + 1e-9,
            low - 1.0,
        ];
        for value in absurd {
            let mut table = base.clone();
            if key.starts_with("camera.position_m") {
                // The camera's position is optional: give all of it, sensible but for one axis.
                *slot(&mut table, "camera.position_m") =
                    Value::Array([0.05, -0.45, 1.28].into_iter().map(Value::Float).collect());
            }
            *slot(&mut table, key) = Value::Float(value);
            let err = load(&table).expect_err(&format!("{key} = {value} was accepted"));
            // A point is named whole (`conveyor.belt_center_m`), a size by its element.
            let named = key.strip_suffix(']').map_or(key, |k| {
                if err.contains(&format!("{k}]")) {
                    key
                } else {
                    k.rsplit_once('[').map_or(k, |(whole, _)| whole)
                }
            });
            assert!(
                err.starts_with(&format!("edited.toml: {named}: must ")),
                "{key} = {value}: {err}"
            );
            assert!(err.contains(&range), "{key} = {value}: {err}");
        }
    }
}

#[test]
fn the_error_for_a_fast_belt_gives_the_range() {
    let mut table = smoke();
    *slot(&mut table, "conveyor.speed_m_s") = Value::Float(1e308);
    let err = load(&table).expect_err("accepted");
    assert_eq!(
        err,
        "edited.toml: conveyor.speed_m_s: must be a positive number in (0, 5], got 1e308"
    );
}

#[test]
fn values_inside_the_ranges_are_accepted() {
    let base = smoke();
    // A sensible in-range value for each key that the rest of the smoke cell still allows.
    let fine: &[(&str, f64)] = &[
        ("conveyor.speed_m_s", 4.9),
        ("conveyor.friction", 5.0),
        ("gripper.pad_friction", 0.05),
        ("part_types[5].density_kg_m3", 19_300.0),
        ("bottle.mass_kg", 5.0),
        ("task.trial_timeout_s", 86_400.0),
        ("roundness_tolerance_mm", 5.0),
        ("min_success", 1.0),
        ("min_success", 0.0),
    ];
    for &(key, value) in fine {
        let mut table = base.clone();
        *slot(&mut table, key) = Value::Float(value);
        load(&table).unwrap_or_else(|e| panic!("{key} = {value}: {e}"));
    }
}

fn ints(values: &[i64]) -> Value {
    Value::Array(values.iter().map(|&v| Value::Integer(v)).collect())
}

fn floats(values: &[f64]) -> Value {
    Value::Array(values.iter().map(|&v| Value::Float(v)).collect())
}

#[test]
fn bottle_counts_outside_one_to_eight_are_refused_with_the_range() {
    let base = smoke();
    for bad in [
        [0, 0],
        [0, 2],
        [3, 2],
        [1, 9],
        [9, 9],
        [-1, 2],
        [i64::MIN, i64::MAX],
    ] {
        let mut table = base.clone();
        *slot(&mut table, "bottle.count_range") = ints(&bad);
        let err = load(&table).expect_err(&format!("count_range {bad:?} was accepted"));
        assert!(
            err.starts_with("edited.toml: bottle.count_range: must be [fewest, most] with 1 <= fewest <= most <= 8"),
            "{bad:?}: {err}"
        );
    }
    for fine in [[1, 1], [2, 3], [1, 8], [8, 8]] {
        let mut table = base.clone();
        *slot(&mut table, "bottle.count_range") = ints(&fine);
        let scenario = load(&table).unwrap_or_else(|e| panic!("{fine:?}: {e}"));
        assert_eq!(scenario.bottle.count_range, fine);
    }
}

#[test]
fn near_gaps_outside_zero_to_half_a_metre_are_refused_with_the_range() {
    let base = smoke();
    let absurd = [
        [-0.001, 0.01],
        [0.02, 0.01],
        [0.0, 0.5 + 1e-9],
        [0.0, f64::INFINITY],
        [f64::NAN, 0.01],
        [0.0, -1e308],
        [1e308, 1e308],
    ];
    for bad in absurd {
        let mut table = base.clone();
        *slot(&mut table, "bottle.near_gap_range_m") = floats(&bad);
        let err = load(&table).expect_err(&format!("near_gap_range_m {bad:?} was accepted"));
        assert!(
            err.starts_with(
                "edited.toml: bottle.near_gap_range_m: must be [least, most] with 0 <= least <= most <= 0.5 m"
            ),
            "{bad:?}: {err}"
        );
    }
    for fine in [[0.0, 0.0], [0.0, 0.01], [0.3, 0.5]] {
        let mut table = base.clone();
        *slot(&mut table, "bottle.near_gap_range_m") = floats(&fine);
        let scenario = load(&table).unwrap_or_else(|e| panic!("{fine:?}: {e}"));
        assert_eq!(scenario.bottle.near_gap_range_m, Some(fine));
    }
    // How many bottles stand near: from 1 to the fewest of count_range.
    for (count, bad) in [
        ([1, 1], 2),
        ([2, 3], 3),
        ([3, 3], 0),
        ([4, 6], -1),
        ([1, 2], i64::MAX),
    ] {
        let mut table = base.clone();
        *slot(&mut table, "bottle.count_range") = ints(&count);
        *slot(&mut table, "bottle.near_count") = Value::Integer(bad);
        let err = load(&table).expect_err(&format!("near_count {bad} of {count:?} was accepted"));
        let want = format!(
            "edited.toml: bottle.near_count: must lie in [1, {}] (bottle.count_range's fewest), got {bad}",
            count[0]
        );
        assert!(err.starts_with(&want), "{bad}: {err}");
    }
    for (count, fine) in [([1, 1], 1), ([2, 3], 2), ([4, 6], 3)] {
        let mut table = base.clone();
        *slot(&mut table, "bottle.count_range") = ints(&count);
        *slot(&mut table, "bottle.near_count") = Value::Integer(fine);
        let scenario = load(&table).unwrap_or_else(|e| panic!("{fine}: {e}"));
        assert_eq!(scenario.bottle.near_count, fine);
    }
    // Unset, the paper's one bottle keeps its centre distance.
    let scenario = load(&base).expect("smoke");
    assert_eq!(scenario.bottle.near_count, 1);
    assert_eq!(scenario.bottle.near_gap_range_m, None);
    assert_eq!(scenario.bottle.count_range, [1, 1]);
}
