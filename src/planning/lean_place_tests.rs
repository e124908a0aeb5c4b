//! A part gripped with the tool leaning is set down standing when, set down leaning, it would
//! fall over (leaning further than its diameter over its height); one that rights itself is
//! set down with the tool pointing straight down, as before.

use nalgebra::Vector3;

use super::pick_planner_tests::{home, percept, planner};
use super::{Payload, bin_slot};
use crate::cell::BinBody;
use crate::kinematics::tcp_pose;
use crate::rng::SimRng;

#[test]
fn a_leaning_grip_sets_a_part_that_would_fall_over_down_standing() {
    let planner = planner();
    let bin = BinBody {
        name: "good".into(),
        floor_center: Vector3::new(0.08, 0.50, 0.50),
        size: [0.30, 0.30],
        wall_height: 0.08,
    };
    let payload = Payload {
        mass_kg: 0.3,
        grip_force_n: 60.0,
        pad_friction: 1.0,
    };
    let mut rng = SimRng::new(2512);
    let (mut standing, mut as_before) = (0, 0);
    for _ in 0..40 {
        let mut percept = percept([rng.range(-0.05, 0.15), rng.range(-0.5, -0.4)], Vec::new());
        percept.part_outer_radius_m = rng.range(0.01, 0.035);
        percept.part_height_m = rng.range(0.04, 0.12);
        let checker = planner.checker_for(&percept);
        let Ok(mut pick) = planner.plan_pick(&percept, &checker, &home()) else {
            panic!("no pick of a free part");
        };
        let tilt = [25.0f64, -25.0, 40.0, -40.0][rng.below(4) as usize].to_radians();
        pick.tilt_rad = tilt;
        let placed_before = rng.below(5) as usize;
        let Ok(place) =
            planner.plan_place(&percept, &bin, placed_before, &pick, &payload, &checker)
        else {
            panic!("no place into a reachable bin");
        };
        let Some(q_low) = place.lower.end() else {
            panic!("empty lowering");
        };
        let world_from_tcp = planner.world_from_base * tcp_pose(&planner.model, &q_low);
        let slot = bin.floor_center + bin_slot(&bin, placed_before);
        let at = world_from_tcp.translation.vector;
        assert!((at.x - slot.x).hypot(at.y - slot.y) < 1e-3, "in the slot");
        // The part's axis, up, in the TCP frame: the tool's axis (down) turned back by the lean.
        let up_in_tcp =
            nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -tilt) * -Vector3::z();
        let part_up = world_from_tcp.rotation * up_in_tcp;
        let tool_down = world_from_tcp.rotation * Vector3::z();
        let falls = tilt.abs() > (2.0 * percept.part_outer_radius_m).atan2(percept.part_height_m);
        if falls {
            standing += 1;
            assert!(
                part_up.z > (1e-3f64).cos(),
                "set down standing: {part_up:?}"
            );
        } else {
            as_before += 1;
            assert!(
                tool_down.z < -(1e-6f64).cos(),
                "tool straight down: {tool_down:?}"
            );
            assert!(
                (part_up.z - tilt.cos()).abs() < 1e-6,
                "the part leaning by the grip"
            );
        }
    }
    assert!(
        standing >= 5 && as_before >= 5,
        "{standing} standing, {as_before} as before"
    );
}
