//! The conveyor's drive: the belt ramps towards its target speed so that a standing bottle does
//! not tip.

use crate::sim::ConveyorHooks;

/// Belt drive ramp, m/s^2: gentle enough that a standing bottle does not tip.
pub const BELT_ACCEL_M_S2: f64 = 1.0;

/// The belt's target speed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BeltDrive {
    target_m_s: f64,
}

impl BeltDrive {
    /// Runs the belt at `speed_m_s` (0 stops it).
    pub fn run_at(&mut self, speed_m_s: f64) {
        self.target_m_s = speed_m_s;
    }

    /// One step of `dt_s`: moves the belt's speed towards the target by the ramp; returns how
    /// far the belt carries things in this step, m.
    pub fn advance(&self, conveyor: &ConveyorHooks, dt_s: f64) -> f64 {
        conveyor.ramp_towards(self.target_m_s as f32, (BELT_ACCEL_M_S2 * dt_s) as f32);
        f64::from(conveyor.speed_m_s()) * dt_s
    }
}
