//! The gripper's drive: jaws that travel at the drive's speed to a commanded opening and push
//! with at most a set force.

use crate::sim::{JAW_SPEED_M_S, SimArm, World};

/// The jaws' command and where the drive has got to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperDrive {
    /// Commanded pad offset from the centre line, m.
    command_m: f64,
    /// Where the drive has brought the pads' set-point so far, m.
    target_m: f64,
    /// Force limit per jaw, N.
    force_n: f64,
}

impl GripperDrive {
    /// Jaws standing at `offset_m`, pushing with at most `force_n`.
    pub fn new(offset_m: f64, force_n: f64) -> Self {
        Self {
            command_m: offset_m,
            target_m: offset_m,
            force_n,
        }
    }

    /// Commands the jaws to `offset_m` with at most `force_n` per jaw.
    pub fn set(&mut self, offset_m: f64, force_n: f64) {
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

    /// The force limit per jaw now, N.
    pub fn force_n(&self) -> f64 {
        self.force_n
    }

    /// One step of `dt_s`: the set-point moves at most `JAW_SPEED_M_S` towards the command, as
    /// a real gripper's drive does, and the arm's jaw servos get it.
    pub fn advance(&mut self, world: &mut World, arm: &SimArm, dt_s: f64) {
        let step = JAW_SPEED_M_S * dt_s;
        self.target_m += (self.command_m - self.target_m).clamp(-step, step);
        arm.command_gripper(world, self.target_m, self.force_n);
    }
}
