//! The part seen twice is no obstacle to its own pick: an "other part" that would pass through
//! the part is dropped from the percept; a real neighbour, and every bottle, stay.

use nalgebra::{Isometry3, Point3};

use super::drop_second_looks;
use super::pick_planner_tests::{home, percept, planner};
use crate::outcome::FailureReason;
use crate::scenario::BottleSection;
use crate::station::{Percept, bottle_obstacle, part_obstacle};

/// Belt top of the test cell, world z, m (as the planner tests' cell).
const BELT_TOP_Z: f64 = 0.70;

/// Another tube's obstacle centred at `xy`, of `radius_m`, 90 mm tall.
fn other_part(xy: [f64; 2], radius_m: f64) -> crate::station::PerceivedObstacle {
    let height_m = 0.09;
    part_obstacle(
        &Point3::new(xy[0], xy[1], BELT_TOP_Z + height_m / 2.0),
        radius_m,
        height_m,
    )
}

#[test]
fn a_second_detection_of_the_part_no_longer_blocks_its_pick() {
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(2525);
    for draw in 0..8 {
        let part = [rng.range(-0.05, 0.15), rng.range(-0.5, -0.4)];
        // The second box's centre anywhere inside the part's footprint (20 mm radius), drawn
        // with a type's radius from the catalogue's range.
        let off_m = rng.range(0.0, 0.019);
        let dir = rng.range(0.0, std::f64::consts::TAU);
        let radius_m = rng.range(0.022, 0.032);
        let ghost = [part[0] + off_m * dir.cos(), part[1] + off_m * dir.sin()];
        let seen = percept(part, vec![other_part(ghost, radius_m)]);
        let plan = |p: &Percept| planner.plan_pick(p, &planner.checker_for(p), &home());
        let refused = plan(&seen);
        assert!(
            refused
                .as_ref()
                .is_err_and(|f| f.reason == FailureReason::Collision),
            "draw {draw}: the second box {:.1} mm off should block the pick as an obstacle",
            off_m * 1e3
        );
        let mut amended = seen.clone();
        drop_second_looks(&mut amended);
        assert!(amended.obstacles.is_empty(), "draw {draw}: not dropped");
        assert!(
            plan(&amended).is_ok(),
            "draw {draw}: no pick with the second box dropped"
        );
    }
}

#[test]
fn a_second_box_placed_beside_the_part_but_through_it_is_dropped() {
    let mut rng = crate::rng::SimRng::new(2527);
    for draw in 0..50 {
        let part = [rng.range(-0.05, 0.15), rng.range(-0.5, -0.4)];
        // A box over the part's side (or the part and a bottle beside it) from a tilted camera:
        // placed 20-30 mm off with some type's radius, the two tubes would interpenetrate.
        let radius_m = rng.range(0.017, 0.032);
        let off_m = rng.range(0.02, 0.02 + radius_m - 0.0081);
        let dir = rng.range(0.0, std::f64::consts::TAU);
        let ghost = [part[0] + off_m * dir.cos(), part[1] + off_m * dir.sin()];
        let mut seen = percept(part, vec![other_part(ghost, radius_m)]);
        drop_second_looks(&mut seen);
        assert!(
            seen.obstacles.is_empty(),
            "draw {draw}: a tube {:.1} mm off, radius {:.1} mm, kept",
            off_m * 1e3,
            radius_m * 1e3
        );
    }
}

#[test]
fn neighbours_and_bottles_stay_obstacles() {
    let mut rng = crate::rng::SimRng::new(2526);
    for draw in 0..50 {
        let part = [rng.range(-0.05, 0.15), rng.range(-0.5, -0.4)];
        let dir = rng.range(0.0, std::f64::consts::TAU);
        let at = |d: f64| [part[0] + d * dir.cos(), part[1] + d * dir.sin()];
        // A tube beside the part (touching it, or placed up to 8 mm into it by its box, or
        // further off), and a bottle standing or lying anywhere, even overlapping the part.
        let radius_m = rng.range(0.017, 0.032);
        let least_m = 0.02 + radius_m - 0.0079;
        let neighbour = other_part(at(rng.range(least_m, least_m + 0.08)), radius_m);
        let bottle_xy = at(rng.range(0.0, 0.1));
        let lying = rng.range(0.0, 1.0) < 0.5;
        let pose = Isometry3::translation(bottle_xy[0], bottle_xy[1], BELT_TOP_Z);
        let bottle = bottle_obstacle(&BottleSection::default(), &pose, lying, 0.004);
        let mut seen = percept(part, vec![neighbour, bottle]);
        drop_second_looks(&mut seen);
        assert_eq!(
            seen.obstacles.len(),
            2,
            "draw {draw}: an obstacle was dropped"
        );
    }
}
