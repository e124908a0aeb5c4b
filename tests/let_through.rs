//! Letting the unpickable pass (issue 25, item 3): a part the planner finds no safe grasp for
//! is carried by the belt into the collector at its end; the trial ends `passed`, neither a
//! success nor a failure. And the `waste` and `collector` bin keys are validated.

mod common;

use std::path::Path;

use toml::{Table, Value};
use twincell::batch::{Outcome, Perception, TrialRecord, TrialRunner, trial_seed};
use twincell::scenario::Scenario;
use twincell::task::CellTrialRunner;

fn run(scenario: &Scenario, path: &Path, trials: u32) -> Vec<TrialRecord> {
    let runner = CellTrialRunner::new(scenario.clone(), path, Perception::Camera).expect("runner");
    (0..trials)
        .map(|i| runner.run_trial(i, trial_seed(scenario.seed, i)))
        .collect()
}

#[test]
fn an_unpickable_part_ends_passed_in_the_collector() {
    let path = common::scenario_path("suite/clutter.toml");
    // Without a waste bin the cell cannot clear a bottle that blocks every grasp, so such a part
    // is unpickable (with it, most are cleared and picked).
    let mut scenario = common::scenario("suite/clutter.toml");
    scenario.bins.retain(|b| !b.waste);
    assert!(scenario.bins.iter().any(|b| b.collector));
    let with = run(&scenario, &path, 6);
    // The same trials without the collector: the refusals stay failures.
    let mut bare = scenario.clone();
    bare.bins.retain(|b| !b.collector);
    let without = run(&bare, &path, 6);
    let mut passed = 0;
    for (a, b) in with.iter().zip(&without) {
        println!("trial {}: {:?} {:?}", a.trial, a.outcome, a.detail);
        let Some(pass) = &a.passed else {
            // Not let through: the collector changed nothing.
            assert_eq!(a.outcome, b.outcome, "trial {}", a.trial);
            assert_eq!(a.failure, b.failure, "trial {}", a.trial);
            continue;
        };
        passed += 1;
        assert_eq!(a.outcome, Outcome::Passed);
        assert_eq!(a.failure, None);
        assert_eq!(pass.collector, "collector");
        // The part truly rests in the collector, and the robot never touched a bottle.
        assert_eq!(a.placed_bin.as_deref(), Some("collector"));
        assert!(!a.distractor_touched && !a.distractor_picked);
        assert!(a.grasp.is_none(), "a passed part had a grasp planned");
        // Without a collector the same refusal fails the trial.
        assert_eq!(b.outcome, Outcome::Failure, "trial {}", a.trial);
        assert_eq!(b.failure, Some(pass.reason));
        let refusal = b.detail.as_deref().unwrap_or_default();
        assert_eq!(pass.detail, format!("unpickable: {refusal}"));
        assert_eq!(a.detail.as_deref(), Some(pass.detail.as_str()));
    }
    assert!(passed > 0, "no part of 6 clutter trials was let through");
}

/// paper_50 written out whole, with `extra` bins appended to its own.
fn with_bins(extra: &str) -> Table {
    let text = common::read(&common::scenario_path("paper_50.toml"));
    let mut table: Table = toml::from_str(&text).expect("TOML");
    let more: Table = toml::from_str(extra).expect("extra TOML");
    let Some(Value::Array(bins)) = table.get_mut("bins") else {
        panic!("no bins");
    };
    let Some(Value::Array(added)) = more.get("bins") else {
        panic!("no extra bins");
    };
    bins.extend(added.iter().cloned());
    table
}

fn load(table: &Table) -> Result<Scenario, String> {
    let text = toml::to_string(table).expect("serialise");
    Scenario::from_toml(&text, Path::new("edited.toml")).map_err(|e| e.to_string())
}

const WASTE: &str = r#"
[[bins]]
name = "waste"
floor_center_m = [0.45, -0.05, 0.50]
size_m = [0.20, 0.20]
waste = true
"#;

/// A collector whose opening spans `x0..x1` (m) and `y0..y1`, its floor at `z` with 0.2 m walls.
fn collector(x: [f64; 2], y: [f64; 2], z: f64) -> String {
    format!(
        "[[bins]]\nname = \"collector\"\nfloor_center_m = [{}, {}, {z}]\nsize_m = [{}, {}]\n\
         wall_height_m = 0.2\ncollector = true\n",
        (x[0] + x[1]) / 2.0,
        (y[0] + y[1]) / 2.0,
        x[1] - x[0],
        y[1] - y[0],
    )
}

#[test]
fn waste_bins_and_collectors_are_validated() {
    // paper_50's belt: x -0.8..0.8 (it runs towards +x), y -0.61..-0.29, top at z 0.70.
    let good = collector([0.78, 1.08], [-0.65, -0.25], 0.3);
    load(&with_bins(&format!("{WASTE}\n{good}"))).expect("a waste bin and a collector");
    let cases: Vec<(String, &str, &str)> = vec![
        (
            format!("{WASTE}\n{}", WASTE.replace("\"waste\"\n", "\"waste2\"\n")),
            "bins:",
            "at most one waste bin, got 2",
        ),
        (
            format!("{good}\n{}", good.replace("\"collector\"\n", "\"c2\"\n")),
            "bins:",
            "at most one collector bin, got 2",
        ),
        (
            WASTE.replace("waste = true", "waste = true\naccepts = [\"axle_a20\"]"),
            "bins[4].accepts",
            "accepts no type",
        ),
        (
            WASTE.replace("waste = true", "waste = true\ncollector = true"),
            "bins[4].waste",
            "at most one of",
        ),
        // Off the belt's end: a gap to fall through, the upstream end, beside the belt.
        (
            collector([0.85, 1.15], [-0.65, -0.25], 0.3),
            "bins[4].floor_center_m",
            "downstream end",
        ),
        (
            collector([-1.1, -0.78], [-0.65, -0.25], 0.3),
            "bins[4].floor_center_m",
            "downstream end",
        ),
        (
            collector([0.78, 1.08], [-0.45, -0.05], 0.3),
            "bins[4].size_m[1]",
            "whole width",
        ),
        // Its rim above the belt's top: the belt would push items into its wall.
        (
            collector([0.78, 1.08], [-0.65, -0.25], 0.6),
            "bins[4].floor_center_m[2]",
            "below the belt's top",
        ),
    ];
    for (extra, key, reason) in cases {
        let Err(message) = load(&with_bins(&extra)) else {
            panic!("accepted:\n{extra}");
        };
        assert!(message.starts_with("edited.toml: "), "{message}");
        assert!(message.contains(key), "{message} (wanted {key})");
        assert!(message.contains(reason), "{message} (wanted {reason})");
    }
}

#[test]
fn a_misplaced_collector_exits_2_naming_file_and_key() {
    let dir = common::out_dir("let_through", "misplaced");
    let file = dir.join("off_end.toml");
    let table = with_bins(&collector([0.85, 1.15], [-0.65, -0.25], 0.3));
    std::fs::write(&file, toml::to_string(&table).expect("TOML")).expect("write");
    let out = dir.join("out");
    let (code, _, stderr) = common::twincell(&[
        "run",
        common::path_str(&file),
        "--trials",
        "1",
        "--perception",
        "oracle",
        "--out",
        common::path_str(&out),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("off_end.toml"), "{stderr}");
    assert!(stderr.contains("bins[4].floor_center_m"), "{stderr}");
}
