//! Joint limits handed to the solver only while a joint is near one.
//!
//! Rapier builds a limit constraint for every limited axis of a multibody joint in every
//! substep, wherever the joint is: an LU solve of the arm's mass matrix and a row in each
//! solver iteration. Away from its limits the row's impulse is bounded to zero on both sides
//! and it changes nothing; the motor's velocity target is clamped by the limits only within a
//! substep's travel of one. So a limit axis is declared to rapier only while the joint is
//! within [`LIMIT_MARGIN_RAD`] (revolute) or [`LIMIT_MARGIN_M`] (prismatic), plus
//! [`LOOKAHEAD_STEPS`] steps of travel at its speed or its motor's target speed, of either
//! end; the joint moves exactly as with the limit always on.

use rapier3d::prelude::*;

/// Angle from a revolute joint's limit within which the limit is always on, rad.
pub const LIMIT_MARGIN_RAD: f32 = 0.1;
/// Distance from a prismatic joint's limit within which the limit is always on, m.
pub const LIMIT_MARGIN_M: f32 = 0.01;
/// Steps of travel, at the larger of the joint's speed and its motor's target speed, added to
/// the margin.
pub const LOOKAHEAD_STEPS: f32 = 8.0;

/// The limit axes each multibody link's joint was given, and which are on now.
#[derive(Debug, Clone, Default)]
pub(super) struct LimitGate {
    /// Off: every declared limit is on, as rapier would have it.
    pub(super) enabled: bool,
    /// The limit axes a link's joint declared when first seen, by the link's body.
    declared: Vec<(RigidBodyHandle, JointAxesMask)>,
    /// Links whose limit axes must change before the step: body and the axes to set.
    changes: Vec<(RigidBodyHandle, JointAxesMask)>,
}

impl LimitGate {
    /// Nothing seen yet; `enabled` says whether limits far from the joint are left out.
    pub(super) fn new(enabled: bool) -> Self {
        Self {
            enabled,
            ..Self::default()
        }
    }

    /// Before a step of `dt` seconds: turns each declared limit on within the margin of the
    /// joint's limits, off beyond it.
    pub(super) fn update(&mut self, joints: &mut MultibodyJointSet, dt: f32) {
        self.changes.clear();
        for multibody in joints.multibodies() {
            let velocities = multibody.generalized_velocity();
            for link in multibody.links() {
                let data = &link.joint().data;
                let body = link.rigid_body_handle();
                let declared = match self.declared.iter().find(|(b, _)| *b == body) {
                    Some((_, axes)) => *axes,
                    None => {
                        self.declared.push((body, data.limit_axes));
                        data.limit_axes
                    }
                };
                if declared.is_empty() {
                    continue;
                }
                let coords = link.joint().coords();
                let mut wanted = JointAxesMask::empty();
                let mut dof = link.assembly_id();
                let axes = coords.iter().zip(&data.limits).zip(&data.motors);
                for (axis, ((&q, limits), motor)) in axes.enumerate() {
                    let bit = 1u8 << axis;
                    if data.locked_axes.bits() & bit != 0 {
                        continue;
                    }
                    let speed = velocities.get(dof).copied().unwrap_or(0.0).abs();
                    dof += 1;
                    if declared.bits() & bit == 0 {
                        continue;
                    }
                    let target = if data.motor_axes.bits() & bit != 0 {
                        motor.target_vel.abs()
                    } else {
                        0.0
                    };
                    let margin = if axis < 3 {
                        LIMIT_MARGIN_M
                    } else {
                        LIMIT_MARGIN_RAD
                    } + LOOKAHEAD_STEPS * dt * speed.max(target);
                    // A coordinate that is not a number keeps its limit (the solver decides).
                    if !(self.enabled && q - margin > limits.min && q + margin < limits.max) {
                        wanted |= JointAxesMask::from_bits_truncate(bit);
                    }
                }
                if wanted != data.limit_axes {
                    self.changes.push((body, wanted));
                }
            }
        }
        for (body, axes) in self.changes.drain(..) {
            let Some(id) = joints.rigid_body_link(body).copied() else {
                continue;
            };
            if let Some(link) = joints
                .get_multibody_mut(id.multibody)
                .and_then(|m| m.link_mut(id.id))
            {
                link.joint.data.limit_axes = axes;
            }
        }
    }
}
