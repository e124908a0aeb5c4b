//! Kinematics against the official AUBO i5 description, and the inverse against the forward.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use twincell::kinematics::{
    AnalyticIk, ArmModel, IkSolver, JointVector, flange_pose, geometric_jacobian, tcp_pose,
};
use twincell::rng::SimRng;

/// Joint origins of the official `aubo_i5.urdf` (xyz in m, rpy in rad), transcribed. The file
/// rounds pi to 3.1416 and pi/2 to 1.5708 and carries 1e-15-sized noise; `EXACT` reads those as
/// the right angles they stand for, `LITERAL` keeps the file's digits.
const EXACT: [([f64; 3], [f64; 3]); 6] = [
    ([0.0, 0.0, 0.122], [0.0, 0.0, PI]),
    ([0.0, 0.1215, 0.0], [-FRAC_PI_2, -FRAC_PI_2, 0.0]),
    ([0.408, 0.0, 0.0], [-PI, 0.0, 0.0]),
    ([0.376, 0.0, 0.0], [PI, 0.0, FRAC_PI_2]),
    ([0.0, 0.1025, 0.0], [-FRAC_PI_2, 0.0, 0.0]),
    ([0.0, -0.094, 0.0], [FRAC_PI_2, 0.0, 0.0]),
];
#[allow(clippy::approx_constant)]
const LITERAL: [([f64; 3], [f64; 3]); 6] = [
    ([0.0, 0.0, 0.122], [0.0, 0.0, 3.1416]),
    ([0.0, 0.1215, 0.0], [-1.5708, -1.5708, 0.0]),
    ([0.408, 0.0, 0.0], [-3.1416, -5.1632E-18, -5.459E-16]),
    ([0.376, 0.0, 0.0], [3.1416, -1.8323E-15, 1.5708]),
    ([0.0, 0.1025, 0.0], [-1.5708, -1.8709E-15, -1.6653E-16]),
    ([0.0, -0.094, 0.0], [1.5708, 0.0, 1.7907E-15]),
];

/// The URDF chain: each joint is `origin * RotZ(q)` (all axes are z).
fn urdf_flange(origins: &[([f64; 3], [f64; 3]); 6], q: &JointVector) -> Isometry3<f64> {
    let mut pose = Isometry3::identity();
    for ((xyz, rpy), &qi) in origins.iter().zip(q) {
        let origin = Isometry3::from_parts(
            Translation3::new(xyz[0], xyz[1], xyz[2]),
            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        );
        pose = pose * origin * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), qi);
    }
    pose
}

fn random_q(rng: &mut SimRng, arm: &ArmModel) -> JointVector {
    std::array::from_fn(|i| rng.range(arm.limits[i].min_rad, arm.limits[i].max_rad))
}

fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let position = (a.translation.vector - b.translation.vector).norm();
    let angle = a.rotation.angle_to(&b.rotation);
    (position, angle)
}

fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(TAU);
    d.min(TAU - d)
}

#[test]
fn fk_matches_official_urdf_chain_over_10000_random_vectors() {
    let arm = ArmModel::aubo_i5();
    let mut rng = SimRng::new(2024);
    let mut worst = (0.0f64, 0.0f64);
    let mut worst_literal = 0.0f64;
    for _ in 0..10_000 {
        let q = random_q(&mut rng, &arm);
        let (dp, da) = pose_error(&flange_pose(&arm, &q), &urdf_flange(&EXACT, &q));
        worst = (worst.0.max(dp), worst.1.max(da));
        let (dp_literal, _) = pose_error(&flange_pose(&arm, &q), &urdf_flange(&LITERAL, &q));
        worst_literal = worst_literal.max(dp_literal);
    }
    assert!(worst.0 < 1e-9 && worst.1 < 1e-9, "worst error {worst:?}");
    // The file's rounded pi moves the flange by at most a few micrometres.
    assert!(
        worst_literal < 2e-5,
        "worst against literal digits {worst_literal}"
    );
}

