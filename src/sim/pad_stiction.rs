//! Pre-sliding friction of the rubber finger pads.
//!
//! A rubber pad pressed on a part sticks: under a tangential load below the friction limit it
//! deflects elastically by a fraction of a millimetre and springs back when the load eases; only
//! past that deflection does the part slide (the bristle picture of Dahl's friction model). The
//! solver's Coulomb friction has no such memory: in every substep it only cancels the sliding
//! velocity that remains, so a held part under a steady load (its weight, the carry's
//! acceleration) creeps along the pads by what each substep leaves over, and more, the fewer
//! substeps a step has (measured in docs/motion.md).
//!
//! Here each body a pad touches is anchored where the pad first held it. At each contact the
//! pad's surface is given a tangent velocity (the same device that moves the belt) that carries
//! the body back toward its anchor at [`PRESLIDE_RATE_HZ`] times its displacement. The friction
//! cone still bounds the force: a load beyond what the grip holds makes the part slide, and a
//! displacement past the pads' pre-sliding limit (the scenario's `gripper.pad_preslide_mm`,
//! 1 mm by default) moves the anchor to where the part now is (it has
//! slipped, and sticks again there). Nothing holds a body the pads do not press on.

use rapier3d::prelude::*;

/// How fast a pad's stiction pulls a displaced part back, per second of displacement.
pub const PRESLIDE_RATE_HZ: f64 = 40.0;

/// Where a pad holds a body: the body's pose in the pad's frame when it stuck.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Anchor {
    pad: RigidBodyHandle,
    body: RigidBodyHandle,
    pad_from_body: Pose,
}

/// The stiction of the pad bodies (the fingers), and where each holds what it touches.
#[derive(Debug, Clone, Default)]
pub struct PadStiction {
    pads: Vec<RigidBodyHandle>,
    preslide_limit_m: f64,
    anchors: Vec<Anchor>,
}

impl PadStiction {
    /// Stiction for the bodies `pads`, which deflect up to `preslide_limit_m` before what they
    /// hold slides (the scenario's `gripper.pad_preslide_mm`); at 0 they have none, and only
    /// the solver's Coulomb friction holds.
    pub fn new(pads: Vec<RigidBodyHandle>, preslide_limit_m: f64) -> Self {
        Self {
            pads,
            preslide_limit_m,
            anchors: Vec::new(),
        }
    }

    /// Brings the anchors up to date after a step: a body a pad now touches and had not is
    /// anchored where it is; one displaced past the pre-sliding limit has slid and is anchored
    /// anew; one the pad no longer touches is let go.
    pub fn update(&mut self, physics: &PhysicsWorld) {
        if self.preslide_limit_m <= 0.0 {
            return;
        }
        let mut anchors = Vec::new();
        for &pad in &self.pads {
            let Some(pad_body) = physics.bodies.get(pad) else {
                continue;
            };
            for &collider in pad_body.colliders() {
                for pair in physics.narrow_phase.contact_pairs_with(collider) {
                    if !pair.has_any_active_contact() {
                        continue;
                    }
                    let other = if pair.collider1 == collider {
                        pair.collider2
                    } else {
                        pair.collider1
                    };
                    let Some(body) = physics.colliders.get(other).and_then(|c| c.parent()) else {
                        continue;
                    };
                    let Some(rb) = physics.bodies.get(body) else {
                        continue;
                    };
                    if !rb.is_dynamic()
                        || self.pads.contains(&body)
                        || anchors
                            .iter()
                            .any(|a: &Anchor| a.pad == pad && a.body == body)
                    {
                        continue;
                    }
                    let now = pad_body.position().inverse() * *rb.position();
                    let kept = self
                        .anchors
                        .iter()
                        .find(|a| a.pad == pad && a.body == body)
                        .filter(|a| {
                            displacement_m(&a.pad_from_body, &now) <= self.preslide_limit_m
                        });
                    anchors.push(Anchor {
                        pad,
                        body,
                        pad_from_body: kept.map_or(now, |a| a.pad_from_body),
                    });
                }
            }
        }
        self.anchors = anchors;
    }
}

