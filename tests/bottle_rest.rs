//! A bottle comes to rest (rapier's sleep) once it stands still on the stopped belt, and is
//! simulated again whenever something could move it: the belt running (whose pull rapier does
//! not see, it is a contact hook), or a moving body reaching it (the arm's links are kinematic).

mod common;
use common::paper_50;

use rapier3d::prelude::*;
use twincell::cell::{Cell, CellModel};
use twincell::rng::SimRng;
use twincell::scenario::BottleSection;
use twincell::sim::{BottlePlacement, ItemSet, World, WorldParams, body_pose};

/// Steps of `dt_s` in `s` seconds.
fn steps(s: f64, dt_s: f64) -> usize {
    (s / dt_s).round() as usize
}

#[test]
fn a_bottle_rests_on_the_stopped_belt_and_rides_again_when_it_runs() {
    let base = paper_50();
    let mut rested = 0;
    for (seed, lying) in [(1, false), (2, true), (3, false), (4, true)] {
        let mut scenario = base.clone();
        scenario.bottle.lying_fraction = if lying { 1.0 } else { 0.0 };
        let model = CellModel::with_urdf(scenario.clone(), None).expect("model");
        let mut cell = Cell::build(&model, &mut SimRng::new(seed)).expect("cell builds");
        let dt = scenario.physics.dt_s;
        let body = cell.items.bottles()[0].body;
        for _ in 0..steps(1.5, dt) {
            cell.step();
        }
        let sleeping = |cell: &Cell| cell.world.physics.bodies[body].is_sleeping();
        assert!(
            sleeping(&cell),
            "seed {seed} (lying {lying}): still simulated after 1.5 s on the stopped belt"
        );
        rested += 1;
        let start = cell.body_pose(body).expect("bottle").translation.x;
        let speed = scenario.conveyor.speed_m_s;
        for _ in 0..steps(1.0, dt) {
            cell.conveyor.ramp_towards(speed as f32, dt as f32);
            cell.step();
        }
        assert!(!sleeping(&cell), "seed {seed}: asleep on the running belt");
        let travelled = cell.body_pose(body).expect("bottle").translation.x - start;
        // The ramp takes 0.25 s of the second: at least 0.75 s at speed, less the slip.
        assert!(
            travelled > 0.6 * speed,
            "seed {seed} (lying {lying}): {:.1} mm in 1 s on a belt at {speed} m/s",
            travelled * 1e3
        );
    }
    assert_eq!(rested, 4);
}

#[test]
fn a_resting_bottle_is_pushed_by_a_kinematic_body() {
    let mut world = World::new(WorldParams::default());
    let dt = world.params().dt_s;
    let floor = world
        .physics
        .bodies
        .insert(RigidBodyBuilder::fixed().translation(Vector::new(0.0, 0.0, -0.025)));
    let physics = &mut world.physics;
    physics.colliders.insert_with_parent(
        ColliderBuilder::cuboid(1.0, 1.0, 0.025).friction(0.8),
        floor,
        &mut physics.bodies,
    );
    let mut items = ItemSet::default();
    let placement = BottlePlacement {
        xy: [0.0, 0.0],
        lying: false,
        yaw_rad: 0.0,
    };
    items.insert_bottle(&mut world, &BottleSection::default(), placement, 0.0);
    let bottle = items.bottles()[0].body;
    for _ in 0..steps(1.5, dt) {
        world.step();
    }
    assert!(world.physics.bodies[bottle].is_sleeping(), "never rested");
    // A 4 cm block (an arm's link) slides at 0.1 m/s through where the bottle stands.
    let start = Vector::new(-0.2, 0.0, 0.05);
    let block = world
        .physics
        .bodies
        .insert(RigidBodyBuilder::kinematic_position_based().translation(start));
    let physics = &mut world.physics;
    physics.colliders.insert_with_parent(
        ColliderBuilder::cuboid(0.02, 0.02, 0.02),
        block,
        &mut physics.bodies,
    );
    let before = body_pose(&world, bottle).expect("bottle").translation.x;
    for k in 1..=steps(3.0, dt) {
        let x = start.x + 0.1 * (k as f64 * dt) as f32;
        if let Some(b) = world.physics.bodies.get_mut(block) {
            b.set_next_kinematic_translation(Vector::new(x, start.y, start.z));
        }
        world.step();
    }
    let after = body_pose(&world, bottle).expect("bottle").translation.x;
    assert!(
        after - before > 0.05,
        "the block pushed the resting bottle by {:.1} mm",
        (after - before) * 1e3
    );
}
