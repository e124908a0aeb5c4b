//! Feeds a joint trajectory to the arm's servos; an arm stop freezes it part-way for a while.

use crate::planning::{JointTrajectory, TrajectorySample};
use crate::sim::{SimArm, World};

/// A stop part-way along a trajectory: the servos hold the pose reached at `at_s` (seconds
/// along the trajectory) for `duration_s`, then release and the motion goes on from there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryStop {
    /// Where along the trajectory the arm stops, s of trajectory time.
    pub at_s: f64,
    /// How long it stands, s.
    pub duration_s: f64,
}

/// Plays a [`JointTrajectory`] into the joint servos from a start time.
#[derive(Debug, Clone)]
pub struct TrajectoryFollower {
    trajectory: JointTrajectory,
    start_s: f64,
    stop: Option<TrajectoryStop>,
}

impl TrajectoryFollower {
    /// Starts `trajectory` at simulated time `start_s`.
    pub fn new(trajectory: JointTrajectory, start_s: f64) -> Self {
        Self {
            trajectory,
            start_s,
            stop: None,
        }
    }

    /// Injects an arm stop into the playing.
    pub fn with_stop(mut self, stop: TrajectoryStop) -> Self {
        self.stop = Some(stop);
        self
    }

    /// The trajectory being played.
    pub fn trajectory(&self) -> &JointTrajectory {
        &self.trajectory
    }

    /// The trajectory's own time `elapsed_s` after it started playing: it stands still
    /// through a stop and goes on after it.
    pub fn trajectory_time_s(&self, elapsed_s: f64) -> f64 {
        match self.stop {
            Some(stop) if elapsed_s >= stop.at_s + stop.duration_s => elapsed_s - stop.duration_s,
            Some(stop) if elapsed_s >= stop.at_s => stop.at_s,
            _ => elapsed_s,
        }
    }

    /// When trajectory time `trajectory_s` is reached, as time since the playing started
    /// (the inverse of [`Self::trajectory_time_s`]; a stop at exactly that time is waited
    /// out first).
    pub fn elapsed_s_at(&self, trajectory_s: f64) -> f64 {
        match self.stop {
            Some(stop) if trajectory_s > stop.at_s => trajectory_s + stop.duration_s,
            _ => trajectory_s,
        }
    }

    /// Whether the arm stands in the stop `elapsed_s` after the playing started.
    pub fn stopped_at(&self, elapsed_s: f64) -> bool {
        self.stop
            .is_some_and(|stop| (stop.at_s..stop.at_s + stop.duration_s).contains(&elapsed_s))
    }

    /// The playing's length, s: the trajectory's, and a stop's that falls within it.
    pub fn duration_s(&self) -> f64 {
        self.elapsed_s_at(self.trajectory.duration_s())
    }

    /// Whether the playing has run out at `time_s`.
    pub fn finished(&self, time_s: f64) -> bool {
        time_s - self.start_s >= self.duration_s()
    }

    /// Commands the servos for the world's next step; returns the commanded sample.
    pub fn update(&self, world: &mut World, arm: &SimArm) -> Option<TrajectorySample> {
        // The command holds over the coming step, so aim at its end.
        let t = world.time_s() + world.params().dt_s - self.start_s;
        self.command_at(world, arm, t)
    }

    /// Commands the servos with the playing's state `t_s` seconds after it started (the end of
    /// the coming step); returns the commanded sample.
    pub fn command_at(
        &self,
        world: &mut World,
        arm: &SimArm,
        t_s: f64,
    ) -> Option<TrajectorySample> {
        let sample = self.sample_at(t_s)?;
        arm.command(world, &sample.q, &sample.qd);
        Some(sample)
    }

    /// The playing's state `t_s` seconds after it started: in a stop, the pose reached with
    /// no velocity, which the servos hold.
    pub fn sample_at(&self, t_s: f64) -> Option<TrajectorySample> {
        let mut sample = self.trajectory.sample(self.trajectory_time_s(t_s))?;
        if self.stopped_at(t_s) {
            sample.qd = [0.0; 6];
        }
        Some(sample)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::ArmModel;

    fn follower() -> TrajectoryFollower {
        let arm = ArmModel::aubo_i5();
        let trajectory =
            JointTrajectory::through(&arm, &[[0.0; 6], [1.0, -0.5, 0.8, 0.3, -0.6, 1.2]], 0.5);
        TrajectoryFollower::new(trajectory, 0.0)
    }

    #[test]
    fn without_a_stop_the_playing_is_the_trajectory() {
        let plain = follower();
        let duration = plain.trajectory().duration_s();
        assert_eq!(plain.duration_s(), duration);
        for k in 0..=20 {
            let t = duration * k as f64 / 20.0;
            assert_eq!(plain.trajectory_time_s(t), t);
            assert_eq!(plain.elapsed_s_at(t), t);
            assert_eq!(plain.sample_at(t), plain.trajectory().sample(t));
            assert!(!plain.stopped_at(t));
        }
    }

    #[test]
    fn a_stop_holds_the_pose_it_reached_then_the_motion_goes_on_from_there() {
        let plain = follower();
        let duration = plain.trajectory().duration_s();
        let stop = TrajectoryStop {
            at_s: 0.4 * duration,
            duration_s: 0.75,
        };
        let stopped = plain.clone().with_stop(stop);
        assert!((stopped.duration_s() - (duration + 0.75)).abs() < 1e-12);
        let Some(at) = plain.trajectory().sample(stop.at_s) else {
            panic!("sample inside the trajectory");
        };
        assert!(
            at.qd.iter().any(|v| v.abs() > 1e-3),
            "the arm moves when it stops"
        );
        for k in 0..10 {
            let t = stop.at_s + stop.duration_s * k as f64 / 10.0;
            assert!(stopped.stopped_at(t));
            let Some(held) = stopped.sample_at(t) else {
                panic!("sample in the stop");
            };
            assert_eq!(held.q, at.q, "the servos hold the pose reached");
            assert_eq!(held.qd, [0.0; 6], "with no velocity");
        }
        for k in 0..=10 {
            let t = stop.at_s + stop.duration_s + (duration - stop.at_s) * k as f64 / 10.0;
            assert!(!stopped.stopped_at(t));
            assert_eq!(
                stopped.sample_at(t),
                plain.trajectory().sample(t - stop.duration_s)
            );
            let back = stopped.elapsed_s_at(stopped.trajectory_time_s(t));
            assert!((back - t).abs() < 1e-12 || k == 0, "{back} {t}");
        }
        assert!(stopped.finished(duration + 0.75) && !stopped.finished(duration + 0.7));
    }
}
