//! A part picked from a held tracking belt near the window's start: the arm's way down to it
//! passes over the belt behind it, where items that came into view after the part's own look
//! stand. The cell looks at the stood belt before it picks and keeps clear of every item its
//! tracks hold there.
//!
//! Without the look, a user's stream (three types of their own, up to 100 mm tall, 0.4 m/s,
//! 0.4 m apart, two bottles in eight items) lost one of eight streams in camera mode (seed 731,
//! stream 3: a 100 mm tube standing upstream knocked over, later gripped off its axis, slid 27
//! mm in the jaws) and one in oracle mode (seed 1024, stream 3: a bottle upstream touched).

mod common;

use serde_json::Value;

/// The user's stream: the shipped stream, their own three types and bins, a camera tilted off
/// the belt, the belt picked from while it runs at 0.4 m/s with items 0.4 m apart.
const USER_STREAM: &str = r#"
trials = 4
[conveyor]
tracking = true
speed_m_s = 0.4
[stream]
spacing_m = 0.4
bottles = 2
[camera]
position_m = [0.30, -0.60, 1.25]
look_at_m = [0.05, -0.45, 0.70]
[[part_types]]
name = "hub_16"
bore_diameter_mm = 16.0
outer_diameter_mm = 30.0
height_mm = 45.0
[[part_types]]
name = "hub_40"
bore_diameter_mm = 40.0
outer_diameter_mm = 58.0
height_mm = 100.0
[[part_types]]
name = "sleeve_60"
bore_diameter_mm = 60.0
outer_diameter_mm = 72.0
height_mm = 50.0
[[bins]]
name = "small"
floor_center_m = [0.42, 0.24, 0.50]
size_m = [0.30, 0.30]
accepts = ["hub_16"]
[[bins]]
name = "big"
floor_center_m = [0.08, 0.50, 0.50]
size_m = [0.30, 0.30]
accepts = ["hub_40", "sleeve_60"]
[[bins]]
name = "reject"
floor_center_m = [-0.50, 0.02, 0.50]
size_m = [0.30, 0.30]
reject = true
"#;

#[test]
fn nothing_upstream_of_a_part_on_a_held_belt_is_touched() {
    for seed in [731, 1024] {
        let dir = common::out_dir("held_belt", &format!("seed_{seed}"));
        let body = format!("seed = {seed}\n{USER_STREAM}");
        let file = common::extending(&dir, "user_stream", "stream.toml", &body);
        let out = dir.join("out");
        common::run_oracle(&file, &out);
        let records: Vec<Value> = common::read(&out.join("trials.jsonl"))
            .lines()
            .map(|l| serde_json::from_str(l).expect("record"))
            .collect();
        assert_eq!(records.len(), 4);
        for r in &records {
            let stream = &r["stream"];
            assert_eq!(r["outcome"], "success", "seed {seed}: {}", r["detail"]);
            assert_eq!(stream["parts_sorted"], 8, "seed {seed}: {}", r["detail"]);
            assert_eq!(r["distractor_touched"], false, "seed {seed}");
            assert!(
                stream["belt_stops"].as_u64().is_some_and(|n| n > 0),
                "a held belt"
            );
        }
    }
}
