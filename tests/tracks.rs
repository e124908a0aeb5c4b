//! Every item tracked on the belt (issue 25, item 4): tracks keep each item's identity from look
//! to look over belt speeds, spacings, look rates, noise, missed looks and false sightings drawn
//! over a wide range; the feeder hands items over at the belt's speed, so a fast belt does not
//! kick them over; and in a fast, crowded stream the cell knows each item at the station, and
//! what reaches the collector, by its track.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use twincell::batch::{Outcome, Perception, TrialRecord, TrialRunner, trial_seed};
use twincell::cell::{Cell, CellModel};
use twincell::control::{BeltDrive, ENCODER_M_PER_COUNT};
use twincell::rng::SimRng;
use twincell::scenario::{Bin, Scenario};
use twincell::station::{
    BeltPoint, ItemKind, ItemSighting, TrackEnd, TrackId, TrackSet, TrackerParams, ViewSpan,
};
use twincell::task::CellTrialRunner;

/// One drawn stream seen by a drawn camera: items a drawn spacing apart, carried by a belt whose
/// travel between looks is drawn (stops included), each look seeing the items in view with
/// noise, missing some (never one item twice in a row: the tracker's allowance) and adding
/// false sightings. Checks that every item keeps one track and
/// no two items share one; returns the number of looks.
fn one_drawn_stream(rng: &mut SimRng) -> usize {
    let spacing_m = rng.range(0.08, 0.6);
    let gate_m = (0.4 * spacing_m).min(0.08);
    let noise_m = gate_m * rng.range(0.0, 0.3);
    let view = ViewSpan {
        from_m: -rng.range(0.15, 0.5),
        to_m: rng.range(0.15, 0.5),
    };
    let mut tracks = TrackSet::new(TrackerParams {
        m_per_count: ENCODER_M_PER_COUNT,
        gate_m,
        max_missed_looks: 1,
    });
    let items = 3 + rng.below(8) as usize;
    // Each item's place at belt travel 0 (the first enters the view at the first look), its
    // lateral offset and kind.
    let start: Vec<(f64, f64, ItemKind)> = (0..items)
        .map(|i| {
            let kind = if rng.uniform() < 0.3 {
                ItemKind::Bottle
            } else {
                ItemKind::Part
            };
            (
                view.from_m + 0.01 - i as f64 * spacing_m,
                rng.range(-0.12, 0.12),
                kind,
            )
        })
        .collect();
    let (mut travel_m, mut looks) = (0.0, 0);
    let width_m = view.to_m - view.from_m;
    // Looks in a row that missed each item in view: at most the one the tracker allows.
    let mut missed = vec![0u32; items];
    let mut track_of: BTreeMap<usize, TrackId> = BTreeMap::new();
    let last_along = |travel: f64| start[items - 1].0 + travel;
    while last_along(travel_m) <= view.to_m + 0.2 {
        let count = (travel_m / ENCODER_M_PER_COUNT).floor() as i64;
        let mut sightings = Vec::new();
        let mut truth = Vec::new();
        for (i, &(along, across, kind)) in start.iter().enumerate() {
            let along_m = along + travel_m;
            if !view.contains(along_m) {
                continue;
            }
            if missed[i] == 0 && rng.uniform() < 0.15 {
                missed[i] += 1;
                continue;
            }
            missed[i] = 0;
            sightings.push(ItemSighting {
                kind,
                score: rng.range(0.5, 1.0),
                at: BeltPoint {
                    along_m: along_m + rng.range(-noise_m, noise_m),
                    across_m: across + rng.range(-noise_m, noise_m),
                },
                half_length_m: 0.02,
            });
            truth.push(Some(i));
        }
        // A false sighting, clear of every item by more than the gate.
        if rng.uniform() < 0.15 {
            let at = BeltPoint {
                along_m: rng.range(view.from_m, view.to_m),
                across_m: rng.range(-0.15, 0.15),
            };
            let clear = start.iter().all(|&(along, across, _)| {
                let item = BeltPoint {
                    along_m: along + travel_m,
                    across_m: across,
                };
                item.distance_m(&at) > 2.0 * gate_m + noise_m
            });
            if clear {
                sightings.push(ItemSighting {
                    kind: ItemKind::Bottle,
                    score: 0.4,
                    at,
                    half_length_m: 0.02,
                });
                truth.push(None);
            }
        }
        let ids = tracks.update(count, &sightings, &view);
        for (item, id) in truth.iter().zip(&ids) {
            let Some(item) = item else {
                assert!(
                    !track_of.values().any(|t| t == id),
                    "a false sighting joined an item's track"
                );
                continue;
            };
            let known = *track_of.entry(*item).or_insert(*id);
            assert_eq!(
                known, *id,
                "item {item} changed track (spacing {spacing_m:.3} m, gate {gate_m:.3} m)"
            );
        }
        looks += 1;
        // The belt's travel to the next look: a stop, or up to most of the gap between items
        // (a faster belt or a slower camera), each item staying in view for a few looks.
        travel_m += if rng.uniform() < 0.1 {
            0.0
        } else {
            rng.range(0.005, (0.9 * spacing_m).min(width_m / 3.0))
        };
    }
    let distinct: std::collections::BTreeSet<_> = track_of.values().collect();
    assert_eq!(distinct.len(), track_of.len(), "two items shared a track");
    assert_eq!(track_of.len(), items, "every item was seen");
    // Carried past the view, every item's track has closed.
    tracks.update(((travel_m + 1.0) / ENCODER_M_PER_COUNT) as i64, &[], &view);
    for id in track_of.values() {
        let end = tracks.track(*id).and_then(|t| t.end);
        assert_eq!(end, Some(TrackEnd::LeftView));
    }
    looks
}

