//! The conveyor belt: a fixed slab whose contacts carry a surface velocity.

use std::sync::atomic::{AtomicU32, Ordering};

use rapier3d::prelude::*;

/// The belt drive's ramp, m/s^2: gentle enough that a standing bottle does not tip.
pub const BELT_ACCEL_M_S2: f64 = 1.0;

/// Physics hooks that make the belt collider's contacts move things along +x.
///
/// The belt is a fixed body; the solver sees its contacts with a tangent velocity, so parts are
/// carried by friction, slip when held back, and stop when the belt does.
#[derive(Debug)]
pub struct ConveyorHooks {
    belt: ColliderHandle,
    speed_bits: AtomicU32,
}

impl ConveyorHooks {
    /// Hooks for the belt collider `belt`, initially stopped.
    pub fn new(belt: ColliderHandle) -> Self {
        Self {
            belt,
            speed_bits: AtomicU32::new(0f32.to_bits()),
        }
    }

    /// The belt's current surface speed, m/s.
    pub fn speed_m_s(&self) -> f32 {
        f32::from_bits(self.speed_bits.load(Ordering::Relaxed))
    }

    /// Sets the belt's surface speed, m/s.
    pub fn set_speed_m_s(&self, speed: f32) {
        self.speed_bits.store(speed.to_bits(), Ordering::Relaxed);
    }

    /// Moves the speed towards `target` by at most `max_change` (the drive's ramp).
    pub fn ramp_towards(&self, target: f32, max_change: f32) {
        let current = self.speed_m_s();
        let next = current + (target - current).clamp(-max_change, max_change);
        self.set_speed_m_s(next);
    }
}

impl PhysicsHooks for ConveyorHooks {
    fn modify_solver_contacts(&self, context: &mut ContactModificationContext) {
        let speed = self.speed_m_s();
        // The finger pads also request this hook (so that rapier rebuilds their contacts every
        // step, see `layout::set_robot_friction`); only the belt's contacts are changed.
        let on_belt = context.collider1 == self.belt || context.collider2 == self.belt;
        if speed == 0.0 || !on_belt {
            return;
        }
        // The tangent velocity is the velocity the solver drives collider 2's surface to,
        // relative to collider 1's (checked by the conveyor test: parts travel downstream, along
        // +x; and by the pads' stiction, which pulls a held part back with the same sign).
        let sign = if context.collider1 == self.belt {
            1.0
        } else {
            -1.0
        };
        if let ModifiableContacts::Rigid(manifold) = &mut context.contacts {
            for contact in manifold.solver_contacts.iter_mut() {
                contact.tangent_velocity = Vector::new(sign * speed, 0.0, 0.0);
            }
        }
    }
}
