use std::path::{Path, PathBuf};

use super::*;
use crate::scenario::{Catalogue, PartTypeId};

fn smoke_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/smoke.toml")
}

fn smoke_text() -> String {
    std::fs::read_to_string(smoke_path()).expect("smoke scenario")
}

fn load(sets: &[&str]) -> Result<Scenario, ScenarioError> {
    let overrides: Vec<Override> = sets
        .iter()
        .map(|s| s.parse().expect("override syntax"))
        .collect();
    Scenario::from_toml_with(&smoke_text(), &smoke_path(), &overrides)
}

#[test]
fn values_parse_as_toml_or_else_as_text() {
    assert_eq!(parse_value("0.02"), toml::Value::Float(0.02));
    assert_eq!(parse_value(" 3 "), toml::Value::Integer(3));
    assert_eq!(parse_value("true"), toml::Value::Boolean(true));
    assert_eq!(
        parse_value("[0.07,0.08]"),
        toml::Value::Array(vec![toml::Value::Float(0.07), toml::Value::Float(0.08)])
    );
    assert_eq!(parse_value("\"a b\""), toml::Value::String("a b".into()));
    assert_eq!(parse_value("paper"), toml::Value::String("paper".into()));
}

#[test]
fn value_lists_split_outside_brackets_and_quotes() {
    assert_eq!(split_values("1,2, 3"), ["1", "2", "3"]);
    assert_eq!(
        split_values("[0.07,0.08],[0.1, 0.2]"),
        ["[0.07,0.08]", "[0.1, 0.2]"]
    );
    assert_eq!(split_values("\"a,b\",c"), ["\"a,b\"", "c"]);
    assert_eq!(split_values("0.5"), ["0.5"]);
}

#[test]
fn override_syntax_is_checked() {
    for bad in [
        "noise",
        "=1",
        "a..b=1",
        "bins[x].size_m=1",
        "bins[1.a=1",
        "a b=1",
        "a=",
    ] {
        assert!(bad.parse::<Override>().is_err(), "{bad:?}");
    }
    let o: Override = "part_types[5].grip_force_n = 40".parse().expect("syntax");
    assert_eq!(o.key, "part_types[5].grip_force_n");
    assert_eq!(o.value, toml::Value::Integer(40));
    assert!("a=1,,2".parse::<SweepAxis>().is_err());
}

#[test]
fn sections_keys_and_array_entries_are_overridden() {
    let base = load(&[]).expect("smoke loads");
    let s = load(&[
        "sensor.noise_sigma=0.02",
        "bottle.distance_range_m=[0.07,0.08]",
        "conveyor.speed_m_s=0.5",
        "part_types.axle_a20.grip_force_n=40",
        "part_types[1].grip_force_n=45.5",
        "bins[0].size_m=[0.25,0.22]",
        "seed=99",
    ])
    .expect("overridden smoke loads");
    assert_eq!(s.sensor.noise_sigma, 0.02);
    // The rest of the section the file leaves out keeps its defaults.
    assert_eq!(s.sensor.max_dirt, base.sensor.max_dirt);
    assert_eq!(s.bottle.distance_range_m, [0.07, 0.08]);
    assert_eq!(s.conveyor.speed_m_s, 0.5);
    assert_eq!(s.conveyor.width_m, base.conveyor.width_m);
    assert_eq!(Catalogue::of(&s).part(PartTypeId(0)).grip_force_n, 40.0);
    assert_eq!(Catalogue::of(&s).part(PartTypeId(1)).grip_force_n, 45.5);
    assert_eq!(
        Catalogue::of(&s).part(PartTypeId(5)).grip_force_n,
        Catalogue::of(&base).part(PartTypeId(5)).grip_force_n
    );
    assert_eq!(s.bins[0].size_m, [0.25, 0.22]);
    assert_eq!(s.seed, 99);
    // Nothing else moved.
    let mut back = s.clone();
    back.sensor = base.sensor.clone();
    back.bottle = base.bottle.clone();
    back.conveyor = base.conveyor.clone();
    back.part_types = base.part_types.clone();
    back.bins = base.bins.clone();
    back.seed = base.seed;
    assert_eq!(back, base);
}

#[test]
fn later_overrides_win() {
    let s = load(&["conveyor.speed_m_s=0.3", "conveyor.speed_m_s=0.2"]).expect("loads");
    assert_eq!(s.conveyor.speed_m_s, 0.2);
}

#[test]
fn a_bad_override_names_the_file_the_key_and_the_reason() {
    let cases: [(&[&str], &str, &str); 8] = [
        (
            &["sensor.noise_sigmaa=1"],
            "sensor.noise_sigmaa",
            "unknown field",
        ),
        (
            &["sensor.noise_sigma=loud"],
            "sensor.noise_sigma",
            "invalid type",
        ),
        (&["conveyor.speed_m_s=-1"], "conveyor.speed_m_s", "positive"),
        (
            &["conveyor.creep_speed_m_s=0"],
            "conveyor.creep_speed_m_s",
            "positive",
        ),
        (
            &[
                "conveyor.speed_m_s=0.3",
                "bottle.distance_range_m=[0.2,0.1]",
            ],
            "bottle.distance_range_m",
            "near <= far",
        ),
        (
            &["part_types[9].grip_force_n=40"],
            "part_types[9].grip_force_n",
            "no [9]",
        ),
        (
            &["part_types.axle_z99.grip_force_n=40"],
            "part_types.axle_z99.grip_force_n",
            "no entry named",
        ),
        (&["name.first=1"], "name.first", "not a table"),
    ];
    for (sets, key, reason) in cases {
        let error = load(sets).expect_err("must fail");
        assert_eq!(error.file, smoke_path(), "{sets:?}");
        assert_eq!(error.key, key, "{sets:?}: {error}");
        assert!(error.reason.contains(reason), "{sets:?}: {error}");
        assert!(error.reason.contains("--set"), "{sets:?}: {error}");
    }
}

#[test]
fn the_files_own_error_comes_before_the_overrides() {
    let text = smoke_text().replace("trials = 4", "trials = 0");
    let o: Override = "trials=3".parse().expect("syntax");
    let error = Scenario::from_toml_with(&text, &smoke_path(), &[o]).expect_err("file is bad");
    assert_eq!(error.key, "trials");
    assert!(!error.reason.contains("--set"), "{error}");
}

#[test]
fn the_grid_is_every_combination_last_axis_fastest() {
    let axes: Vec<SweepAxis> = ["a=1,2", "b.c=[1,2],[3,4],[5,6]"]
        .iter()
        .map(|t| t.parse().expect("axis"))
        .collect();
    let grid = sweep_grid(&axes);
    assert_eq!(grid.len(), 6);
    let text: Vec<String> = grid
        .iter()
        .map(|p| {
            p.iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect();
    assert_eq!(text[0], "a=1 b.c=[1, 2]");
    assert_eq!(text[1], "a=1 b.c=[3, 4]");
    assert_eq!(text[5], "a=2 b.c=[5, 6]");
    assert_eq!(sweep_grid(&[]), vec![Vec::<Override>::new()]);
}
