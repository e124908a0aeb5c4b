//! A camera leaning back along the belt (35° off vertical, 0.4 m above the station) can see a
//! standing bottle behind the part at the photo-eye and not the part. The cell then says so and
//! leaves the belt where it stopped; it used to jog the belt on as if the part were still
//! upstream of the view, and index it six times more, carrying it out of reach.

mod common;

use serde_json::Value;

#[test]
fn a_part_hidden_at_the_beam_is_reported_and_not_carried_away() {
    let dir = common::out_dir("hidden_at_beam", "leaning_back");
    // paper_50's trials 29, 32 and 47 on its seed put a standing bottle 0.12 m behind the part.
    let body = "name = \"leaning_back\"\n\n[camera]\nposition_m = [-0.2301, -0.45, 1.10]\n\
                look_at_m = [0.05, -0.45, 0.70]\n";
    let file = common::extending(&dir, "leaning_back", "paper_50.toml", body);
    let out = dir.join("out");
    let (_, stdout, stderr) = common::twincell(&[
        "run",
        common::path_str(&file),
        "--trials",
        "50",
        "--shard",
        "29/50",
        "--jobs",
        "1",
        "--out",
        common::path_str(&out),
    ]);
    let text = common::read(&out.join("trials.jsonl"));
    let record: Value = serde_json::from_str(text.trim()).expect("one record");
    assert_eq!(record["trial"], 29, "{stdout}{stderr}");
    assert_eq!(record["failure"], "not_detected", "{record}");
    let detail = record["detail"].as_str().unwrap_or_default();
    assert!(detail.contains("hidden from the camera"), "{detail}");
    // The belt stood: no jog, no indexing.
    assert_eq!(record["motion"]["phase_s"]["pass"], 0.0, "{record}");
}
