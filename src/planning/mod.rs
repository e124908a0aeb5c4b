//! Motion planning: joint-space trajectories within the arm's limits.

mod collision;
mod trajectory;

pub use collision::{Carried, CollisionChecker, CollisionHit, LinkMount, Obstacle, RobotShape};
pub use trajectory::{JointTrajectory, TrajectorySample};
