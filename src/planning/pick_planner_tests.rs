//! The grasp and place search on percepts and obstacles made by hand: no physics world.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rapier3d::geometry::SharedShape;

use super::grasp_search::GraspSearch;
use super::grasp_search::{COARSE_YAWS_DEG, fine_yaws_deg};
use super::*;
use crate::cell::BinBody;
use crate::kinematics::{AnalyticIk, ArmModel, gripper_tcp, tcp_pose};
use crate::outcome::FailureReason;
use crate::scenario::{BottleSection, RobotSection};
use crate::station::{PerceivedObstacle, Percept, bottle_obstacle};

const BELT_TOP_Z: f64 = 0.70;

/// The scenarios' home: TCP pointing down 0.3 m in front of the base and 0.4 m above it.
pub(super) fn home() -> [f64; 6] {
    RobotSection::default().home_q_rad
}

/// The robot as simple shapes on its frames: a wrist drum on the flange, two finger pads.
fn robot_shapes() -> Vec<RobotShape> {
    let pad = SharedShape::cuboid(0.006, 0.015, 0.03);
    let finger = |sign: f64| RobotShape {
        link: if sign > 0.0 {
            "finger_left_Link"
        } else {
            "finger_right_Link"
        }
        .into(),
        mount: LinkMount::Finger { sign },
        mount_from_shape: Isometry3::translation(sign * 0.045, 0.0, 0.11),
        shape: pad.clone(),
    };
    vec![
        RobotShape {
            link: "wrist3_Link".into(),
            mount: LinkMount::Dh(6),
            mount_from_shape: Isometry3::from_parts(
                Translation3::new(0.0, 0.0, 0.04),
                UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            ),
            shape: SharedShape::cylinder(0.04, 0.045),
        },
        finger(1.0),
        finger(-1.0),
    ]
}

pub(super) fn planner() -> PickPlanner {
    let model = ArmModel::aubo_i5().with_tool(gripper_tcp());
    let Ok(ik) = AnalyticIk::new(model.clone()) else {
        panic!("the AUBO i5 model has a closed-form inverse");
    };
    PickPlanner {
        model,
        ik,
        world_from_base: Isometry3::translation(0.0, 0.0, 0.6),
        robot_shapes: robot_shapes(),
        finger_reference_m: 0.045,
        obstacles: Vec::new(),
        belt_top_z: BELT_TOP_Z,
        open_clearance_m: 0.012,
        speed_fraction: 0.6,
        carry_speed_fraction: 0.4,
        home_q_rad: home(),
    }
}

/// A 0.4 kg tube held with 60 N per jaw on rubber pads.
fn payload() -> Payload {
    Payload {
        mass_kg: 0.4,
        grip_force_n: 60.0,
        pad_friction: 1.0,
    }
}

pub(super) fn percept(xy: [f64; 2], obstacles: Vec<PerceivedObstacle>) -> Percept {
    Percept {
        part_type: crate::scenario::PartTypeId(2),
        part_xy: xy,
        part_outer_radius_m: 0.02,
        part_height_m: 0.05,
        roundness_mm: Some(0.2),
        bore_diameter_mm: Some(28.0),
        inconsistency: None,
        unidentified: None,
        obstacles,
    }
}

fn bottle() -> BottleSection {
    BottleSection {
        radius_m: 0.033,
        height_m: 0.2,
        ..BottleSection::default()
    }
}

/// The gripper's yaw at a joint configuration, world frame, folded to [0, pi) (the jaws are
/// symmetric).
fn jaw_yaw(planner: &PickPlanner, q: &[f64; 6]) -> f64 {
    let world_from_tcp = planner.world_from_base * tcp_pose(&planner.model, q);
    let x_axis = world_from_tcp.rotation * Vector3::x();
    x_axis.y.atan2(x_axis.x).rem_euclid(std::f64::consts::PI)
}

fn tcp_xyz(planner: &PickPlanner, q: &[f64; 6]) -> Vector3<f64> {
    (planner.world_from_base * tcp_pose(&planner.model, q))
        .translation
        .vector
}

