//! A stream's bottles and parts out of the camera's view stay obstacles while the tracks hold
//! them on the belt ([`BeltTracking::add_tracked_bottles`], [`BeltTracking::add_tracked_parts`]).

use std::path::Path;

use nalgebra::{Isometry3, Point3};

use super::BeltTracking;
use crate::cell::CellModel;
use crate::control::ENCODER_M_PER_COUNT;
use crate::rng::SimRng;
use crate::scenario::{PartTypeId, Scenario};
use crate::station::{
    BeltPoint, ItemKind, ItemSighting, Percept, TrackEnd, TrackId, ViewSpan, bottle_obstacle,
    part_obstacle,
};

fn model() -> CellModel {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/suite/fast_belt.toml");
    let scenario = Scenario::load(&path).expect("scenario");
    CellModel::new(scenario, &path).expect("model")
}

fn percept() -> Percept {
    Percept {
        part_type: PartTypeId(0),
        part_xy: [0.0, 0.0],
        part_outer_radius_m: 0.03,
        part_height_m: 0.05,
        roundness_mm: None,
        bore_diameter_mm: None,
        inconsistency: None,
        unidentified: None,
        obstacles: Vec::new(),
    }
}

fn sighting(kind: ItemKind, along_m: f64, across_m: f64, half_length_m: f64) -> ItemSighting {
    ItemSighting {
        kind,
        score: 0.9,
        at: BeltPoint { along_m, across_m },
        half_length_m,
    }
}

/// Items over `view` 0.21 m apart (the first 0.01 m inside its upstream end), of the kind
/// `kind_of` draws for each, across the belt within 0.1 m of its middle, each footprint's half
/// length 0.02 m to `half_max_m`.
fn drawn_items(
    rng: &mut SimRng,
    view: &ViewSpan,
    mut kind_of: impl FnMut(usize, &mut SimRng) -> ItemKind,
    half_max_m: f64,
) -> Vec<ItemSighting> {
    let n = ((view.to_m - view.from_m - 0.02) / 0.21).floor() as usize + 1;
    (0..n)
        .map(|i| {
            let kind = kind_of(i, rng);
            let along = view.from_m + 0.01 + 0.21 * i as f64;
            sighting(
                kind,
                along,
                rng.range(-0.1, 0.1),
                rng.range(0.02, half_max_m),
            )
        })
        .collect()
}

/// Bottles and parts drawn over the view, then carried on by a drawn travel: each bottle track
/// still on the belt (open, or carried out of the view) and away from the percept's bottles
/// becomes one standing obstacle at its predicted place, as wide as its footprint was long; a
/// part, a lost track, a bottle past the belt's end or beside a bottle the percept holds adds
/// nothing.
#[test]
fn bottles_the_tracks_hold_on_the_belt_are_obstacles() {
    let model = model();
    let scenario = model.scenario();
    let belt = &scenario.conveyor;
    let top_z = 0.7;
    let end_along_m = belt.belt_center_m[0] + belt.length_m / 2.0 - belt.photo_eye_x_m;
    let mut rng = SimRng::new(2512);
    for _ in 0..40 {
        let mut tracking = BeltTracking::new(&model, top_z);
        let view = tracking.view;
        // Items in view at least 0.21 m apart (the percept's bottle below, 0.05 m from one,
        // lies more than 0.1 m from every other).
        let kind = |_: usize, rng: &mut SimRng| {
            if rng.uniform() < 0.5 {
                ItemKind::Bottle
            } else {
                ItemKind::Part
            }
        };
        let items = drawn_items(&mut rng, &view, kind, 0.11);
        let n = items.len();
        assert!(n >= 2, "a view of {:.2} m", view.to_m - view.from_m);
        let ids = tracking.tracks.update(0, &items, &view);
        // One track lost, and the belt carried on by up to the belt's far end and beyond.
        let lost = ids[rng.below(n as u64) as usize];
        tracking.tracks.close(lost, TrackEnd::Lost);
        let travel_m = rng.range(0.0, end_along_m - view.from_m + 0.3);
        let count = (travel_m / ENCODER_M_PER_COUNT).round() as i64;
        tracking.tracks.update(count, &[], &view);
        // The percept already holds a bottle where one drawn track now stands.
        let mut percept = percept();
        let known: Option<TrackId> = ids.iter().copied().find(|&id| id != lost);
        let known_at = known.and_then(|id| tracking.tracks.predicted(id, count));
        if let Some(at) = known_at {
            let p = tracking.frame.world_from_belt(&BeltPoint {
                along_m: at.along_m + 0.05,
                ..at
            });
            let pose = Isometry3::translation(p.x, p.y, p.z);
            percept
                .obstacles
                .push(bottle_obstacle(&scenario.bottle, &pose, false, 0.0));
        }
        let before = percept.obstacles.len();
        tracking.add_tracked_bottles(&model, count, &mut percept);
        let added = &percept.obstacles[before..];
        let expected: Vec<(TrackId, Point3<f64>, f64)> = ids
            .iter()
            .zip(&items)
            .filter(|&(&id, item)| item.kind == ItemKind::Bottle && id != lost)
            .filter(|&(&id, _)| Some(id) != known)
            .filter_map(|(&id, item)| {
                let at = tracking.tracks.predicted(id, count)?;
                (at.along_m <= end_along_m)
                    .then(|| (id, tracking.frame.world_from_belt(&at), item.half_length_m))
            })
            .collect();
        assert_eq!(added.len(), expected.len(), "travel {travel_m:.2} m");
        for ((_, point, half_length_m), o) in expected.iter().zip(added) {
            let c = o.world_from_shape.translation.vector;
            assert!(
                (c.x - point.x).hypot(c.y - point.y) < 1e-9,
                "placed at the prediction"
            );
            assert!(
                (o.top_z - (top_z + scenario.bottle.height_m)).abs() < 1e-9,
                "standing"
            );
            let radius = o
                .shape
                .as_cylinder()
                .map(|c| f64::from(c.radius))
                .unwrap_or(0.0);
            let wanted = scenario.bottle.radius_m.max(*half_length_m);
            assert!(
                (radius - wanted).abs() < 1e-6,
                "radius {radius} for {wanted}"
            );
        }
    }
}

