//! The cylinder grasp on percepts made by hand: a bottle lying across the part's only clear
//! side, a standing one 2 mm from the part, at several yaws; no physics world.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rapier3d::geometry::SharedShape;

use super::pick_planner::PLANNING_MARGIN_M;
use super::*;
use crate::cell::BinBody;
use crate::kinematics::{AnalyticIk, ArmModel, gripper_tcp, tcp_pose};
use crate::outcome::FailureReason;
use crate::scenario::RobotSection;
use crate::station::{PerceivedObstacle, Percept, part_obstacle};

const BELT_TOP_Z: f64 = 0.70;
const BOTTLE_RADIUS_M: f64 = 0.033;
const BOTTLE_LENGTH_M: f64 = 0.2;
const PART_RADIUS_M: f64 = 0.02;
const PART_HEIGHT_M: f64 = 0.06;
const OPEN_CLEARANCE_M: f64 = 0.012;

/// The gripper as the shipped URDF draws it: a body under the flange (its palm 75 mm above the
/// TCP) and two 90 mm fingers, at a reference opening of 45 mm.
fn robot_shapes() -> Vec<RobotShape> {
    let finger = |sign: f64| RobotShape {
        link: if sign > 0.0 {
            "finger_left_Link"
        } else {
            "finger_right_Link"
        }
        .into(),
        mount: LinkMount::Finger { sign },
        mount_from_shape: Isometry3::translation(sign * 0.051, 0.0, 0.095),
        shape: SharedShape::cuboid(0.006, 0.015, 0.045),
    };
    vec![
        RobotShape {
            link: "gripper_Link".into(),
            mount: LinkMount::Dh(6),
            mount_from_shape: Isometry3::translation(0.0, 0.0, 0.025),
            shape: SharedShape::cuboid(0.06, 0.025, 0.025),
        },
        finger(1.0),
        finger(-1.0),
    ]
}

fn planner() -> PickPlanner {
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
        open_clearance_m: OPEN_CLEARANCE_M,
        speed_fraction: 0.6,
        carry_speed_fraction: 0.4,
        home_q_rad: RobotSection::default().home_q_rad,
    }
}

fn home() -> [f64; 6] {
    RobotSection::default().home_q_rad
}

/// A bottle's bounding cylinder lying at `yaw_rad` with its middle at `xy`, or standing there.
fn bottle(xy: [f64; 2], lying: bool, yaw_rad: f64) -> GripCylinder {
    let (centre, axis) = if lying {
        (
            Point3::new(xy[0], xy[1], BELT_TOP_Z + BOTTLE_RADIUS_M),
            Vector3::new(yaw_rad.cos(), yaw_rad.sin(), 0.0),
        )
    } else {
        (
            Point3::new(xy[0], xy[1], BELT_TOP_Z + BOTTLE_LENGTH_M / 2.0),
            Vector3::z(),
        )
    };
    let h = BOTTLE_LENGTH_M;
    GripCylinder {
        centre,
        axis,
        radius_m: BOTTLE_RADIUS_M,
        length_m: h,
        grip_span_m: [0.1 * h - h / 2.0, 0.7 * h - h / 2.0],
        mass_kg: 0.03,
        grip_force_n: 8.0,
        obstacle: cylinder_obstacle("bottle", &centre, &axis, BOTTLE_RADIUS_M, h),
    }
}

fn part(xy: [f64; 2]) -> PerceivedObstacle {
    part_obstacle(
        &Point3::new(xy[0], xy[1], BELT_TOP_Z + PART_HEIGHT_M / 2.0),
        PART_RADIUS_M,
        PART_HEIGHT_M,
    )
}

fn percept(xy: [f64; 2], obstacles: Vec<PerceivedObstacle>) -> Percept {
    Percept {
        part_type: crate::scenario::PartTypeId(0),
        part_xy: xy,
        part_outer_radius_m: PART_RADIUS_M,
        part_height_m: PART_HEIGHT_M,
        roundness_mm: Some(0.2),
        bore_diameter_mm: Some(24.0),
        inconsistency: None,
        unidentified: None,
        obstacles,
    }
}

