//! Errors of the kinematics layer.

/// Why a kinematic model or query could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KinematicsError {
    /// The DH table does not have the structure the closed-form solver assumes.
    #[error("unsupported arm geometry for the analytic solver: {reason}")]
    UnsupportedGeometry {
        /// What is wrong with the table.
        reason: String,
    },
    /// A robot description that cannot be read.
    #[error("the URDF cannot be read: {reason}")]
    Urdf {
        /// What the reader said.
        reason: String,
    },
    /// A joint value is outside its limits.
    #[error("joint {joint} at {value_rad} rad is outside [{min_rad}, {max_rad}]")]
    JointOutOfLimit {
        /// Joint index, 0-based.
        joint: usize,
        /// The offending value.
        value_rad: f64,
        /// Lower limit.
        min_rad: f64,
        /// Upper limit.
        max_rad: f64,
    },
    /// A value is not finite.
    #[error("{what} is not finite")]
    NotFinite {
        /// What was not finite.
        what: &'static str,
    },
}