#[test]
fn fk_at_zero_is_the_straight_up_pose() {
    let arm = ArmModel::aubo_i5();
    let pose = flange_pose(&arm, &[0.0; 6]);
    let p = pose.translation.vector;
    // Upright arm: height = 0.122 + 0.408 + 0.376 + 0.1025; lateral offset 0.1215 - 0.094.
    assert!(
        (p.z - (0.122 + 0.408 + 0.376 + 0.1025)).abs() < 1e-12,
        "{p}"
    );
    // Shoulder offset 0.1215 plus the flange's d6 = 0.094, both towards -y.
    assert!(
        p.x.abs() < 1e-12 && (p.y + 0.1215 + 0.094).abs() < 1e-12,
        "{p}"
    );
}

fn assert_ik_round_trip(arm: &ArmModel, ik: &AnalyticIk, q: &JointVector) {
    let target = tcp_pose(arm, q);
    let solutions = ik.solve(&target);
    assert!(!solutions.is_empty(), "no solution for {q:?}");
    let found = solutions
        .as_slice()
        .iter()
        .any(|s| s.iter().zip(q).all(|(a, b)| angle_diff(*a, *b) < 1e-6));
    assert!(found, "{q:?} not among {:?}", solutions.as_slice());
    for s in solutions.as_slice() {
        assert!(s.iter().all(|v| v.is_finite()));
        arm.check_limits(s).expect("solution within limits");
        let (dp, da) = pose_error(&tcp_pose(arm, s), &target);
        assert!(
            dp < 1e-9 && da < 1e-9,
            "solution {s:?} misses by {dp} m, {da} rad"
        );
    }
}

#[test]
fn ik_round_trip_with_flange_and_tool() {
    let flange = ArmModel::aubo_i5();
    let tool = ArmModel::aubo_i5().with_tool(Isometry3::from_parts(
        Translation3::new(0.01, -0.02, 0.17),
        UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
    ));
    for arm in [flange, tool] {
        let ik = AnalyticIk::new(arm.clone()).expect("AUBO geometry");
        let mut rng = SimRng::new(99);
        for _ in 0..20_000 {
            let q = random_q(&mut rng, &arm);
            assert_ik_round_trip(&arm, &ik, &q);
        }
    }
}

#[test]
fn ik_finds_up_to_eight_distinct_solutions() {
    let arm = ArmModel::aubo_i5();
    let ik = AnalyticIk::new(arm.clone()).expect("AUBO geometry");
    let mut rng = SimRng::new(8);
    let mut histogram = [0usize; 9];
    for _ in 0..2000 {
        let q = random_q(&mut rng, &arm);
        let count = ik.solve(&flange_pose(&arm, &q)).len();
        assert!((1..=8).contains(&count), "{count} solutions for {q:?}");
        histogram[count] += 1;
    }
    // With limits of +-3.04 rad no 2pi variant fits, so eight is the most; many poses have all.
    assert!(histogram[8] > 100, "solution-count histogram {histogram:?}");
}

#[test]
fn singular_poses_give_finite_solutions() {
    let arm = ArmModel::aubo_i5();
    let ik = AnalyticIk::new(arm.clone()).expect("AUBO geometry");
    let singular = [
        // Wrist singular: q5 = 0.
        [0.2, 0.3, 1.0, -0.4, 0.0, 0.6],
        [-1.0, -0.5, 0.7, 1.1, 0.0, -2.0],
        // Elbow straight: edge of reach.
        [0.5, 0.2, 0.0, 0.3, 1.0, 0.0],
        // Both at once, straight up.
        [0.0; 6],
    ];
    let mut rng = SimRng::new(11);
    let mut random_singular = Vec::new();
    for _ in 0..2000 {
        let mut q = random_q(&mut rng, &arm);
        q[4] = 0.0;
        if rng.uniform() < 0.5 {
            q[2] = 0.0;
        }
        random_singular.push(q);
    }
    for q in singular.into_iter().chain(random_singular) {
        let target = flange_pose(&arm, &q);
        let solutions = ik.solve(&target);
        assert!(!solutions.is_empty(), "no solution for singular {q:?}");
        for s in solutions.as_slice() {
            assert!(s.iter().all(|v| v.is_finite()), "{s:?}");
            let (dp, da) = pose_error(&flange_pose(&arm, s), &target);
            assert!(dp < 1e-8 && da < 1e-8, "{s:?} misses by {dp} m {da} rad");
        }
    }
}