/// A wall 0.08 m high and 0.04 m long standing `gap_m` from the part's side, square to the
/// direction `direction_rad` from the part.
fn wall(part: [f64; 2], direction_rad: f64, gap_m: f64) -> PerceivedObstacle {
    let half_thickness = 0.005;
    let d = PART_RADIUS_M + gap_m + half_thickness;
    let (s, c) = direction_rad.sin_cos();
    PerceivedObstacle {
        name: "wall",
        world_from_shape: Isometry3::from_parts(
            Translation3::new(part[0] + d * c, part[1] + d * s, BELT_TOP_Z + 0.04),
            UnitQuaternion::from_euler_angles(0.0, 0.0, direction_rad),
        ),
        shape: SharedShape::cuboid(half_thickness as f32, 0.02, 0.04),
        top_z: BELT_TOP_Z + 0.08,
    }
}

/// The grasp's TCP pose in the world.
/// A square waste bin 0.2-0.3 m wide, 80 mm deep, drawn within the arm's reach beside the belt.
fn waste_bin(rng: &mut crate::rng::SimRng) -> BinBody {
    let side = rng.range(0.2, 0.3);
    BinBody {
        name: "waste".into(),
        floor_center: Vector3::new(rng.range(0.4, 0.5), rng.range(-0.1, 0.05), 0.5),
        size: [side, side],
        wall_height: 0.08,
    }
}

fn grasp_tcp(planner: &PickPlanner, picked: &CylinderPick) -> Isometry3<f64> {
    let Some(q) = picked.pick.lift_path.first() else {
        panic!("a pick without a grasp");
    };
    planner.world_from_base * tcp_pose(&planner.model, q)
}

/// The angle between the jaw line and the square to `axis`, deg (0: square to it).
fn off_square_deg(world_from_tcp: &Isometry3<f64>, axis: &Vector3<f64>) -> f64 {
    let jaws = world_from_tcp.rotation * Vector3::x();
    let flat = Vector3::new(axis.x, axis.y, 0.0).normalize();
    jaws.dot(&flat).abs().asin().to_degrees()
}

#[test]
fn a_free_lying_bottle_is_gripped_across_its_body_square_to_its_axis_at_any_yaw() {
    let planner = planner();
    for yaw_deg in [0.0, 35.0, 90.0, 150.0, 250.0] {
        let cylinder = bottle([0.05, -0.45], true, f64::to_radians(yaw_deg));
        let picked = planner.plan_cylinder_pick(&cylinder, &[], &home(), 1.0);
        let Ok(picked) = picked else {
            panic!("no grasp of a free bottle lying at yaw {yaw_deg}: {picked:?}");
        };
        let tcp = grasp_tcp(&planner, &picked);
        assert!(
            off_square_deg(&tcp, &cylinder.axis) <= 30.0 + 1e-6,
            "yaw {yaw_deg}: jaws {:.1} deg off square",
            off_square_deg(&tcp, &cylinder.axis)
        );
        // Straight down, the fingertips just above the belt, the jaws on the body's span.
        let tool_axis = tcp.rotation * Vector3::z();
        assert!(tool_axis.z < -0.8, "yaw {yaw_deg}: tool axis {tool_axis:?}");
        let along = (tcp.translation.vector - cylinder.centre.coords).dot(&cylinder.axis);
        let [from, to] = cylinder.grip_span_m;
        assert!(
            along >= from && along <= to,
            "yaw {yaw_deg}: grip at {along:.3} m"
        );
        assert!(
            (tcp.translation.z - (BELT_TOP_Z + GRASP_TCP_ABOVE_BOTTOM_M)).abs() < 0.02,
            "yaw {yaw_deg}: {tcp:?}"
        );
        assert!(picked.pick.clearance_m >= CLEARANCE_CAP_M - 1e-9);
        // Light and wide enough: open past the body, close on its radius.
        assert!((picked.open_m - (BOTTLE_RADIUS_M + OPEN_CLEARANCE_M)).abs() < 1e-4);
        assert_eq!(picked.grip_m, BOTTLE_RADIUS_M);
    }
}

