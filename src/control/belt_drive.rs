//! The conveyor's drive: the belt ramps towards its target speed so that a standing bottle does
//! not tip, and slows to a creep while something is in the slow-down zone ahead of the
//! photo-eye, so that a fast belt still stops with its item at the beam. A faulty drive runs
//! the belt slower than commanded, or not at all, for a while; the encoder on the belt's
//! roller counts the travel that really happened, which is what the controller can read.

use super::BeltFault;
pub use crate::sim::BELT_ACCEL_M_S2;
use crate::sim::ConveyorHooks;

/// Belt travel per encoder count, m: a 2000-count encoder on a roller of 64 mm circumference.
pub const ENCODER_M_PER_COUNT: f64 = 0.000_032;

/// The belt's target speed, its fault, and the travel its encoder has counted.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BeltDrive {
    target_m_s: f64,
    /// The most the belt runs while the slow-down zone is occupied (`None`: no zone).
    creep_m_s: Option<f64>,
    zone_occupied: bool,
    /// An injected fault, if any.
    fault: Option<BeltFault>,
    /// Time the drive has run, s (the trial's time when it is stepped from the start).
    clock_s: f64,
    /// The belt's true travel, m.
    travel_m: f64,
    /// The speed the drive would have reached by its ramp had it obeyed, m/s.
    commanded_speed_m_s: f64,
    /// The travel it would have made had it obeyed, m.
    commanded_travel_m: f64,
}

impl BeltDrive {
    /// A drive that slows to `creep_m_s` while the slow-down zone is occupied.
    pub fn with_creep(creep_m_s: f64) -> Self {
        Self {
            creep_m_s: Some(creep_m_s),
            ..Self::default()
        }
    }

    /// Injects `fault`: while it holds, the belt runs at its share of every command.
    pub fn inject(&mut self, fault: &BeltFault) {
        self.fault = Some(*fault);
    }

    /// Whether an injected fault holds the belt now.
    pub fn fault_active(&self) -> bool {
        self.fault.is_some_and(|f| f.active_at(self.clock_s))
    }

    /// The injected fault, if any.
    pub fn fault(&self) -> Option<&BeltFault> {
        self.fault.as_ref()
    }

    /// Whether an injected fault has begun by now.
    pub fn fault_struck(&self) -> bool {
        self.fault.is_some_and(|f| self.clock_s >= f.onset_s)
    }

    /// The encoder's count: the belt's true travel since the drive started, in counts of
    /// [`ENCODER_M_PER_COUNT`].
    pub fn encoder_counts(&self) -> i64 {
        (self.travel_m / ENCODER_M_PER_COUNT).floor() as i64
    }

    /// The travel the encoder shows, m.
    pub fn encoder_travel_m(&self) -> f64 {
        self.encoder_counts() as f64 * ENCODER_M_PER_COUNT
    }

    /// The travel the commands asked for, m: what an obedient belt would have made.
    pub fn commanded_travel_m(&self) -> f64 {
        self.commanded_travel_m
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

    /// The speed the belt really ramps towards: the target, or its share while a fault holds.
    fn driven_m_s(&self) -> f64 {
        match self.fault {
            Some(fault) if fault.active_at(self.clock_s) => {
                self.target_m_s() * fault.speed_fraction
            }
            _ => self.target_m_s(),
        }
    }

    /// One step of `dt_s`: moves the belt's speed towards the target by the ramp; returns how
    /// far the belt carries things in this step, m (what the encoder counts).
    pub fn advance(&mut self, conveyor: &ConveyorHooks, dt_s: f64) -> f64 {
        let ramp_m_s = BELT_ACCEL_M_S2 * dt_s;
        conveyor.ramp_towards(self.driven_m_s() as f32, ramp_m_s as f32);
        let travel_m = f64::from(conveyor.speed_m_s()) * dt_s;
        self.commanded_speed_m_s +=
            (self.target_m_s() - self.commanded_speed_m_s).clamp(-ramp_m_s, ramp_m_s);
        self.commanded_travel_m += self.commanded_speed_m_s * dt_s;
        self.travel_m += travel_m;
        self.clock_s += dt_s;
        travel_m
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

    const DT_S: f64 = 1.0 / 240.0;

    /// Runs `drive` at `speed_m_s` for `seconds`; returns the true travel, m.
    fn run(drive: &mut BeltDrive, conveyor: &ConveyorHooks, speed_m_s: f64, seconds: f64) -> f64 {
        drive.run_at(speed_m_s);
        (0..(seconds / DT_S).round() as usize)
            .map(|_| drive.advance(conveyor, DT_S))
            .sum()
    }

    fn hooks() -> ConveyorHooks {
        ConveyorHooks::new(rapier3d::prelude::ColliderHandle::invalid())
    }

    #[test]
    fn an_obedient_belt_makes_the_commanded_travel_and_the_encoder_counts_it() {
        let (mut drive, conveyor) = (BeltDrive::default(), hooks());
        let travel_m = run(&mut drive, &conveyor, 0.25, 3.0);
        // Ramp up to 0.25 m/s, then run: a little under 0.75 m.
        assert!((0.7..0.75).contains(&travel_m), "{travel_m}");
        assert!((drive.commanded_travel_m() - travel_m).abs() < 1e-6);
        assert!((drive.encoder_travel_m() - travel_m).abs() <= ENCODER_M_PER_COUNT);
        assert!(!drive.fault_struck() && !drive.fault_active());
    }

    #[test]
    fn a_slow_belt_runs_at_its_share_for_its_window_and_the_encoder_shows_the_shortfall() {
        let (mut drive, conveyor) = (BeltDrive::default(), hooks());
        drive.inject(&BeltFault {
            onset_s: 1.0,
            duration_s: 2.0,
            speed_fraction: 0.4,
        });
        // (Clear of the window's edges, which a sum of ticks meets only to rounding.)
        run(&mut drive, &conveyor, 0.25, 1.1);
        assert!(drive.fault_active() && drive.fault_struck());
        run(&mut drive, &conveyor, 0.25, 1.0);
        assert!(
            (f64::from(conveyor.speed_m_s()) - 0.1).abs() < 1e-6,
            "40 % of 0.25"
        );
        run(&mut drive, &conveyor, 0.25, 1.0);
        assert!(!drive.fault_active() && drive.fault_struck());
        run(&mut drive, &conveyor, 0.25, 1.0);
        assert!(
            (f64::from(conveyor.speed_m_s()) - 0.25).abs() < 1e-6,
            "back to the command"
        );
        // Two seconds at 60 % short, less the ramps: about 0.3 m behind the commands.
        let shortfall_m = drive.commanded_travel_m() - drive.encoder_travel_m();
        assert!((0.25..0.31).contains(&shortfall_m), "{shortfall_m}");
    }

    #[test]
    fn a_stalled_belt_stands_whatever_it_is_told_and_the_encoder_stops() {
        let (mut drive, conveyor) = (BeltDrive::default(), hooks());
        drive.inject(&BeltFault {
            onset_s: 0.0,
            duration_s: 10.0,
            speed_fraction: 0.0,
        });
        let travel_m = run(&mut drive, &conveyor, 0.25, 5.0);
        assert_eq!(travel_m, 0.0);
        assert_eq!(drive.encoder_counts(), 0);
        assert!(drive.commanded_travel_m() > 1.0);
    }
}