#[test]
fn a_free_part_is_picked_upright_straight_down() {
    let planner = planner();
    let percept = percept([0.05, -0.45], Vec::new());
    let checker = planner.checker_for(&percept);
    let Ok(plan) = planner.plan_pick(&percept, &checker, &home()) else {
        panic!("no pick for a free part in reach");
    };
    let Some(q_at) = plan.approach.end() else {
        panic!("empty descent");
    };
    let at = tcp_xyz(&planner, &q_at);
    assert!(
        (at.x - 0.05).abs() < 1e-3 && (at.y + 0.45).abs() < 1e-3,
        "{at:?}"
    );
    assert!(
        (at.z - (BELT_TOP_Z + GRASP_TCP_ABOVE_BOTTOM_M)).abs() < 1e-3,
        "{at:?}"
    );
    // Straight down: once the blend from the approach is over, every sample of the descent
    // stays over the part's axis; before that the fingertips (15 mm below the TCP) stay above
    // the part's top with the planning margin to spare.
    let blend_end = plan.approach.part_ends_s()[0];
    let steps = 400;
    for k in 0..=steps {
        let t = plan.approach.duration_s() * f64::from(k) / f64::from(steps);
        let Some(sample) = plan.approach.sample(t) else {
            panic!("no sample");
        };
        let p = tcp_xyz(&planner, &sample.q);
        let off_axis = (p.x - 0.05).hypot(p.y + 0.45);
        if t >= blend_end {
            assert!(off_axis < 2e-3, "off axis at {t} s: {p:?}");
        } else if off_axis >= 2e-3 {
            let part_top = BELT_TOP_Z + percept.part_height_m;
            assert!(
                p.z - 0.015 > part_top + 0.008,
                "low off the axis at {t} s: {p:?}"
            );
        }
    }
    assert!(plan.approach.part_starts_s()[1] < blend_end, "no blend");
    // Upright: the tool axis points down.
    let world_from_tcp = planner.world_from_base * tcp_pose(&planner.model, &q_at);
    assert!((world_from_tcp.rotation * Vector3::z()).z < -0.999);
    // The lift ends above where it started.
    assert!(tcp_xyz(&planner, &plan.lift_end).z > at.z + 0.1);
}

#[test]
fn the_jaws_close_across_the_line_to_the_nearest_obstacle() {
    let planner = planner();
    for angle_deg in [0.0f64, 45.0, 120.0] {
        let angle = angle_deg.to_radians();
        let part = [0.05, -0.45];
        let at = Point3::new(
            part[0] + 0.15 * angle.cos(),
            part[1] + 0.15 * angle.sin(),
            BELT_TOP_Z,
        );
        let standing = Isometry3::translation(at.x, at.y, at.z);
        let obstacle = bottle_obstacle(&bottle(), &standing, false, 0.0);
        let percept = percept(part, vec![obstacle]);
        let checker = planner.checker_for(&percept);
        let Ok(plan) = planner.plan_pick(&percept, &checker, &home()) else {
            panic!("no pick with a bottle 150 mm away at {angle_deg} deg");
        };
        let Some(q_at) = plan.approach.end() else {
            panic!("empty descent");
        };
        let expected = (angle + std::f64::consts::FRAC_PI_2).rem_euclid(std::f64::consts::PI);
        let yaw = jaw_yaw(&planner, &q_at);
        let diff = (yaw - expected).abs();
        let diff = diff.min(std::f64::consts::PI - diff);
        assert!(
            diff < 1e-3,
            "bottle at {angle_deg} deg: jaws at {yaw} rad, want {expected}"
        );
    }
}

