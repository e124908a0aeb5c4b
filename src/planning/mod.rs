//! Motion planning: joint-space trajectories within the arm's limits.

mod trajectory;

pub use trajectory::{JointTrajectory, TrajectorySample};
