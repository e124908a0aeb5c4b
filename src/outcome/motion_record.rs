//! How a trial's arm moved, in simulated time: seconds per phase, the measured joint motion
//! against the arm's limits, and how far the held part drifted in the jaws.

use serde::{Deserialize, Serialize};

/// Simulated seconds spent in each phase of a trial.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PhaseSeconds {
    /// The belt brings the part to the photo-eye and stops.
    pub wait: f64,
    /// The camera (or the oracle) looks.
    pub perceive: f64,
    /// Grasp and place are planned.
    pub plan: f64,
    /// Over the part.
    pub approach: f64,
    /// Down around it.
    pub descend: f64,
    /// Jaws close.
    pub grasp: f64,
    /// Up with the part.
    pub lift: f64,
    /// Over to the bin.
    pub transport: f64,
    /// Down into the bin.
    pub place: f64,
    /// Jaws open.
    pub release: f64,
    /// Up and home.
    pub retreat: f64,
    /// A bottle runs through the station.
    pub pass: f64,
}

impl PhaseSeconds {
    /// Every phase's name and seconds, in the order of a pick cycle.
    pub fn named(&self) -> [(&'static str, f64); 12] {
        [
            ("wait", self.wait),
            ("perceive", self.perceive),
            ("plan", self.plan),
            ("approach", self.approach),
            ("descend", self.descend),
            ("grasp", self.grasp),
            ("lift", self.lift),
            ("transport", self.transport),
            ("place", self.place),
            ("release", self.release),
            ("retreat", self.retreat),
            ("pass", self.pass),
        ]
    }
}

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
