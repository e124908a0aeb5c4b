//! The planner knows the arm's links by the joints that move them, not by the names the shipped
//! AUBO i5 description gives them: the same arm under other link and joint names (a vendor's
//! description, as a user brings it) gets the same collision shapes on the same frames, and
//! sorts the same trials the same way. The planner used to match the AUBO i5's link names and
//! leave every other arm's links out of its collision checks.

mod common;

use std::path::Path;

use twincell::cell::{Cell, CellModel, UrdfSource};
use twincell::kinematics::BUILTIN_URDF;
use twincell::planning::{LinkMount, PickPlanner};
use twincell::rng::SimRng;

/// The shipped description with its arm's links and joints renamed in another vendor's style.
fn renamed_urdf() -> String {
    let renames = [
        ("base_link", "base"),
        ("shoulder_Link", "link_1"),
        ("upperArm_Link", "link_2"),
        ("foreArm_Link", "link_3"),
        ("wrist1_Link", "link_4"),
        ("wrist2_Link", "link_5"),
        ("wrist3_Link", "link_6"),
        ("shoulder_joint", "joint_1"),
        ("upperArm_joint", "joint_2"),
        ("foreArm_joint", "joint_3"),
        ("wrist1_joint", "joint_4"),
        ("wrist2_joint", "joint_5"),
        ("wrist3_joint", "joint_6"),
    ];
    let mut text = BUILTIN_URDF.to_owned();
    for (from, to) in renames {
        text = text.replace(&format!("\"{from}\""), &format!("\"{to}\""));
    }
    assert!(!text.contains("upperArm"), "a name left");
    text
}

/// The planner's robot shapes of paper_50's cell with `urdf`: each shape's mount and its pose
/// on it, in order.
fn planner_shapes(urdf: Option<UrdfSource>) -> Vec<(LinkMount, [f64; 7])> {
    let model = CellModel::with_urdf(common::paper_50(), urdf).expect("cell model");
    let cell = Cell::build(&model, &mut SimRng::new(1)).expect("cell");
    PickPlanner::for_cell(&model, &cell)
        .robot_shapes
        .iter()
        .map(|s| {
            let t = s.mount_from_shape.translation.vector;
            let q = s.mount_from_shape.rotation.quaternion().coords;
            (s.mount, [t.x, t.y, t.z, q.x, q.y, q.z, q.w])
        })
        .collect()
}

#[test]
fn renamed_links_get_the_same_collision_shapes_on_the_same_frames() {
    let shipped = planner_shapes(None);
    let renamed = planner_shapes(Some(UrdfSource {
        path: Path::new("renamed.urdf").to_path_buf(),
        text: renamed_urdf(),
    }));
    // Upper arm, forearm, three wrists, the gripper's body, two fingers.
    eprintln!("{} shapes", shipped.len());
    assert!(shipped.len() >= 8, "{} shapes", shipped.len());
    assert!(
        shipped.iter().any(|(m, _)| *m == LinkMount::Dh(2)),
        "no upper arm"
    );
    assert_eq!(renamed, shipped);
}

#[test]
fn a_renamed_arm_sorts_the_same_trials_the_same_way() {
    let dir = common::out_dir("arm_link_names", "runs");
    std::fs::write(dir.join("renamed.urdf"), renamed_urdf()).expect("write urdf");
    let mut records = Vec::new();
    for (name, robot) in [
        ("shipped", String::new()),
        ("renamed", "[robot]\nurdf = \"renamed.urdf\"\n".to_owned()),
    ] {
        let body = format!("name = \"arm\"\ntrials = 6\n{robot}");
        let file = common::extending(&dir, name, "paper_50.toml", &body);
        let out = dir.join(name);
        common::run_oracle(&file, &out);
        records.push(common::without_timing(&out));
    }
    assert_eq!(records[0].len(), 6);
    assert_eq!(records[1], records[0]);
}
