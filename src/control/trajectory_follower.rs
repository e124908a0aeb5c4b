//! Feeds a joint trajectory to the arm's servos.

use crate::planning::{JointTrajectory, TrajectorySample};
use crate::sim::{SimArm, World};

/// Plays a [`JointTrajectory`] into the joint servos from a start time.
#[derive(Debug, Clone)]
pub struct TrajectoryFollower {
    trajectory: JointTrajectory,
    start_s: f64,
}

impl TrajectoryFollower {
    /// Starts `trajectory` at simulated time `start_s`.
    pub fn new(trajectory: JointTrajectory, start_s: f64) -> Self {
        Self {
            trajectory,
            start_s,
        }
    }

    /// The trajectory being played.
    pub fn trajectory(&self) -> &JointTrajectory {
        &self.trajectory
    }

    /// Whether the trajectory's time has run out at `time_s`.
    pub fn finished(&self, time_s: f64) -> bool {
        time_s - self.start_s >= self.trajectory.duration_s()
    }

    /// Commands the servos for the world's next step; returns the commanded sample.
    pub fn update(&self, world: &mut World, arm: &SimArm) -> Option<TrajectorySample> {
        // The command holds over the coming step, so aim at its end.
        let t = world.time_s() + world.params().dt_s - self.start_s;
        self.command_at(world, arm, t)
    }

    /// Commands the servos with the trajectory's state `t_s` seconds along it (the end of the
    /// coming step); returns the commanded sample.
    pub fn command_at(
        &self,
        world: &mut World,
        arm: &SimArm,
        t_s: f64,
    ) -> Option<TrajectorySample> {
        let sample = self.trajectory.sample(t_s)?;
        arm.command(world, &sample.q, &sample.qd);
        Some(sample)
    }
}