/// Parts and bottles drawn over the view, then carried on by a drawn travel: each part track
/// still on the belt, other than the part picked (by its track, or where the percept has it
/// when it has none) and away from the percept's other parts, becomes one standing tube of the
/// catalogue's widest and tallest at its predicted place; a bottle, a lost track, or a part past
/// the belt's end adds nothing.
#[test]
fn parts_the_tracks_hold_on_the_belt_are_obstacles() {
    let model = model();
    let scenario = model.scenario();
    let belt = &scenario.conveyor;
    let top_z = 0.7;
    let end_along_m = belt.belt_center_m[0] + belt.length_m / 2.0 - belt.photo_eye_x_m;
    let widest = scenario
        .part_types
        .iter()
        .map(|t| t.outer_diameter_mm / 2000.0)
        .fold(0.0, f64::max);
    let tallest = scenario
        .part_types
        .iter()
        .map(|t| t.height_mm / 1000.0)
        .fold(0.0, f64::max);
    let mut rng = SimRng::new(1512);
    for round in 0..40 {
        let mut tracking = BeltTracking::new(&model, top_z);
        let view = tracking.view;
        // The first item is the part picked; the others drawn.
        let kind = |i: usize, rng: &mut SimRng| {
            if i == 0 || rng.uniform() < 0.6 {
                ItemKind::Part
            } else {
                ItemKind::Bottle
            }
        };
        let items = drawn_items(&mut rng, &view, kind, 0.05);
        let n = items.len();
        let ids = tracking.tracks.update(0, &items, &view);
        let lost = ids[1 + rng.below(n as u64 - 1) as usize];
        tracking.tracks.close(lost, TrackEnd::Lost);
        let travel_m = rng.range(0.0, end_along_m - view.from_m + 0.3);
        let count = (travel_m / ENCODER_M_PER_COUNT).round() as i64;
        tracking.tracks.update(count, &[], &view);
        let world_at = |id: TrackId| {
            let at = tracking.tracks.predicted(id, count)?;
            Some(tracking.frame.world_from_belt(&at))
        };
        // The picked part where the percept has it, known by its track every other round.
        let mut percept = percept();
        let Some(own_at) = world_at(ids[0]) else {
            panic!("no prediction");
        };
        percept.part_xy = [own_at.x, own_at.y];
        let own = (round % 2 == 0).then_some(ids[0]);
        // The percept already holds another part where one drawn part track now stands.
        let known = ids[1..]
            .iter()
            .zip(&items[1..])
            .find(|&(&id, item)| item.kind == ItemKind::Part && id != lost)
            .map(|(&id, _)| id);
        if let Some(p) = known.and_then(world_at) {
            let centre = Point3::new(p.x + 0.03, p.y, p.z + 0.03);
            percept.obstacles.push(part_obstacle(&centre, 0.02, 0.06));
        }
        let before = percept.obstacles.len();
        tracking.add_tracked_parts(&model, count, &mut percept, own);
        let added = &percept.obstacles[before..];
        let expected: Vec<Point3<f64>> = ids[1..]
            .iter()
            .zip(&items[1..])
            .filter(|&(&id, item)| item.kind == ItemKind::Part && id != lost)
            .filter(|&(&id, _)| Some(id) != known)
            .filter_map(|(&id, _)| {
                let at = tracking.tracks.predicted(id, count)?;
                (at.along_m <= end_along_m).then(|| tracking.frame.world_from_belt(&at))
            })
            .collect();
        assert_eq!(
            added.len(),
            expected.len(),
            "travel {travel_m:.2} m, own {own:?}"
        );
        for (point, o) in expected.iter().zip(added) {
            let c = o.world_from_shape.translation.vector;
            assert!((c.x - point.x).hypot(c.y - point.y) < 1e-9);
            assert!((o.top_z - (top_z + tallest)).abs() < 1e-9, "the tallest");
            let radius = o.shape.as_cylinder().map_or(0.0, |c| f64::from(c.radius));
            assert!(
                (radius - widest).abs() < 1e-6,
                "radius {radius}, widest {widest}"
            );
        }
    }
}
