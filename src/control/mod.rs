//! Control: turns planned motion into servo commands, one fixed step at a time: the arm's
//! trajectory, the gripper's and the belt's drives, and the monitor of a held part.

mod belt_drive;
mod gripper_drive;
mod hold_monitor;
mod trajectory_follower;

pub use belt_drive::{BELT_ACCEL_M_S2, BeltDrive};
pub use gripper_drive::GripperDrive;
pub use hold_monitor::HoldMonitor;
pub use trajectory_follower::TrajectoryFollower;