#[test]
fn a_tall_obstacle_raises_the_approach_and_the_lift() {
    let planner = planner();
    let near = Isometry3::translation(0.05 + 0.12, -0.45, BELT_TOP_Z);
    let with_bottle = percept(
        [0.05, -0.45],
        vec![bottle_obstacle(&bottle(), &near, false, 0.0)],
    );
    let free = percept([0.05, -0.45], Vec::new());
    let plan = |p: &Percept| {
        let Ok(plan) = planner.plan_pick(p, &planner.checker_for(p), &home()) else {
            panic!("no pick");
        };
        plan
    };
    let (a, b) = (plan(&with_bottle), plan(&free));
    let top = |q: &[f64; 6]| tcp_xyz(&planner, q).z;
    let (a_above, b_above) = (a.pregrasp, b.pregrasp);
    // Fingertips hang 15 mm below the TCP; they pass 30 mm over the 200 mm bottle.
    assert!(
        top(&a_above) >= BELT_TOP_Z + 0.2 + 0.045 - 1e-6,
        "{}",
        top(&a_above)
    );
    assert!(top(&a_above) > top(&b_above));
    assert!(top(&a.lift_end) > top(&b.lift_end));
}

#[test]
fn an_obstacle_on_the_part_itself_is_a_collision_and_a_far_part_unreachable() {
    let planner = planner();
    // A box standing right where the jaws go down, on both sides of the part.
    let wall = PerceivedObstacle {
        name: "bottle",
        world_from_shape: Isometry3::translation(0.05, -0.45, BELT_TOP_Z + 0.1),
        shape: SharedShape::cuboid(0.2, 0.2, 0.001),
        top_z: BELT_TOP_Z + 0.1,
    };
    let blocked = percept([0.05, -0.45], vec![wall]);
    let Err(failure) = planner.plan_pick(&blocked, &planner.checker_for(&blocked), &home()) else {
        panic!("a pick through a plate over the part was planned");
    };
    assert_eq!(
        failure.reason,
        FailureReason::Collision,
        "{}",
        failure.detail
    );
    let far = percept([2.5, -0.45], Vec::new());
    let Err(failure) = planner.plan_pick(&far, &planner.checker_for(&far), &home()) else {
        panic!("a part 2.5 m away was planned");
    };
    assert_eq!(failure.reason, FailureReason::Unreachable);
}

fn bin() -> BinBody {
    BinBody {
        name: "group_b".into(),
        floor_center: Vector3::new(0.08, 0.50, 0.50),
        size: [0.20, 0.20],
        wall_height: 0.08,
    }
}

#[test]
fn bin_slots_fill_from_the_centre_without_repeats() {
    let bin = bin();
    assert_eq!(bin_slot(&bin, 0), Vector3::zeros());
    // 0.2 m at a 0.09 m pitch: a 2 x 2 grid, each cell 0.045 m off the centre both ways.
    let slots: Vec<Vector3<f64>> = (1..5).map(|k| bin_slot(&bin, k)).collect();
    for slot in &slots {
        assert!((slot.x.abs() - 0.045).abs() < 1e-12 && (slot.y.abs() - 0.045).abs() < 1e-12);
        assert!(slot.x.abs() <= bin.size[0] / 2.0 && slot.y.abs() <= bin.size[1] / 2.0);
    }
    for (i, a) in slots.iter().enumerate().take(3) {
        assert!(slots[i + 1..4].iter().all(|b| (a - b).norm() > 0.05));
    }
    // A wider bin is a 3 x 3 grid: the first part at the centre, then the four cells beside
    // it, then the corners.
    let wide = BinBody {
        size: [0.30, 0.30],
        ..bin
    };
    for k in 1..5 {
        assert!((bin_slot(&wide, k).norm() - 0.09).abs() < 1e-12, "{k}");
    }
    for k in 5..9 {
        assert!(
            (bin_slot(&wide, k).norm() - 0.09 * 2f64.sqrt()).abs() < 1e-12,
            "{k}"
        );
    }
}

