//! Tubes taller than the fingers reach from the standard grasp height (the palm of the shipped
//! gripper stands 75 mm above the TCP, the TCP 23 mm above a tube's bottom): a user's catalogue of
//! them, at the gripper's default force, is gripped clear of the palm and held without sliding,
//! from a stopped belt and from a moving one.
//!
//! Gripped at the standard height, such a tube had the gripper's body pressed onto its top and
//! into the belt: a 100 mm, 1.09 kg tube slid 14 mm in the jaws during the lift from a stopped
//! belt and 25-27 mm (a failed trial) from a moving one.

mod common;

use std::path::Path;

use serde_json::Value;
use twincell::rng::SimRng;

/// A catalogue of `count` steel tubes 95-120 mm tall (bores 16-48 mm, outer/bore 1.25-1.7, walls
/// of 4 mm at least), drawn from `seed`, none with a grip force of its own; with their bins, as
/// TOML.
fn tall_catalogue(seed: u64, count: usize) -> String {
    let mut rng = SimRng::new(seed);
    let mut text = String::new();
    let mut names = Vec::new();
    for k in 0..count {
        // Bores spread over the range, each in its own band, so the types stay apart.
        let band = 32.0 / count as f64;
        let bore = 16.0 + band * k as f64 + rng.range(0.0, band * 0.5);
        let outer = (bore * rng.range(1.25, 1.7)).max(bore + 8.0).min(72.0);
        let height = rng.range(95.0, 120.0);
        let name = format!("tall_{k}");
        text += &format!(
            "[[part_types]]\nname = \"{name}\"\nbore_diameter_mm = {bore:.1}\n\
             outer_diameter_mm = {outer:.1}\nheight_mm = {height:.1}\n\n"
        );
        names.push(name);
    }
    let accepts: Vec<String> = names.iter().map(|n| format!("{n:?}")).collect();
    text += &format!(
        "[[bins]]\nname = \"good\"\nfloor_center_m = [0.08, 0.50, 0.50]\nsize_m = [0.30, 0.30]\n\
         accepts = [{}]\n\n[[bins]]\nname = \"reject\"\nfloor_center_m = [-0.50, 0.02, 0.50]\n\
         size_m = [0.30, 0.30]\nreject = true\n",
        accepts.join(", ")
    );
    text
}

/// Runs `body` over the shipped scenario `base` in oracle mode in `dir`; returns its records.
fn run(dir: &Path, base: &str, body: &str) -> Vec<Value> {
    let file = common::extending(dir, "tall", base, body);
    let out = dir.join("out");
    common::run_oracle(&file, &out);
    common::read(&out.join("trials.jsonl"))
        .lines()
        .map(|l| serde_json::from_str(l).expect("record"))
        .collect()
}

#[test]
fn tall_tubes_are_held_without_sliding_from_a_stopped_belt() {
    let dir = common::out_dir("tall_tubes", "stopped");
    let body = format!(
        "name = \"tall_stopped\"\ntrials = 12\n\n{}",
        tall_catalogue(95, 3)
    );
    let records = run(&dir, "paper_50.toml", &body);
    assert_eq!(records.len(), 12);
    for r in &records {
        let drift = r["motion"]["grip_drift_mm"].as_f64().unwrap_or(f64::NAN);
        assert_eq!(r["outcome"], "success", "{r}");
        assert!(drift <= 5.0, "trial {}: drift {drift} mm", r["trial"]);
    }
}

#[test]
fn tall_tubes_are_held_without_sliding_from_a_moving_belt() {
    let dir = common::out_dir("tall_tubes", "moving");
    let body = format!(
        "name = \"tall_moving\"\ntrials = 3\nparts_per_trial = 5\n\n\
         [conveyor]\ntracking = true\n\n{}",
        tall_catalogue(120, 3)
    );
    let records = run(&dir, "stream.toml", &body);
    assert_eq!(records.len(), 3);
    let mut parts = 0;
    for r in &records {
        assert_eq!(r["outcome"], "success", "{r}");
        for part in r["stream"]["parts"].as_array().expect("parts") {
            let drift = part["tracking"]["jaw_drift_mm"]
                .as_f64()
                .unwrap_or(f64::NAN);
            assert!(drift <= 5.0, "trial {}: drift {drift} mm", r["trial"]);
            parts += 1;
        }
    }
    assert_eq!(parts, 15);
}