#[test]
fn out_of_reach_poses_give_no_solution() {
    let arm = ArmModel::aubo_i5();
    let ik = AnalyticIk::new(arm).expect("AUBO geometry");
    let far = Isometry3::translation(1.2, 0.3, 0.4);
    assert!(ik.solve(&far).is_empty());
    // On the base axis: inside the shoulder offset cylinder, no joint-1 angle works.
    let inside = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.5),
        UnitQuaternion::from_euler_angles(PI, 0.0, 0.0),
    );
    assert!(ik.solve(&inside).is_empty());
    let nan = Isometry3::translation(f64::NAN, 0.0, 0.3);
    assert!(ik.solve(&nan).is_empty());
}

#[test]
fn nearest_solution_is_the_reference_itself() {
    let arm = ArmModel::aubo_i5();
    let ik = AnalyticIk::new(arm.clone()).expect("AUBO geometry");
    let q = [1.0, -0.3, 1.5, 0.2, -1.1, 0.4];
    let nearest = ik
        .solve(&flange_pose(&arm, &q))
        .nearest(&q)
        .expect("solvable");
    assert!(
        nearest.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-7),
        "{nearest:?}"
    );
}

#[test]
fn jacobian_matches_finite_differences() {
    let arm = ArmModel::aubo_i5().with_tool(Isometry3::translation(0.0, 0.0, 0.15));
    let mut rng = SimRng::new(5);
    for _ in 0..200 {
        let q = random_q(&mut rng, &arm);
        let jacobian = geometric_jacobian(&arm, &q);
        let h = 1e-6;
        for joint in 0..6 {
            let mut plus = q;
            let mut minus = q;
            plus[joint] += h;
            minus[joint] -= h;
            let (p_plus, p_minus) = (tcp_pose(&arm, &plus), tcp_pose(&arm, &minus));
            let linear = (p_plus.translation.vector - p_minus.translation.vector) / (2.0 * h);
            let angular = (p_plus.rotation * p_minus.rotation.inverse()).scaled_axis() / (2.0 * h);
            for row in 0..3 {
                assert!((jacobian[(row, joint)] - linear[row]).abs() < 1e-6);
                assert!((jacobian[(row + 3, joint)] - angular[row]).abs() < 1e-6);
            }
        }
    }
}

fn joint_strategy() -> impl Strategy<Value = JointVector> {
    prop::array::uniform6(-3.04f64..3.04)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn prop_ik_contains_q_and_reproduces_pose(q in joint_strategy()) {
        let arm = ArmModel::aubo_i5();
        let ik = AnalyticIk::new(arm.clone()).expect("AUBO geometry");
        assert_ik_round_trip(&arm, &ik, &q);
    }

    #[test]
    fn prop_random_poses_never_give_nan(
        xyz in prop::array::uniform3(-1.2f64..1.2),
        rpy in prop::array::uniform3(-PI..PI),
    ) {
        let arm = ArmModel::aubo_i5();
        let ik = AnalyticIk::new(arm.clone()).expect("AUBO geometry");
        let target = Isometry3::from_parts(
            Translation3::new(xyz[0], xyz[1], xyz[2]),
            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        );
        for s in ik.solve(&target).as_slice() {
            prop_assert!(s.iter().all(|v| v.is_finite()));
            let (dp, da) = pose_error(&flange_pose(&arm, s), &target);
            prop_assert!(dp < 1e-9 && da < 1e-9);
        }
    }
}