#[test]
fn a_place_goes_into_the_slot_and_retreats_home() {
    let planner = planner();
    let percept = percept([0.05, -0.45], Vec::new());
    let checker = planner.checker_for(&percept);
    let Ok(pick) = planner.plan_pick(&percept, &checker, &home()) else {
        panic!("no pick");
    };
    let bin = bin();
    for placed_before in [0, 1] {
        let Ok(place) =
            planner.plan_place(&percept, &bin, placed_before, &pick, &payload(), &checker)
        else {
            panic!("no place into a reachable bin");
        };
        let Some(q_low) = place.lower.end() else {
            panic!("empty lowering");
        };
        let at = tcp_xyz(&planner, &q_low);
        let slot = bin.floor_center + bin_slot(&bin, placed_before);
        assert!(
            (at.x - slot.x).hypot(at.y - slot.y) < 1e-3,
            "{at:?} vs {slot:?}"
        );
        let Some(end) = place.retreat.end() else {
            panic!("empty retreat");
        };
        assert!(end.iter().zip(home()).all(|(a, b)| (a - b).abs() < 1e-9));
    }
    let far = BinBody {
        floor_center: Vector3::new(3.0, 0.0, 0.5),
        ..bin
    };
    let Err(failure) = planner.plan_place(&percept, &far, 0, &pick, &payload(), &checker) else {
        panic!("a bin 3 m away was reachable");
    };
    assert_eq!(failure.reason, FailureReason::Unreachable);
}

#[test]
fn the_fine_yaws_fill_the_gaps_between_the_coarse_ones_nearest_the_jaw_line_first() {
    let fine: Vec<f64> = fine_yaws_deg().collect();
    let mut all: Vec<f64> = fine
        .iter()
        .copied()
        .chain(COARSE_YAWS_DEG.iter().map(|d| d.rem_euclid(360.0)))
        .collect();
    all.sort_by(f64::total_cmp);
    let every_ten: Vec<f64> = (0..36).map(|k| f64::from(k) * 10.0).collect();
    assert_eq!(all, every_ten, "each 10 degrees once, coarse or fine");
    assert_eq!(&fine[..4], &[10.0, 170.0, 190.0, 350.0]);
    let off_line = |d: f64| (d % 180.0).min(180.0 - d % 180.0);
    assert!(fine.windows(2).all(|w| off_line(w[0]) <= off_line(w[1])));
}

/// A wall standing on the belt: `length` along `direction_rad`'s normal, its inner face
/// `gap_m` from the part's axis at `part` in direction `direction_rad`, 120 mm high.
fn wall(part: [f64; 2], direction_rad: f64, gap_m: f64) -> PerceivedObstacle {
    let (half_thick, half_long, half_high) = (0.005, 0.1, 0.06);
    let centre = gap_m + half_thick;
    PerceivedObstacle {
        name: "wall",
        world_from_shape: Isometry3::from_parts(
            Translation3::new(
                part[0] + centre * direction_rad.cos(),
                part[1] + centre * direction_rad.sin(),
                BELT_TOP_Z + half_high,
            ),
            UnitQuaternion::from_euler_angles(0.0, 0.0, direction_rad),
        ),
        shape: SharedShape::cuboid(half_thick as f32, half_long as f32, half_high as f32),
        top_z: BELT_TOP_Z + 2.0 * half_high,
    }
}

/// The smallest distance from the robot to the percept's obstacles (not the part, not the
/// belt) over `configurations`, each with its finger offset, capped.
fn measured_clearance(
    planner: &PickPlanner,
    percept: &Percept,
    configurations: &[([f64; 6], f64)],
) -> f64 {
    let base_from_world = planner.world_from_base.inverse();
    let walls = percept
        .obstacles
        .iter()
        .map(|o| Obstacle {
            name: o.name.into(),
            base_from_shape: base_from_world * o.world_from_shape,
            shape: o.shape.clone(),
        })
        .collect();
    let checker = CollisionChecker::new(
        planner.model.clone(),
        planner.robot_shapes.clone(),
        planner.finger_reference_m,
        walls,
        0.0,
    );
    configurations
        .iter()
        .filter_map(|(q, fingers)| checker.clearance(q, *fingers, None, &[], CLEARANCE_CAP_M))
        .map(|c| c.distance_m)
        .fold(CLEARANCE_CAP_M, f64::min)
}

