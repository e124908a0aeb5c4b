//! Motion planning: joint-space trajectories within the arm's limits.

mod collision;
mod straight_line;
mod trajectory;

pub use collision::{Carried, CollisionChecker, CollisionHit, LinkMount, Obstacle, RobotShape};
pub use straight_line::straight_line;
pub use trajectory::{JointTrajectory, TrajectorySample};