#[test]
fn drawn_streams_keep_every_item_on_one_track() {
    let mut rng = SimRng::new(2025);
    let looks: usize = (0..300).map(|_| one_drawn_stream(&mut rng)).sum();
    assert!(looks > 3000, "{looks} looks");
}

#[test]
fn fed_items_stay_upright_on_a_fast_belt() {
    // Handed over at the belt's speed, slender tubes and standing bottles ride a belt from the
    // paper's 0.25 m/s to 1 m/s without tipping.
    for (k, speed_m_s) in [0.25, 0.5, 0.75, 1.0].into_iter().enumerate() {
        let mut scenario = common::paper_50();
        scenario.bottle.enabled = false;
        scenario.bottle.lying_fraction = 0.0;
        scenario.conveyor.speed_m_s = speed_m_s;
        scenario.conveyor.creep_speed_m_s = speed_m_s;
        let model = CellModel::with_urdf(scenario.clone(), None).expect("model");
        let mut rng = SimRng::new(70 + k as u64);
        let mut cell = Cell::build(&model, &mut rng).expect("cell builds");
        let dt = scenario.physics.dt_s;
        let mut drive = BeltDrive::default();
        drive.run_at(speed_m_s);
        let mut step = |cell: &mut Cell| {
            drive.advance(&cell.conveyor, dt);
            cell.step();
        };
        for _ in 0..240 {
            step(&mut cell);
        }
        for _ in 0..4 {
            cell.spawn_part(&model, &mut rng);
            for _ in 0..30 {
                step(&mut cell);
            }
            cell.spawn_bottle(&scenario, &mut rng);
            for _ in 0..30 {
                step(&mut cell);
            }
        }
        let fed = cell.items.parts()[1..]
            .iter()
            .map(|p| p.body)
            .chain(cell.items.bottles().iter().map(|b| b.body));
        for body in fed {
            let pose = cell.body_pose(body).expect("pose");
            let up = (pose.rotation * nalgebra::Vector3::z()).z;
            assert!(
                up > 0.98,
                "an item tipped at {speed_m_s} m/s (axis z {up:.3})"
            );
        }
    }
}

/// suite/fast_belt with a collector under the belt's end and two bottles a trial.
fn fast_belt_with_collector() -> Scenario {
    let mut scenario = common::scenario("suite/fast_belt.toml");
    scenario.stream.bottles = 2;
    scenario.bins.push(Bin {
        name: "collector".into(),
        floor_center_m: [0.93, -0.45, 0.30],
        size_m: [0.30, 0.40],
        wall_height_m: 0.20,
        accepts: Vec::new(),
        reject: false,
        waste: false,
        collector: true,
    });
    scenario
}

fn run(scenario: &Scenario, path: &Path, trials: u32) -> Vec<TrialRecord> {
    let runner = CellTrialRunner::new(scenario.clone(), path, Perception::Camera).expect("runner");
    (0..trials)
        .map(|i| runner.run_trial(i, trial_seed(scenario.seed, i)))
        .collect()
}

#[test]
fn a_fast_crowded_stream_knows_each_item_and_what_reached_the_collector_by_its_track() {
    let scenario = fast_belt_with_collector();
    let path = common::scenario_path("suite/fast_belt.toml");
    let records = run(&scenario, &path, 4);
    let mut collected = 0;
    for record in &records {
        println!(
            "trial {}: {:?} {:?}",
            record.trial, record.outcome, record.detail
        );
        let stream = record.stream.as_ref().expect("a stream record");
        assert_eq!(stream.misidentified, None, "trial {}", record.trial);
        assert_eq!(stream.misidentified_items(), 0, "trial {}", record.trial);
        // Every item at the station had its own track, parts and bottles alike.
        let mut ids: Vec<u32> = stream.parts.iter().filter_map(|p| p.track).collect();
        assert_eq!(ids.len(), stream.parts.len(), "a part without a track");
        ids.extend(&stream.passed_tracks);
        let mut unique = ids.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), ids.len(), "two items shared a track");
        assert!(ids.iter().all(|&id| id < stream.tracks_opened));
        if record.outcome != Outcome::Success {
            continue;
        }
        // What reached the collector is each bottle let through, by its own track.
        assert_eq!(stream.collected.len(), stream.passed_tracks.len());
        for item in &stream.collected {
            assert_eq!(item.truth, "bottle");
            assert_eq!(item.seen_as.as_deref(), Some("bottle"));
            assert!(
                item.track
                    .is_some_and(|t| stream.passed_tracks.contains(&t))
            );
            collected += 1;
        }
    }
    assert!(collected > 0, "nothing reached the collector in 4 trials");
}
