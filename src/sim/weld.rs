//! Welds each link that hangs on a fixed joint into its parent before the arm enters the world.
//!
//! A link on a fixed joint moves with its parent. Welded, its colliders ride on the parent's body
//! at the same place and its inertia is added to the parent's, so the arm has the same motion
//! with fewer bodies to place each step. Links without any geometry or inertia (a `world` anchor, a
//! tool-centre frame) the loader already drops.

use rapier3d::na::Matrix3;
use rapier3d::prelude::*;
use rapier3d_urdf::UrdfRobot;
use rapier3d_urdf::urdf_rs::{Inertial, Robot};

/// A loaded robot whose fixed joints are welded, and where each collider came from.
pub(super) struct WeldedRobot {
    /// The links (fewer than the URDF's when fixed joints were welded) and moving joints.
    pub robot: UrdfRobot,
    /// Per link of `robot`, per collider in its order: the index in the URDF's `links` of the
    /// link the collider was declared on.
    pub collider_sources: Vec<Vec<usize>>,
}

/// Welds every link on a fixed joint of `robot` (loaded from `description`) into its parent:
/// its colliders move onto the parent's body at the same pose, its mass properties (as the
/// loader reads them from `<inertial>`) add to the parent's, and the joints it carried are
/// re-anchored on the parent. Bodies must still be at the poses the loader placed them.
pub(super) fn weld_fixed_links(mut robot: UrdfRobot, description: &Robot) -> WeldedRobot {
    let mut collider_sources: Vec<Vec<usize>> = robot
        .links
        .iter()
        .map(|link| vec![link.urdf_link_index; link.colliders.len()])
        .collect();
    let mut mass: Vec<Option<MassProperties>> = vec![None; robot.links.len()];
    while let Some(index) = robot
        .joints
        .iter()
        .position(|joint| joint.joint.locked_axes == JointAxesMask::LOCKED_FIXED_AXES)
    {
        let welded = robot.joints.remove(index);
        let (host, child) = (welded.link1, welded.link2);
        let host_pose = *robot.links[host].body.position();
        let host_from_child = host_pose.inverse() * *robot.links[child].body.position();

        let own_mass = |links: &[rapier3d_urdf::UrdfLink], i: usize| {
            link_mass(&description.links[links[i].urdf_link_index].inertial)
        };
        let child_mass = mass[child].unwrap_or_else(|| own_mass(&robot.links, child));
        let host_mass = mass[host].unwrap_or_else(|| own_mass(&robot.links, host));
        let combined = host_mass + child_mass.transform_by(&host_from_child);
        robot.links[host]
            .body
            .set_additional_mass_properties(combined, false);
        mass[host] = Some(combined);

        let mut colliders = std::mem::take(&mut robot.links[child].colliders);
        for collider in &mut colliders {
            let pose = host_from_child * *collider.collider.position();
            collider.collider.set_position(pose);
        }
        robot.links[host].colliders.extend(colliders);
        let sources = std::mem::take(&mut collider_sources[child]);
        collider_sources[host].extend(sources);

        for joint in &mut robot.joints {
            if joint.link1 == child {
                joint.link1 = host;
                joint.joint.local_frame1 = host_from_child * joint.joint.local_frame1;
            }
        }
        robot.links.remove(child);
        collider_sources.remove(child);
        mass.remove(child);
        for joint in &mut robot.joints {
            for link in [&mut joint.link1, &mut joint.link2] {
                if *link > child {
                    *link -= 1;
                }
            }
        }
    }
    WeldedRobot {
        robot,
        collider_sources,
    }
}

/// A link's mass properties in its own frame, as the URDF loader builds them from `<inertial>`.
fn link_mass(inertial: &Inertial) -> MassProperties {
    let [x, y, z] = inertial.origin.xyz.0.map(|v| v as f32);
    let i = &inertial.inertia;
    let inertia = Matrix3::new(
        i.ixx as f32,
        i.ixy as f32,
        i.ixz as f32,
        i.ixy as f32,
        i.iyy as f32,
        i.iyz as f32,
        i.ixz as f32,
        i.iyz as f32,
        i.izz as f32,
    );
    MassProperties::with_inertia_matrix(
        Vector::new(x, y, z),
        inertial.mass.value as f32,
        inertia.into(),
    )
}

#[cfg(test)]
mod tests {
    use rapier3d_urdf::{UrdfLoaderOptions, UrdfMultibodyOptions};

    use super::*;
    use crate::sim::{World, WorldParams};

