//! Control: turns planned motion into servo commands, one fixed step at a time: the arm's
//! trajectory, the gripper's and the belt's drives, and the monitor of a held part; and the
//! faults those drives and the cell's sensors suffer in a trial, drawn from its seed.

mod backoff;
mod belt_drive;
mod fault_plan;
mod grip_watch;
mod gripper_drive;
mod hold_monitor;
mod photo_eye_signal;
mod trajectory_follower;

pub use backoff::Backoff;
pub use belt_drive::{BELT_ACCEL_M_S2, BeltDrive, ENCODER_M_PER_COUNT};
pub use fault_plan::{
    ARM_MOTIONS, ArmStop, BeltFault, BlackoutFrames, CameraBlackout, FaultPlan, GripFault,
    PhotoEyeFaults,
};
pub use grip_watch::{GripReading, GripWatch, JAWS_PAST_PART_M, WEAK_FORCE_SHARE, WEAK_READINGS};
pub use gripper_drive::GripperDrive;
pub use hold_monitor::HoldMonitor;
pub use photo_eye_signal::PhotoEyeSignal;
pub use trajectory_follower::{TrajectoryFollower, TrajectoryStop};
