//! The arm's kinematic model read from its URDF: the shipped arm gets its published table, an
//! arm of the same family with other lengths, offsets, link frames and axis directions gets its
//! own, and one the closed form cannot solve is refused with the reason.

use std::fmt::Write as _;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use twincell::kinematics::{
    AnalyticIk, ArmModel, BUILTIN_URDF, DhRow, IkSolver, JointVector, UrdfArm, flange_pose,
    gripper_tcp, tcp_pose,
};
use twincell::rng::SimRng;

mod common;

/// One joint of a generated arm: its origin in the parent link and its axis in its own frame.
struct JointSpec {
    origin: Isometry3<f64>,
    axis: Vector3<f64>,
}

/// A URDF of six revolute joints `joints`, then the gripper mount and TCP links the twin needs.
fn urdf_text(joints: &[JointSpec]) -> String {
    let mut text = String::from("<robot name=\"generated\">\n<link name=\"base_link\"/>\n");
    let mut parent = "base_link".to_owned();
    for (i, joint) in joints.iter().enumerate() {
        let child = format!("link{}", i + 1);
        let (r, p, y) = joint.origin.rotation.euler_angles();
        let t = joint.origin.translation.vector;
        let a = joint.axis;
        let _ = write!(
            text,
            "<link name=\"{child}\"/>\n<joint name=\"j{}\" type=\"revolute\">\
             <origin xyz=\"{} {} {}\" rpy=\"{r} {p} {y}\"/><parent link=\"{parent}\"/>\
             <child link=\"{child}\"/><axis xyz=\"{} {} {}\"/>\
             <limit lower=\"-3.0\" upper=\"3.0\" effort=\"100\" velocity=\"2.5\"/></joint>\n",
            i + 1,
            t.x,
            t.y,
            t.z,
            a.x,
            a.y,
            a.z
        );
        parent = child;
    }
    let _ = write!(
        text,
        "<link name=\"gripper_Link\"/><joint name=\"mount\" type=\"fixed\">\
         <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/><parent link=\"{parent}\"/>\
         <child link=\"gripper_Link\"/></joint>\n\
         <link name=\"tcp_Link\"/><joint name=\"tcp\" type=\"fixed\">\
         <origin xyz=\"0 0 0.125\" rpy=\"0 0 0\"/><parent link=\"{parent}\"/>\
         <child link=\"tcp_Link\"/></joint>\n</robot>\n"
    );
    text
}

/// The joints of an arm with DH table `dh` (closed-form twists), each link frame turned about
/// its joint's axis by a random angle away from its DH frame, and the axes of `reversed` joints
/// pointing the other way (a positive angle turns them backwards).
fn family_arm(dh: &[DhRow; 6], rng: &mut SimRng, reversed: &[usize]) -> Vec<JointSpec> {
    let base_from_dh0 = Isometry3::translation(rng.range(-0.05, 0.05), 0.0, rng.range(0.0, 0.1));
    let mut previous_turn = base_from_dh0;
    let mut joints = Vec::new();
    for (i, row) in dh.iter().enumerate() {
        let spin = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rng.range(-3.0, 3.0));
        let turn = Isometry3::from_parts(Translation3::identity(), spin);
        let direction = if reversed.contains(&i) { -1.0 } else { 1.0 };
        joints.push(JointSpec {
            origin: previous_turn * row.transform(0.0) * turn,
            axis: turn.rotation.inverse() * Vector3::z() * direction,
        });
        previous_turn = turn.inverse();
    }
    joints
}

fn random_family_dh(rng: &mut SimRng) -> [DhRow; 6] {
    let deg = std::f64::consts::PI / 180.0;
    [
        DhRow::new(0.0, 0.0, rng.range(0.05, 0.2)),
        DhRow::new(90.0 * deg, 0.0, rng.range(0.05, 0.2)),
        DhRow::new(180.0 * deg, rng.range(0.2, 0.6), rng.range(-0.05, 0.05)),
        DhRow::new(180.0 * deg, rng.range(0.2, 0.6), rng.range(-0.05, 0.05)),
        DhRow::new(-90.0 * deg, 0.0, rng.range(0.05, 0.15)),
        DhRow::new(90.0 * deg, 0.0, rng.range(0.05, 0.15)),
    ]
}