    /// A base, a link on a revolute joint, a box on a fixed joint off that link, and a finger
    /// on a prismatic joint off the box.
    const CHAIN: &str = r#"<robot name="chain">
      <link name="base"><inertial><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
        <collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
      <link name="arm"><inertial><origin xyz="0 0 0.1" rpy="0 0 0"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.002"/></inertial>
        <collision><origin xyz="0 0 0.1" rpy="0 0 0"/><geometry><cylinder radius="0.03" length="0.2"/></geometry></collision></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.05" rpy="0 0 0"/>
        <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
      <link name="hand"><inertial><origin xyz="0 0 0.02" rpy="0 0 0"/><mass value="0.5"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.003"/></inertial>
        <collision><origin xyz="0 0 0.02" rpy="0 0 0"/><geometry><box size="0.08 0.04 0.04"/></geometry></collision></link>
      <joint name="fix" type="fixed"><parent link="arm"/><child link="hand"/><origin xyz="0.01 0 0.2" rpy="0 1.5707963 0"/></joint>
      <link name="finger"><inertial><mass value="0.1"/><inertia ixx="0.0001" ixy="0" ixz="0" iyy="0.0001" iyz="0" izz="0.0001"/></inertial>
        <collision><geometry><box size="0.01 0.01 0.05"/></geometry></collision></link>
      <joint name="slide" type="prismatic"><parent link="hand"/><child link="finger"/><origin xyz="0 0 0.04" rpy="0 0 0"/>
        <axis xyz="1 0 0"/><limit lower="0" upper="0.05" effort="10" velocity="0.1"/></joint>
    </robot>"#;

    fn load() -> (Robot, UrdfRobot) {
        let description = rapier3d_urdf::urdf_rs::read_from_string(CHAIN).expect("parse");
        let options = UrdfLoaderOptions {
            make_roots_fixed: true,
            ..UrdfLoaderOptions::default()
        };
        let robot = UrdfRobot::from_robot(&description, options, std::path::Path::new("."));
        (description, robot)
    }

    /// Every collider's world pose, keyed by the URDF link it was declared on.
    fn collider_poses(robot: &UrdfRobot, sources: &[Vec<usize>]) -> Vec<(usize, Pose)> {
        let mut poses: Vec<(usize, Pose)> = robot
            .links
            .iter()
            .zip(sources)
            .flat_map(|(link, sources)| {
                let body = *link.body.position();
                link.colliders
                    .iter()
                    .zip(sources)
                    .map(move |(c, &s)| (s, body * *c.collider.position()))
            })
            .collect();
        poses.sort_by_key(|(s, _)| *s);
        poses
    }

    #[test]
    fn welding_keeps_every_collider_where_it_was_and_the_total_mass() {
        let (description, robot) = load();
        let before_sources: Vec<Vec<usize>> = robot
            .links
            .iter()
            .map(|l| vec![l.urdf_link_index; l.colliders.len()])
            .collect();
        let before = collider_poses(&robot, &before_sources);
        let welded = weld_fixed_links(robot, &description);
        assert_eq!(
            welded.robot.links.len(),
            3,
            "base, arm with the hand, finger"
        );
        assert_eq!(
            welded.robot.joints.len(),
            2,
            "the revolute and the prismatic joint"
        );
        let after = collider_poses(&welded.robot, &welded.collider_sources);
        assert_eq!(before.len(), after.len());
        for ((s0, p0), (s1, p1)) in before.iter().zip(&after) {
            assert_eq!(s0, s1);
            assert!((p0.translation - p1.translation).length() < 1e-6, "{s0}");
            assert!(p0.rotation.dot(p1.rotation).abs() > 1.0 - 1e-6, "{s0}");
        }
        // The finger now hangs on the arm's body, 4 cm out along the hand's z axis.
        let slide = &welded.robot.joints[1];
        assert_eq!((slide.link1, slide.link2), (1, 2));
        let anchor = slide.joint.local_frame1.translation;
        assert!(
            (anchor - Vector::new(0.01 + 0.04, 0.0, 0.2)).length() < 1e-5,
            "{anchor:?}"
        );
        // The arm's body carries its own and the hand's mass, with the hand's centre of mass
        // where it was: 2 cm out along the hand's z axis, which the weld turned onto the arm's x.
        let mut world = World::new(WorldParams::default());
        let physics = &mut world.physics;
        let handles = welded.robot.insert_using_multibody_joints(
            &mut physics.bodies,
            &mut physics.colliders,
            &mut physics.multibody_joints,
            UrdfMultibodyOptions::empty(),
        );
        world.step();
        let arm = &world.physics.bodies[handles.links[1].body];
        assert!((arm.mass() - 1.5).abs() < 1e-5, "mass {}", arm.mass());
        let com = arm.center_of_mass();
        let want = Vector::new(0.0, 0.0, 0.05)
            + (Vector::new(0.0, 0.0, 0.1) + Vector::new(0.03, 0.0, 0.2) * 0.5) / 1.5;
        assert!((com - want).length() < 1e-4, "{com:?} != {want:?}");
    }
}