/// The descent (after the blend) and the lift of `plan`, sampled, with the jaws open.
fn descent_and_lift(
    planner: &PickPlanner,
    percept: &Percept,
    plan: &PickPlan,
) -> Vec<([f64; 6], f64)> {
    let open = planner.open_offset_m(percept);
    let start = plan.approach.part_ends_s()[0];
    let steps = 200;
    let mut configurations: Vec<([f64; 6], f64)> = (0..=steps)
        .filter_map(|k| {
            let t = start + (plan.approach.duration_s() - start) * f64::from(k) / f64::from(steps);
            plan.approach.sample(t).map(|s| (s.q, open))
        })
        .collect();
    // The lift is scored with the jaws open: their envelope holds the closed jaws'.
    configurations.extend(plan.lift_path.iter().map(|q| (*q, open)));
    configurations
}

#[test]
fn a_part_boxed_in_on_three_sides_is_picked_with_the_most_clearance_there_is() {
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(25);
    for draw in 0..5 {
        let part = [rng.range(-0.05, 0.15), rng.range(-0.5, -0.4)];
        let open_side = rng.range(0.0, std::f64::consts::TAU);
        let gap = rng.range(0.055, 0.08);
        let walls = (1..4)
            .map(|k| {
                wall(
                    part,
                    open_side + f64::from(k) * std::f64::consts::FRAC_PI_2,
                    gap,
                )
            })
            .collect();
        let percept = percept(part, walls);
        let checker = planner.checker_for(&percept);
        let plan = match planner.plan_pick(&percept, &checker, &home()) {
            Ok(plan) => plan,
            Err(f) => panic!(
                "draw {draw}: no pick in a box {gap} m wide open at {open_side} rad: {}",
                f.detail
            ),
        };
        // The clearance the plan reports is the one its motion has, within the spacing of
        // the samples the search scored.
        let measured = measured_clearance(
            &planner,
            &percept,
            &descent_and_lift(&planner, &percept, &plan),
        );
        assert!(
            plan.clearance_m >= 0.008,
            "draw {draw}: {}",
            plan.clearance_m
        );
        assert!(
            (measured - plan.clearance_m).abs() < 1e-3,
            "draw {draw}: reports {} m, measured {measured} m",
            plan.clearance_m
        );
        // The best of all candidates, not the first that passes: no candidate of the grid,
        // scored in full, clears the walls by more.
        let search = GraspSearch::new(&planner, &percept, &checker, &home());
        let best_of_grid = search
            .exhaustive()
            .iter()
            .map(|g| g.clearance_m)
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(
            plan.clearance_m >= best_of_grid - 1e-9,
            "draw {draw}: chose {} m, the grid has {best_of_grid} m",
            plan.clearance_m
        );
        assert!(
            plan.candidates > 100,
            "draw {draw}: {} candidates",
            plan.candidates
        );
    }
}

#[test]
fn a_free_part_keeps_the_preferred_grasp_at_full_clearance() {
    let planner = planner();
    let percept = percept([0.05, -0.45], Vec::new());
    let checker = planner.checker_for(&percept);
    let Ok(plan) = planner.plan_pick(&percept, &checker, &home()) else {
        panic!("no pick for a free part");
    };
    assert_eq!(plan.clearance_m, CLEARANCE_CAP_M);
    let ranking = GraspSearch::new(&planner, &percept, &checker, &home()).rank();
    // The first candidate reaches the cap and nothing else is scored.
    assert_eq!(ranking.scored, 1);
    assert_eq!(ranking.grasps[0].pose.tilt_rad, 0.0);
}