impl PhysicsHooks for PadStiction {
    /// Gives the contacts between a pad and a body anchored to it the tangent velocity that
    /// carries the body back to its anchor (see the module's documentation).
    fn modify_solver_contacts(&self, context: &mut ContactModificationContext) {
        let (Some(body1), Some(body2)) = (context.rigid_body1, context.rigid_body2) else {
            return;
        };
        let (pad, body, pad_is_first) = if self.pads.contains(&body1) {
            (body1, body2, true)
        } else if self.pads.contains(&body2) {
            (body2, body1, false)
        } else {
            return;
        };
        let Some(anchor) = self.anchors.iter().find(|a| a.pad == pad && a.body == body) else {
            return;
        };
        let (Some(pad_rb), Some(rb)) = (context.bodies.get(pad), context.bodies.get(body)) else {
            return;
        };
        // Where a point of the body would be, had it stayed at its anchor on the pad.
        let anchored_from_now = *pad_rb.position() * anchor.pad_from_body * rb.position().inverse();
        let rate = PRESLIDE_RATE_HZ as f32;
        let ModifiableContacts::Rigid(manifold) = &mut context.contacts else {
            return;
        };
        let normal = *manifold.normal;
        for contact in manifold.solver_contacts.iter_mut() {
            let on_body = if pad_is_first {
                contact.anchor2
            } else {
                contact.anchor1
            };
            let back = anchored_from_now.transform_point(on_body) - on_body;
            let tangential = back - normal * back.dot(normal);
            // The velocity collider 2's surface is driven to, relative to collider 1's (as on the
            // belt): the body moves back toward its anchor.
            contact.tangent_velocity = if pad_is_first {
                tangential * rate
            } else {
                -tangential * rate
            };
        }
    }
}

/// How far a body's points move between two of its poses in a pad's frame, m: the shift of its
/// origin, plus its turn times a 5 cm lever (the size of a gripped part).
fn displacement_m(anchor: &Pose, now: &Pose) -> f64 {
    let shift = f64::from((now.translation - anchor.translation).length());
    let turn = f64::from(anchor.rotation.angle_between(now.rotation));
    shift + 0.05 * turn
}

/// The cell's contact hooks: the belt's surface speed and the pads' stiction.
pub struct CellHooks<'a> {
    /// The belt.
    pub conveyor: &'a super::ConveyorHooks,
    /// The finger pads.
    pub pads: &'a PadStiction,
}

impl PhysicsHooks for CellHooks<'_> {
    fn modify_solver_contacts(&self, context: &mut ContactModificationContext) {
        self.conveyor.modify_solver_contacts(context);
        PhysicsHooks::modify_solver_contacts(self.pads, context);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{World, WorldParams};

    /// How far (m) a 4 cm box set on a fixed pad tilted by `slope_deg` moves along it in
    /// `duration_s`, with friction `friction` on both, with or without the pad's stiction.
    fn slide_m(friction: f32, slope_deg: f32, stiction: bool, duration_s: f64) -> f32 {
        let mut world = World::new(WorldParams::default());
        let tilt = Rotation::from_rotation_y(slope_deg.to_radians());
        let physics = &mut world.physics;
        let pad = physics
            .bodies
            .insert(RigidBodyBuilder::fixed().pose(Pose::from_parts(Vector::ZERO, tilt)));
        let pad_collider = ColliderBuilder::cuboid(0.5, 0.2, 0.05)
            .friction(friction)
            .active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS);
        physics
            .colliders
            .insert_with_parent(pad_collider, pad, &mut physics.bodies);
        let start = tilt * Vector::new(0.0, 0.0, 0.07);
        let body = physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .pose(Pose::from_parts(start, tilt))
                .can_sleep(false),
        );
        let box_collider = ColliderBuilder::cuboid(0.02, 0.02, 0.02)
            .friction(friction)
            .density(1000.0);
        physics
            .colliders
            .insert_with_parent(box_collider, body, &mut physics.bodies);
        let mut pads = PadStiction::new(vec![pad], 0.001);
        let steps = (duration_s / world.params().dt_s).round() as usize;
        for _ in 0..steps {
            if stiction {
                world.step_with_hooks(&pads);
            } else {
                world.step();
            }
            pads.update(&world.physics);
        }
        (world.physics.bodies[body].translation() - start).length()
    }

    #[test]
    fn a_part_on_a_pad_within_its_friction_angle_stays_put() {
        // 25 degrees under friction 0.8 (a friction angle of 39 degrees), for 3 s.
        let held = slide_m(0.8, 25.0, true, 3.0);
        assert!(held < 5e-4, "moved {:.2} mm", held * 1e3);
    }

    #[test]
    fn stiction_does_not_hold_a_part_past_its_friction_angle() {
        // 30 degrees under friction 0.2: it slides, about 1.6 m in a second, stiction or not.
        let free = slide_m(0.2, 30.0, false, 1.0);
        let with = slide_m(0.2, 30.0, true, 1.0);
        assert!(free > 1.0, "without stiction it slid {free:.3} m");
        assert!(
            (with - free).abs() < 0.05 * free,
            "{with:.3} m with stiction, {free:.3} m without"
        );
    }
}
