//! The gripper's drive: jaws that travel at the drive's speed to a commanded opening and push
//! with at most a set force; a faulty one lets its force fall some time after it closes.

use super::GripFault;
use crate::sim::{JAW_SPEED_M_S, SimArm, World};

/// Where an injected grip fault stands.
#[derive(Debug, Clone, Copy, PartialEq)]
enum FaultState {
    /// Waiting for the jaws to be commanded closed.
    Armed { delay_s: f64, force_fraction: f64 },
    /// The jaws were commanded closed `elapsed_s` ago.
    Counting {
        delay_s: f64,
        force_fraction: f64,
        elapsed_s: f64,
    },
    /// The force has fallen to this share of the command, until the jaws open.
    Fallen { force_fraction: f64 },
    /// Over: the jaws opened, after the force fell (`struck`) or before its delay ran out (a
    /// fault strikes the one grasp it was injected for).
    Spent { struck: bool },
}

/// The jaws' command and where the drive has got to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperDrive {
    /// Commanded pad offset from the centre line, m.
    command_m: f64,
    /// Where the drive has brought the pads' set-point so far, m.
    target_m: f64,
    /// Force limit per jaw, N.
    force_n: f64,
    /// An injected fault, if any.
    fault: Option<FaultState>,
}

impl GripperDrive {
    /// Jaws standing at `offset_m`, pushing with at most `force_n`.
    pub fn new(offset_m: f64, force_n: f64) -> Self {
        Self {
            command_m: offset_m,
            target_m: offset_m,
            force_n,
            fault: None,
        }
    }

    /// Injects `fault`: the next time the jaws are commanded closed, their force falls to
    /// `fault.force_fraction` of the command `fault.delay_s` later and stays there until they
    /// are commanded open.
    pub fn inject(&mut self, fault: &GripFault) {
        self.fault = Some(FaultState::Armed {
            delay_s: fault.delay_s,
            force_fraction: fault.force_fraction,
        });
    }

    /// Whether an injected fault has let the force fall (now or earlier in the trial).
    pub fn fault_struck(&self) -> bool {
        matches!(
            self.fault,
            Some(FaultState::Fallen { .. } | FaultState::Spent { struck: true })
        )
    }

    /// Commands the jaws to `offset_m` with at most `force_n` per jaw.
    pub fn set(&mut self, offset_m: f64, force_n: f64) {
        let closing = offset_m < self.command_m;
        let opening = offset_m > self.command_m;
        self.fault = match self.fault {
            Some(FaultState::Armed {
                delay_s,
                force_fraction,
            }) if closing => Some(FaultState::Counting {
                delay_s,
                force_fraction,
                elapsed_s: 0.0,
            }),
            Some(FaultState::Counting { .. }) if opening => {
                Some(FaultState::Spent { struck: false })
            }
            Some(FaultState::Fallen { .. }) if opening => Some(FaultState::Spent { struck: true }),
            other => other,
        };
        self.command_m = offset_m;
        self.force_n = force_n;
    }

    /// Commands the jaws open to `offset_m` with at most `force_n`, the drive starting from
    /// where the pads stand (`pads_m`, the smaller pad offset): a drive stalled on a part
    /// reverses from the contact, as a real one does, not from the set-point it was pushing
    /// towards to build the grip force.
    pub fn open_from(&mut self, pads_m: f64, offset_m: f64, force_n: f64) {
        if offset_m > self.target_m {
            self.target_m = self.target_m.max(pads_m.min(offset_m));
        }
        self.set(offset_m, force_n);
    }

    /// The drive's set-point now, m.
    pub fn target_m(&self) -> f64 {
        self.target_m
    }

    /// The force limit per jaw commanded now, N (what the controller asked for).
    pub fn force_n(&self) -> f64 {
        self.force_n
    }

    /// The force limit per jaw the drive gives now, N: the command, or its fallen share.
    pub fn applied_force_n(&self) -> f64 {
        match self.fault {
            Some(FaultState::Fallen { force_fraction }) => self.force_n * force_fraction,
            _ => self.force_n,
        }
    }

    /// One step of `dt_s`: the set-point moves at most `JAW_SPEED_M_S` towards the command, as
    /// a real gripper's drive does, and the arm's jaw servos get it.
    pub fn advance(&mut self, world: &mut World, arm: &SimArm, dt_s: f64) {
        self.step_state(dt_s);
        arm.command_gripper(world, self.target_m, self.applied_force_n());
    }

    /// The drive's own state one step of `dt_s` on: the set-point, and a fault's clock.
    fn step_state(&mut self, dt_s: f64) {
        let step = JAW_SPEED_M_S * dt_s;
        self.target_m += (self.command_m - self.target_m).clamp(-step, step);
        if let Some(FaultState::Counting {
            delay_s,
            force_fraction,
            elapsed_s,
        }) = self.fault
        {
            let elapsed_s = elapsed_s + dt_s;
            self.fault = Some(if elapsed_s >= delay_s {
                FaultState::Fallen { force_fraction }
            } else {
                FaultState::Counting {
                    delay_s,
                    force_fraction,
                    elapsed_s,
                }
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT_S: f64 = 1.0 / 240.0;

    fn run(drive: &mut GripperDrive, seconds: f64) {
        for _ in 0..(seconds / DT_S).round() as usize {
            drive.step_state(DT_S);
        }
    }

    fn fault(delay_s: f64) -> GripFault {
        GripFault {
            grasp: 0,
            delay_s,
            force_fraction: 0.1,
        }
    }

    #[test]
    fn without_a_fault_the_drive_gives_what_it_is_told() {
        let mut drive = GripperDrive::new(0.03, 60.0);
        drive.set(0.0, 60.0);
        run(&mut drive, 5.0);
        assert_eq!(drive.applied_force_n(), 60.0);
        assert!(!drive.fault_struck());
    }

    #[test]
    fn the_force_falls_its_delay_after_the_close_and_recovers_when_the_jaws_open() {
        let mut drive = GripperDrive::new(0.03, 60.0);
        drive.inject(&fault(0.5));
        // Armed only: opening, holding and waiting leave the force whole.
        drive.set(0.04, 10.0);
        run(&mut drive, 1.0);
        assert_eq!(drive.applied_force_n(), 10.0);
        drive.set(0.0, 80.0);
        run(&mut drive, 0.45);
        assert_eq!(drive.applied_force_n(), 80.0, "before the delay");
        run(&mut drive, 0.1);
        assert!(drive.fault_struck());
        assert!(
            (drive.applied_force_n() - 8.0).abs() < 1e-12,
            "after the delay"
        );
        assert_eq!(
            drive.force_n(),
            80.0,
            "the command stays what the controller asked"
        );
        // Opening ends the fault; the next grasp holds with its whole force.
        drive.set(0.04, 10.0);
        drive.set(0.0, 80.0);
        run(&mut drive, 5.0);
        assert_eq!(drive.applied_force_n(), 80.0);
        assert!(drive.fault_struck());
    }

    #[test]
    fn a_grasp_that_opens_before_the_delay_escapes_the_fault() {
        let mut drive = GripperDrive::new(0.03, 60.0);
        drive.inject(&fault(2.0));
        drive.set(0.0, 60.0);
        run(&mut drive, 1.0);
        drive.set(0.04, 10.0);
        drive.set(0.0, 60.0);
        run(&mut drive, 5.0);
        assert_eq!(drive.applied_force_n(), 60.0);
        assert!(!drive.fault_struck());
    }
}
