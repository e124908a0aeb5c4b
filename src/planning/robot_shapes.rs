//! The robot's collision shapes for the planner, read once from the simulated arm.

use nalgebra::Isometry3;

use super::{LinkMount, RobotShape};
use crate::kinematics::{ArmModel, DOF, link_frames};
use crate::math::pose_from_physics;
use crate::sim::{FINGER_LINKS, SimArm, World};

/// The robot's collision shapes, mounted on DH frames, captured from the simulated arm standing
/// at `q` (before the world has stepped).
pub fn capture_robot_shapes(
    world: &World,
    arm: &SimArm,
    model: &ArmModel,
    q: &[f64; DOF],
) -> Vec<RobotShape> {
    let frames = link_frames(model, q);
    let base_from_world = arm.world_from_base().inverse();
    let mut shapes = Vec::new();
    for link in arm.links() {
        let name = &link.name;
        // Each link by the joint that moves it, whatever the URDF calls it; the fingers are
        // the twin's own gripper's, named by it.
        let mount = if name == FINGER_LINKS[0] {
            LinkMount::Finger { sign: 1.0 }
        } else if name == FINGER_LINKS[1] {
            LinkMount::Finger { sign: -1.0 }
        } else {
            match arm.joint_moving(link) {
                // The base and the shoulder (the first joint's link) sit on the pedestal by
                // design; they are not checked.
                None | Some(0) => continue,
                Some(joint) => LinkMount::Dh(joint + 1),
            }
        };
        let mount_frame = match mount {
            LinkMount::Dh(k) => frames[k],
            LinkMount::Finger { .. } => frames[DOF],
        };
        let Some(rb) = world.physics.bodies.get(link.body) else {
            continue;
        };
        for handle in &link.colliders {
            let Some(collider) = world.physics.colliders.get(*handle) else {
                continue;
            };
            // Colliders' world poses lag their bodies until the next step; compose from the body.
            let body_from_collider = collider
                .position_wrt_parent()
                .map_or_else(Isometry3::identity, pose_from_physics);
            let shape_in_base =
                base_from_world * pose_from_physics(rb.position()) * body_from_collider;
            shapes.push(RobotShape {
                link: name.clone(),
                mount,
                mount_from_shape: mount_frame.inverse() * shape_in_base,
                shape: collider.shared_shape().clone(),
            });
        }
    }
    shapes
}