#[test]
fn a_bottle_lying_across_the_parts_only_clear_side_is_gripped_clear_of_the_part() {
    let planner = planner();
    let xy = [0.05, -0.45];
    for open_side_deg in [90.0_f64, 270.0, 0.0, 180.0] {
        let open_side = open_side_deg.to_radians();
        // Walls 10 mm from the part on two sides, 40 mm behind it: the jaws can only close
        // along the line from the back to the open side.
        let walls: Vec<PerceivedObstacle> = [(90.0_f64, 0.01), (180.0, 0.04), (270.0, 0.01)]
            .iter()
            .map(|(d, gap)| wall(xy, open_side + d.to_radians(), *gap))
            .collect();
        // The bottle lies across the open side, 2 mm from the part, its middle in front of it.
        let d = PART_RADIUS_M + 0.002 + BOTTLE_RADIUS_M;
        let middle = [xy[0] + d * open_side.cos(), xy[1] + d * open_side.sin()];
        let cylinder = bottle(middle, true, open_side + std::f64::consts::FRAC_PI_2);
        // Boxed in on three sides and blocked on the fourth, the part has no clear grasp...
        let mut obstacles = walls.clone();
        obstacles.push(cylinder.obstacle.clone());
        let blocked = percept(xy, obstacles);
        let refused = planner.plan_pick(&blocked, &planner.checker_for(&blocked), &home());
        let Err(refusal) = refused else {
            panic!("side {open_side_deg}: the blocked part was picked");
        };
        assert_eq!(refusal.reason, FailureReason::Collision, "{refusal:?}");
        // ...and one once the bottle is gone.
        let freed = percept(xy, walls.clone());
        let pick = planner.plan_pick(&freed, &planner.checker_for(&freed), &home());
        assert!(pick.is_ok(), "side {open_side_deg}: {pick:?}");
        // The bottle is gripped away from the part, clear of it and the walls.
        let mut others = walls;
        others.push(part(xy));
        let picked = planner.plan_cylinder_pick(&cylinder, &others, &home(), 1.0);
        let Ok(picked) = picked else {
            panic!("side {open_side_deg}: no grasp of the blocking bottle: {picked:?}");
        };
        assert!(
            picked.pick.clearance_m >= PLANNING_MARGIN_M,
            "side {open_side_deg}: {:.4}",
            picked.pick.clearance_m
        );
        let tcp = grasp_tcp(&planner, &picked);
        let along = (tcp.translation.vector - cylinder.centre.coords).dot(&cylinder.axis);
        assert!(
            along.abs() > PART_RADIUS_M + 0.015,
            "side {open_side_deg}: gripped {along:.3} m from the middle, in front of the part"
        );
        assert!(off_square_deg(&tcp, &cylinder.axis) <= 30.0 + 1e-6);
    }
}

#[test]
fn a_standing_bottle_two_millimetres_from_the_part_is_gripped_below_the_palm() {
    let planner = planner();
    let xy = [0.05, -0.45];
    for side_deg in [0.0_f64, 90.0, 200.0, 300.0] {
        let side = side_deg.to_radians();
        let d = PART_RADIUS_M + 0.002 + BOTTLE_RADIUS_M;
        let cylinder = bottle([xy[0] + d * side.cos(), xy[1] + d * side.sin()], false, 0.0);
        let picked = planner.plan_cylinder_pick(&cylinder, &[part(xy)], &home(), 1.0);
        let Ok(picked) = picked else {
            panic!("side {side_deg}: no grasp of the standing bottle: {picked:?}");
        };
        assert!(picked.pick.clearance_m >= PLANNING_MARGIN_M);
        let tcp = grasp_tcp(&planner, &picked);
        // Over its axis, the palm 75 mm above the TCP just clearing its top, the fingertips
        // (15 mm below the TCP) on the body below the shoulder.
        let top_z = BELT_TOP_Z + BOTTLE_LENGTH_M;
        let dxy = (tcp.translation.vector - cylinder.centre.coords)
            .xy()
            .norm();
        assert!(dxy < 1e-3, "side {side_deg}: {dxy}");
        let palm_z = tcp.translation.z + 0.075;
        assert!(
            palm_z >= top_z + PLANNING_MARGIN_M - 1e-4,
            "side {side_deg}: {palm_z}"
        );
        assert!(tcp.translation.z - 0.015 < BELT_TOP_Z + 0.7 * BOTTLE_LENGTH_M - 0.015);
        // Gripped that high, the fingers pass over the part beside it.
        assert!(tcp.translation.z - 0.015 > BELT_TOP_Z + PART_HEIGHT_M + PLANNING_MARGIN_M);
    }
}