/// The flange of the URDF `joints` at angles `q`, by composing the chain directly.
fn chain_flange(joints: &[JointSpec], q: &JointVector) -> Isometry3<f64> {
    joints
        .iter()
        .zip(q)
        .fold(Isometry3::identity(), |pose, (j, &qi)| {
            let axis = nalgebra::Unit::new_normalize(j.axis);
            pose * j.origin * UnitQuaternion::from_axis_angle(&axis, qi)
        })
}

fn assert_ik_recovers(model: &ArmModel, rng: &mut SimRng) {
    let ik = AnalyticIk::new(model.clone()).expect("the closed form serves the arm");
    for _ in 0..40 {
        let q: JointVector = std::array::from_fn(|_| rng.range(-2.5, 2.5));
        let target = tcp_pose(model, &q);
        let solutions = ik.solve(&target);
        assert!(!solutions.is_empty(), "no solution for q = {q:?}");
        for s in solutions.as_slice() {
            let reached = tcp_pose(model, s);
            let error = (reached.translation.vector - target.translation.vector).norm();
            assert!(error < 1e-7, "solution misses by {error} m");
            assert!(reached.rotation.angle_to(&target.rotation) < 1e-7);
        }
    }
}

#[test]
fn the_shipped_urdf_gets_the_published_table_exactly() {
    let arm = UrdfArm::from_urdf_str(BUILTIN_URDF).expect("the shipped arm");
    assert_eq!(arm.model, ArmModel::aubo_i5().with_tool(gripper_tcp()));
    assert_eq!(arm.joints[0], "shoulder_joint");
    assert_eq!(arm.flange_link, "wrist3_Link");
    assert_eq!(arm.base_link, "world");
}

#[test]
fn arms_of_the_family_get_their_own_tables() {
    let mut rng = SimRng::new(2311);
    for case in 0..24 {
        let dh = random_family_dh(&mut rng);
        // Reverse some axes: a UR-style arm whose parallel axes all point one way, and others.
        let flipped: Vec<usize> = (0..6).filter(|_| rng.range(0.0, 1.0) < 0.4).collect();
        let joints = family_arm(&dh, &mut rng, &flipped);
        let text = urdf_text(&joints);
        let arm = UrdfArm::from_urdf_str(&text)
            .unwrap_or_else(|e| panic!("case {case} (flipped {flipped:?}): {e}"));
        for _ in 0..20 {
            let q: JointVector = std::array::from_fn(|_| rng.range(-3.0, 3.0));
            let by_table = flange_pose(&arm.model, &q);
            let by_chain = chain_flange(&joints, &q);
            let error = (by_table.translation.vector - by_chain.translation.vector).norm();
            assert!(error < 1e-7, "case {case}: flange {error} m off");
            assert!(by_table.rotation.angle_to(&by_chain.rotation) < 1e-7);
        }
        for (i, joint) in arm.model.limits.iter().enumerate() {
            assert_eq!((joint.min_rad, joint.max_rad), (-3.0, 3.0), "joint {i}");
            assert_eq!(joint.max_velocity_rad_s, 2.5);
        }
        assert_ik_recovers(&arm.model, &mut rng);
    }
}

#[test]
fn a_longer_link_moves_the_flange_by_its_length() {
    let longer = BUILTIN_URDF.replace(
        "<origin xyz=\"0.408 0 0\" rpy=\"-3.141592653589793 0 0\"/>",
        "<origin xyz=\"0.458 0 0\" rpy=\"-3.141592653589793 0 0\"/>",
    );
    assert_ne!(
        longer, BUILTIN_URDF,
        "the upper arm's joint origin was found"
    );
    let arm = UrdfArm::from_urdf_str(&longer).expect("the longer arm");
    let aubo = ArmModel::aubo_i5().with_tool(gripper_tcp());
    assert_ne!(arm.model, aubo);
    // Stretched out along the upper arm, the flange lies 5 cm further away.
    let q = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let stretch =
        flange_pose(&arm.model, &q).translation.vector - flange_pose(&aubo, &q).translation.vector;
    assert!((stretch.norm() - 0.05).abs() < 1e-9, "{stretch:?}");
    assert_ik_recovers(&arm.model, &mut SimRng::new(7));
}

