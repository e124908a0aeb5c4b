//! Control: turns planned motion into servo commands, one fixed step at a time.

mod trajectory_follower;

pub use trajectory_follower::TrajectoryFollower;