#[test]
fn a_standing_cylinder_taller_than_the_fingers_reach_is_refused() {
    let planner = planner();
    let mut cylinder = bottle([0.05, -0.45], false, 0.0);
    // Pads only on its lowest 30 mm.
    cylinder.grip_span_m = [-0.1, -0.07];
    let refused = planner.plan_cylinder_pick(&cylinder, &[], &home(), 1.0);
    let Err(failure) = refused else {
        panic!("gripped a body the fingers cannot reach");
    };
    assert_eq!(failure.reason, FailureReason::Unreachable);
}

/// The carried body's pose in the world where `drop` lets it go.
fn released(planner: &PickPlanner, picked: &CylinderPick, drop: &PlacePlan) -> Isometry3<f64> {
    let Some(q) = drop.lower.end() else {
        panic!("empty lowering");
    };
    planner.world_from_base * tcp_pose(&planner.model, &q) * picked.carried.tcp_from_shape
}

/// The lowest point of the carried body let go where `drop` lets it go, world z, m.
fn released_lowest_z(planner: &PickPlanner, picked: &CylinderPick, drop: &PlacePlan) -> f64 {
    let pose = released(planner, picked, drop);
    let aabb = picked
        .carried
        .shape
        .compute_aabb(&crate::math::pose_to_physics(&pose));
    f64::from(aabb.mins.z)
}

#[test]
fn a_picked_bottle_is_set_down_low_in_an_empty_bin() {
    // Dropped from above the rim, a standing bottle falls the bin's depth and topples, or lands
    // across the rim when it has turned in the jaws; set down, it stays. Drawn over bins (0.2-0.3
    // m) and bottles' yaws, standing and lying: a standing one is always set down just over the
    // floor over the middle; a lying one, as long as the bin is wide, where the jaws clear the
    // walls (along one, or along the middle's diagonal), else just above the rim.
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(25);
    for draw in 0..4 {
        let bin = waste_bin(&mut rng);
        for lying in [true, false] {
            let cylinder = bottle([0.05, -0.45], lying, rng.range(0.0, 3.0));
            let Ok(picked) = planner.plan_cylinder_pick(&cylinder, &[], &home(), 1.0) else {
                panic!("no grasp (lying {lying})");
            };
            let drop = planner.plan_drop(&picked, &bin, &[]);
            let Ok((drop, rests)) = drop else {
                panic!("draw {draw}: no drop (lying {lying}): {drop:?}");
            };
            let pose = released(&planner, &picked, &drop);
            let lowest_z = released_lowest_z(&planner, &picked, &drop);
            let floor_z = bin.floor_center.z;
            let rim_z = floor_z + bin.wall_height;
            let low = lowest_z > floor_z + 0.008 && lowest_z < floor_z + 0.03;
            let over_rim = lowest_z > rim_z && lowest_z < rim_z + 0.05;
            assert!(
                low || (lying && over_rim),
                "draw {draw}, lying {lying}: let go with its bottom at {lowest_z:.3} m, floor at \
                 {floor_z:.3} m, rim at {rim_z:.3} m"
            );
            // An empty bin: a standing body's middle over its middle; a lying one (gripped off
            // its middle, where its straight body is) over the middle or along a wall, within
            // the walls either way.
            let off = (pose.translation.vector - bin.floor_center).xy().norm();
            assert!(
                lying || off < 1e-3,
                "draw {draw}, lying {lying}: {off} m off the middle"
            );
            let aabb = picked
                .carried
                .shape
                .compute_aabb(&crate::math::pose_to_physics(&pose));
            for i in 0..2 {
                let half = bin.size[i] / 2.0;
                let (lo, hi) = (
                    f64::from(aabb.mins[i]) - bin.floor_center[i],
                    f64::from(aabb.maxs[i]) - bin.floor_center[i],
                );
                assert!(
                    lo > -half && hi < half,
                    "draw {draw}, lying {lying}: let go over the wall ({lo:.3}..{hi:.3} m, half \
                     {half:.3} m)"
                );
            }
            // Where it will rest: on the floor, under where it was let go.
            let rest = rests.world_from_shape.translation.vector;
            assert!((rest.xy() - pose.translation.vector.xy()).norm() < 1e-9);
            assert!(rest.z < pose.translation.vector.z);
        }
    }
}