#[test]
fn arms_the_closed_form_cannot_solve_are_refused_with_the_reason() {
    let mut rng = SimRng::new(99);
    let dh = random_family_dh(&mut rng);
    let good = family_arm(&dh, &mut rng, &[]);
    // The elbow's axis tilted 5 degrees out of parallel.
    let mut tilted = family_arm(&dh, &mut SimRng::new(99), &[]);
    tilted[2].axis = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.087) * tilted[2].axis;
    let cases = [
        (urdf_text(&tilted), "must be parallel"),
        (urdf_text(&good[..5]), "has 5 revolute joints"),
        (
            urdf_text(&good).replace("gripper_Link", "hand_Link"),
            "no link `gripper_Link`",
        ),
        ("<robot".to_owned(), "cannot be read"),
    ];
    for (text, expected) in cases {
        match UrdfArm::from_urdf_str(&text) {
            Ok(_) => panic!("accepted; expected `{expected}`"),
            Err(e) => assert!(e.to_string().contains(expected), "{e}"),
        }
    }
}

#[test]
fn a_scenario_with_another_arm_plans_with_its_geometry_and_a_bad_one_exits_2() {
    let dir = common::out_dir("urdf_arm", "scenario");
    let longer = BUILTIN_URDF.replace(
        "<origin xyz=\"0.408 0 0\" rpy=\"-3.141592653589793 0 0\"/>",
        "<origin xyz=\"0.458 0 0\" rpy=\"-3.141592653589793 0 0\"/>",
    );
    std::fs::write(dir.join("longer.urdf"), &longer).expect("writes");
    let paper = common::read(&common::scenario_path("paper_50.toml"));
    std::fs::write(dir.join("paper_50.toml"), &paper).expect("writes");
    let scenario = dir.join("longer.toml");
    std::fs::write(
        &scenario,
        "extends = \"paper_50.toml\"\nname = \"longer_arm\"\n[robot]\nurdf = \"longer.urdf\"\n",
    )
    .expect("writes");
    let out = dir.join("out");
    let (code, _, stderr) = common::twincell(&[
        "run",
        scenario.to_str().expect("path"),
        "--perception",
        "oracle",
        "--trials",
        "3",
        "--min-success",
        "1.0",
        "--out",
        out.to_str().expect("path"),
    ]);
    assert_eq!(code, 0, "the longer arm sorts every part: {stderr}");

    // Joints 2 and 3 no longer parallel: the closed form cannot serve it.
    let skewed = longer.replace(
        "<origin xyz=\"0.458 0 0\" rpy=\"-3.141592653589793 0 0\"/>",
        "<origin xyz=\"0.458 0 0\" rpy=\"-3.141592653589793 0.1 0\"/>",
    );
    std::fs::write(dir.join("skewed.urdf"), skewed).expect("writes");
    let bad = dir.join("skewed.toml");
    std::fs::write(
        &bad,
        "extends = \"paper_50.toml\"\nname = \"skewed_arm\"\n[robot]\nurdf = \"skewed.urdf\"\n",
    )
    .expect("writes");
    let (code, _, stderr) = common::twincell(&[
        "run",
        bad.to_str().expect("path"),
        "--trials",
        "1",
        "--out",
        dir.join("bad-out").to_str().expect("path"),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("skewed.toml"),
        "names the scenario: {stderr}"
    );
    assert!(stderr.contains("robot.urdf"), "names the key: {stderr}");
    assert!(stderr.contains("skewed.urdf"), "names the URDF: {stderr}");
    assert!(stderr.contains("must be parallel"), "says why: {stderr}");
}
