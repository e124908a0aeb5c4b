//! The conveyor's drive: the belt ramps towards its target speed so that a standing bottle does
//! not tip, and slows to a creep while something is in the slow-down zone ahead of the
//! photo-eye, so that a fast belt still stops with its item at the beam.

pub use crate::sim::BELT_ACCEL_M_S2;
use crate::sim::ConveyorHooks;

/// The belt's target speed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BeltDrive {
    target_m_s: f64,
    /// The most the belt runs while the slow-down zone is occupied (`None`: no zone).
    creep_m_s: Option<f64>,
    zone_occupied: bool,
}

impl BeltDrive {
    /// A drive that slows to `creep_m_s` while the slow-down zone is occupied.
    pub fn with_creep(creep_m_s: f64) -> Self {
        Self {
            creep_m_s: Some(creep_m_s),
            ..Self::default()
        }
    }

    /// Runs the belt at `speed_m_s` (0 stops it).
    pub fn run_at(&mut self, speed_m_s: f64) {
        self.target_m_s = speed_m_s;
    }

    /// Tells the drive whether anything is in the slow-down zone now.
    pub fn set_zone_occupied(&mut self, occupied: bool) {
        self.zone_occupied = occupied;
    }

    /// The speed the drive ramps towards: the target, capped at the creep while the zone is
    /// occupied.
    pub fn target_m_s(&self) -> f64 {
        match self.creep_m_s {
            Some(creep) if self.zone_occupied => self.target_m_s.min(creep),
            _ => self.target_m_s,
        }
    }

    /// One step of `dt_s`: moves the belt's speed towards the target by the ramp; returns how
    /// far the belt carries things in this step, m.
    pub fn advance(&self, conveyor: &ConveyorHooks, dt_s: f64) -> f64 {
        conveyor.ramp_towards(self.target_m_s() as f32, (BELT_ACCEL_M_S2 * dt_s) as f32);
        f64::from(conveyor.speed_m_s()) * dt_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_occupied_zone_caps_the_speed_at_the_creep_and_a_stop_stays_a_stop() {
        let mut drive = BeltDrive::with_creep(0.25);
        drive.run_at(0.5);
        assert_eq!(drive.target_m_s(), 0.5);
        drive.set_zone_occupied(true);
        assert_eq!(drive.target_m_s(), 0.25);
        drive.run_at(0.0);
        assert_eq!(drive.target_m_s(), 0.0);
        drive.run_at(0.5);
        drive.set_zone_occupied(false);
        assert_eq!(drive.target_m_s(), 0.5);
        // Without a zone the drive never creeps.
        let mut plain = BeltDrive::default();
        plain.run_at(0.5);
        plain.set_zone_occupied(true);
        assert_eq!(plain.target_m_s(), 0.5);
    }
}