#[test]
fn a_bottle_is_not_set_down_onto_what_the_bin_holds() {
    // A bin whose floor is covered (a low body over all of it): no spot is clear, and the bottle
    // is let go over the middle above the rim, not lowered onto what lies there.
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(2026);
    for draw in 0..3 {
        let bin = waste_bin(&mut rng);
        let floor = bin.floor_center;
        let cover = crate::planning::cylinder_obstacle(
            "bottle",
            &nalgebra::Point3::new(floor.x, floor.y, floor.z + 0.02),
            &Vector3::z(),
            bin.size[0] * 0.7,
            0.04,
        );
        for lying in [true, false] {
            let cylinder = bottle([0.05, -0.45], lying, rng.range(0.0, 3.0));
            let Ok(picked) = planner.plan_cylinder_pick(&cylinder, &[], &home(), 1.0) else {
                panic!("no grasp (lying {lying})");
            };
            let drop = planner.plan_drop(&picked, &bin, std::slice::from_ref(&cover));
            let Ok((drop, _)) = drop else {
                panic!("draw {draw}: no drop (lying {lying}): {drop:?}");
            };
            let lowest_z = released_lowest_z(&planner, &picked, &drop);
            let rim_z = floor.z + bin.wall_height;
            assert!(
                lowest_z > rim_z,
                "draw {draw}, lying {lying}: let go at {lowest_z:.3} m, below the rim at \
                 {rim_z:.3} m, onto what the bin holds"
            );
        }
    }
}

#[test]
fn bottles_removed_one_after_another_are_let_go_clear_of_those_already_in_the_bin() {
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(2025);
    for draw in 0..3 {
        let bin = waste_bin(&mut rng);
        let mut in_bin: Vec<PerceivedObstacle> = Vec::new();
        for k in 0..3 {
            let cylinder = bottle([rng.range(0.0, 0.1), -0.45], false, 0.0);
            let Ok(picked) = planner.plan_cylinder_pick(&cylinder, &[], &home(), 1.0) else {
                panic!("no grasp");
            };
            let drop = planner.plan_drop(&picked, &bin, &in_bin);
            let Ok((drop, rests)) = drop else {
                panic!("draw {draw}: no drop for bottle {k}: {drop:?}");
            };
            let pose = crate::math::pose_to_physics(&released(&planner, &picked, &drop));
            for other in &in_bin {
                let other_pose = crate::math::pose_to_physics(&other.world_from_shape);
                let gap = rapier3d::parry::query::distance(
                    &pose,
                    picked.carried.shape.as_ref(),
                    &other_pose,
                    other.shape.as_ref(),
                )
                .map_or(0.0, |d| f64::from(d.distance));
                assert!(
                    gap > 0.0,
                    "draw {draw}: bottle {k} let go onto an earlier one"
                );
            }
            in_bin.push(rests);
        }
    }
}

