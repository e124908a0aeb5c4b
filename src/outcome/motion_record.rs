//! How a trial's arm moved, in simulated time: seconds per phase, the measured joint motion
//! against the arm's limits, and how far the held part drifted in the jaws.

use serde::{Deserialize, Serialize};

use super::PhaseSeconds;

/// The arm's motion over a trial as the physics measured it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct MotionRecord {
    /// Simulated seconds per phase.
    pub phase_s: PhaseSeconds,
    /// Largest measured joint speed as a share of that joint's velocity limit (1 is at the
    /// limit), from the joint angles of consecutive physics steps.
    pub joint_speed_ratio: f64,
    /// Smallest distance of a measured joint angle from its position limits, rad (negative past
    /// a limit).
    pub joint_limit_margin_rad: f64,
    /// Largest difference between a commanded and the measured joint angle, rad.
    pub tracking_error_rad: f64,
    /// Largest drift of the held part from where the jaws closed on it, in the TCP frame, mm.
    pub grip_drift_mm: f64,
}