#[test]
fn a_bottle_near_the_part_gets_the_grasp_that_clears_it_most() {
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(2501);
    for draw in 0..4 {
        let part = [rng.range(-0.05, 0.15), rng.range(-0.5, -0.4)];
        let angle = rng.range(0.0, std::f64::consts::TAU);
        // A gap of 15-40 mm between the bottle's and the part's footprints: some grasps pass
        // it, others would touch it.
        let centre = 0.02 + 0.033 + rng.range(0.015, 0.04);
        let standing = Isometry3::translation(
            part[0] + centre * angle.cos(),
            part[1] + centre * angle.sin(),
            BELT_TOP_Z,
        );
        let percept = percept(
            part,
            vec![bottle_obstacle(&bottle(), &standing, false, 0.0)],
        );
        let checker = planner.checker_for(&percept);
        let search = GraspSearch::new(&planner, &percept, &checker, &home());
        let ranking = search.rank();
        let all = search.exhaustive();
        let best_of_grid = all
            .iter()
            .map(|g| g.clearance_m)
            .fold(f64::NEG_INFINITY, f64::max);
        let Some(best) = ranking.grasps.first() else {
            panic!("draw {draw}: nothing scored");
        };
        assert!(best.clearance_m >= best_of_grid - 1e-9, "draw {draw}");
        // Ranked best first, each clearance below the cap set by a named pair.
        assert!(
            ranking
                .grasps
                .windows(2)
                .all(|w| w[0].clearance_m >= w[1].clearance_m)
        );
        if best.clearance_m < CLEARANCE_CAP_M {
            let Some(near) = &best.nearest else {
                panic!("draw {draw}: no nearest pair below the cap");
            };
            assert_eq!(near.obstacle, "bottle");
        }
        // Candidates differ: ranking is not a formality here.
        let worst = all
            .iter()
            .map(|g| g.clearance_m)
            .fold(f64::INFINITY, f64::min);
        assert!(
            best_of_grid > worst + 0.005,
            "draw {draw}: {worst} .. {best_of_grid}"
        );
        assert!(
            ranking.scored < all.len(),
            "draw {draw}: the bound pruned nothing"
        );
    }
}

/// Lying bottles around a part, 2 or 3 drawn over direction, yaw and a gap of about 20-80 mm:
/// every part is picked, clear of them by the planning margin.
#[test]
fn lying_bottles_around_a_part_leave_it_pickable() {
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(2502);
    let (b, tau) = (bottle(), std::f64::consts::TAU);
    for draw in 0..12 {
        let part = [rng.range(-0.05, 0.15), rng.range(-0.5, -0.4)];
        let (mut obstacles, count) = (Vec::<PerceivedObstacle>::new(), 2 + rng.below(2));
        while obstacles.len() < count as usize {
            let (angle, yaw) = (rng.range(0.0, tau), rng.range(0.0, tau));
            let (cos, sin) = ((yaw - angle).cos().abs(), (yaw - angle).sin().abs());
            let half = f64::max(cos * b.height_m / 2.0, sin * b.radius_m).max(b.radius_m);
            let centre = 0.02 + rng.range(0.02, 0.08) + half;
            let at = Vector3::new(part[0], part[1], BELT_TOP_Z + b.radius_m)
                + centre * Vector3::new(angle.cos(), angle.sin(), 0.0);
            let lying = Isometry3::from_parts(
                Translation3::from(at),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw)
                    * UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
            ) * Isometry3::translation(0.0, 0.0, -b.height_m / 2.0);
            let candidate = bottle_obstacle(&b, &lying, true, 0.0);
            let c = candidate.world_from_shape.translation.vector;
            let apart = obstacles.iter().all(|o| {
                let d = o.world_from_shape.translation.vector - c;
                d.x.hypot(d.y) > b.height_m + 0.01
            });
            obstacles.extend(apart.then_some(candidate));
        }
        let percept = percept(part, obstacles);
        let checker = planner.checker_for(&percept);
        match planner.plan_pick(&percept, &checker, &home()) {
            Ok(plan) => assert!(
                plan.clearance_m >= super::pick_planner::PLANNING_MARGIN_M,
                "draw {draw}: clearance {:.4} m",
                plan.clearance_m
            ),
            Err(refusal) => panic!("draw {draw} at {part:?}: {}", refusal.detail),
        }
    }
}