#[test]
fn a_bottle_gripped_at_a_lean_is_let_go_as_it_stood_or_lay() {
    // Held at a lean, a standing bottle carried with the tool pointing straight down hangs askew
    // in the jaws; the drop undoes the grasp's lean. Drawn over bins, yaws and leans of either
    // sign up to the grasps' 35 degrees.
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(2605);
    for draw in 0..6 {
        let bin = waste_bin(&mut rng);
        for lying in [true, false] {
            let cylinder = bottle([0.05, -0.45], lying, rng.range(0.0, 3.0));
            let Ok(mut picked) = planner.plan_cylinder_pick(&cylinder, &[], &home(), 1.0) else {
                panic!("no grasp (lying {lying})");
            };
            // The same body as a grasp leaned by `lean` about the jaw line would hold it.
            let lean = rng.range(10.0, 35.0).to_radians() * if draw % 2 == 0 { 1.0 } else { -1.0 };
            picked.carried.tcp_from_shape =
                Isometry3::rotation(Vector3::x() * lean) * picked.carried.tcp_from_shape;
            let drop = planner.plan_drop(&picked, &bin, &[]);
            let Ok((drop, _)) = drop else {
                panic!("draw {draw}: no drop (lying {lying}): {drop:?}");
            };
            let axis = released(&planner, &picked, &drop).rotation * Vector3::y();
            let off_deg = if lying {
                axis.z.abs().asin().to_degrees()
            } else {
                axis.z.abs().min(1.0).acos().to_degrees()
            };
            assert!(
                off_deg < 1.0,
                "draw {draw}, lying {lying}, lean {:.1} deg: let go {off_deg:.1} deg off",
                lean.to_degrees()
            );
        }
    }
}

#[test]
fn lying_bottles_removed_one_after_another_are_set_down_side_by_side_in_a_tote() {
    // A tote about 400 x 300 mm takes two 200 mm bottles lying side by side along its longer
    // walls, both set down low; one laid along the middle's diagonal would leave the second no
    // clear spot. Drawn over tote sizes and places, and the bottles' yaws on the belt.
    let planner = planner();
    let mut rng = crate::rng::SimRng::new(4315);
    for draw in 0..3 {
        let (long, short) = (rng.range(0.38, 0.45), rng.range(0.28, 0.32));
        let size = if draw % 2 == 0 {
            [long, short]
        } else {
            [short, long]
        };
        let bin = BinBody {
            name: "waste".into(),
            floor_center: Vector3::new(rng.range(0.42, 0.48), rng.range(-0.08, -0.02), 0.5),
            size,
            wall_height: 0.08,
        };
        let mut in_bin: Vec<PerceivedObstacle> = Vec::new();
        for k in 0..2 {
            let cylinder = bottle([rng.range(0.0, 0.1), -0.45], true, rng.range(0.0, 3.0));
            let Ok(picked) = planner.plan_cylinder_pick(&cylinder, &[], &home(), 1.0) else {
                panic!("no grasp");
            };
            let drop = planner.plan_drop(&picked, &bin, &in_bin);
            let Ok((drop, rests)) = drop else {
                panic!("draw {draw}: no drop for bottle {k}: {drop:?}");
            };
            let lowest_z = released_lowest_z(&planner, &picked, &drop);
            assert!(
                lowest_z < bin.floor_center.z + 0.03,
                "draw {draw}, bin {size:?}: bottle {k} let go with its bottom {:.3} m over the \
                 floor",
                lowest_z - bin.floor_center.z
            );
            let pose = crate::math::pose_to_physics(&released(&planner, &picked, &drop));
            for other in &in_bin {
                let other_pose = crate::math::pose_to_physics(&other.world_from_shape);
                let gap = rapier3d::parry::query::distance(
                    &pose,
                    picked.carried.shape.as_ref(),
                    &other_pose,
                    other.shape.as_ref(),
                )
                .map_or(0.0, |d| f64::from(d.distance));
                assert!(gap > 0.0, "draw {draw}: bottle {k} set down onto the first");
            }
            in_bin.push(rests);
        }
    }
}
