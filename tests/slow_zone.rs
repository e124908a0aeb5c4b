//! A fast belt stops its item at the photo-eye: the slow-down zone ahead of the beam drops the
//! belt to its creep speed, so the item that breaks the beam still breaks it once the drive has
//! ramped the belt to a stop. Drawn over belt speeds from the paper's to four times it, creep
//! speeds and every part type, without a bottle.

mod common;

use twincell::cell::{Cell, CellModel};
use twincell::control::BeltDrive;
use twincell::rng::SimRng;

/// Runs the belt as a trial's wait does (full speed, the creep while the zone is occupied, a
/// stop when the beam breaks); returns whether the first part still breaks the beam at rest.
fn part_at_the_eye_after_the_stop(speed_m_s: f64, creep_m_s: f64, seed: u64) -> bool {
    let mut scenario = common::paper_50();
    scenario.bottle.enabled = false;
    scenario.conveyor.speed_m_s = speed_m_s;
    scenario.conveyor.creep_speed_m_s = creep_m_s;
    let mut rng = SimRng::new(seed);
    let mut cell = Cell::build(
        &CellModel::with_urdf(scenario.clone(), None).expect("model"),
        &mut rng,
    )
    .expect("cell builds");
    let dt = scenario.physics.dt_s;
    let mut drive = BeltDrive::with_creep(creep_m_s);
    drive.run_at(speed_m_s);
    let step = |cell: &mut Cell, drive: &mut BeltDrive| {
        drive.set_zone_occupied(cell.slow_zone_occupied());
        drive.advance(&cell.conveyor, dt);
        cell.step();
    };
    let mut steps = 0;
    while !cell.photo_eye_blocked() && steps < 4800 {
        step(&mut cell, &mut drive);
        steps += 1;
    }
    assert!(
        cell.photo_eye_blocked(),
        "nothing reached the eye at {speed_m_s} m/s"
    );
    drive.run_at(0.0);
    while cell.conveyor.speed_m_s() > 0.0 {
        step(&mut cell, &mut drive);
    }
    for _ in 0..60 {
        step(&mut cell, &mut drive);
    }
    let part = cell.items.parts()[0].body;
    cell.bodies_at_photo_eye().contains(&part)
}

#[test]
fn a_fast_belt_stops_its_part_at_the_eye() {
    // Belt speeds from the paper's 0.25 m/s to 1 m/s, creep speeds at and below the paper's;
    // each seed draws another part type and lateral offset.
    let mut seed = 40;
    for speed in [0.25, 0.35, 0.5, 0.7, 1.0] {
        for creep in [0.15, 0.25] {
            seed += 1;
            assert!(
                part_at_the_eye_after_the_stop(speed, creep, seed),
                "at {speed} m/s with a creep of {creep} m/s the part ran past the beam"
            );
        }
    }
}

#[test]
fn without_the_zone_a_fast_belt_runs_its_part_through_the_beam() {
    // The same drive with the creep at the belt's speed (no zone): from 0.5 m/s the belt needs
    // 125 mm to stop, more than any part's diameter, so the zone is what keeps the part there.
    for seed in [41, 42, 43] {
        assert!(
            !part_at_the_eye_after_the_stop(0.5, 0.5, seed),
            "seed {seed}: the part stopped at the beam without a zone"
        );
    }
}
