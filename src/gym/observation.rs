//! What the controller sees after a control period.

use image::RgbImage;
use nalgebra::Isometry3;

use crate::kinematics::JointVector;

/// The cell's sensors after a control period.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Measured joint angles, rad.
    pub joint_positions_rad: JointVector,
    /// Measured joint velocities over the last control period, rad/s.
    pub joint_velocities_rad_s: JointVector,
    /// Measured distance between the jaws' pads, m.
    pub jaw_width_m: f64,
    /// Force with which each jaw (left, right) pressed on a part in the last physics step, N.
    pub jaw_force_n: [f64; 2],
    /// Whether the photo-eye reports something in its beam.
    pub photo_eye: bool,
    /// The belt's travel as its encoder counts it since the trial began, m.
    pub belt_position_m: f64,
    /// The belt's surface speed, m/s.
    pub belt_speed_m_s: f64,
    /// Simulated time since the trial began, s.
    pub sim_time_s: f64,
    /// The camera's frame as the sensor delivers it, when the action asked for one.
    pub frame: Option<RgbImage>,
    /// The truth, in oracle mode only.
    pub truth: Option<Truth>,
}

/// What the world knows (oracle mode only): the trial's part and its bottles.
#[derive(Debug, Clone, PartialEq)]
pub struct Truth {
    /// The part's type, its index in the scenario's catalogue.
    pub part_type: usize,
    /// The part's pose in the world (its origin at the tube's centre, half its height above its base).
    pub world_from_part: Isometry3<f64>,
    /// The bore's true roundness, mm.
    pub roundness_mm: f64,
    /// The bore's true mean diameter, mm.
    pub bore_diameter_mm: f64,
    /// The bin the truth calls for, its index in the scenario's bins.
    pub correct_bin: Option<usize>,
    /// Each bottle's pose in the world.
    pub world_from_bottles: Vec<Isometry3<f64>>,
}
