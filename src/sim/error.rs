//! Errors of the simulation layer.

use std::path::PathBuf;

/// Why the simulated world could not be built or stepped.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A URDF file could not be read or parsed.
    #[error("cannot load URDF: {reason}: {}", path.display())]
    Urdf {
        /// Why.
        reason: String,
        /// The file.
        path: PathBuf,
    },
    /// A joint the cell needs is missing from the URDF.
    #[error("URDF has no joint named `{joint}`: {}", path.display())]
    MissingJoint {
        /// The joint's name.
        joint: String,
        /// The file.
        path: PathBuf,
    },
    /// The arm's kinematic model cannot be used.
    #[error(transparent)]
    Kinematics(#[from] crate::kinematics::KinematicsError),
    /// A body left the finite numbers: the simulation blew up.
    #[error("physics blow-up: {what} became non-finite at t = {time_s:.3} s")]
    BlowUp {
        /// What went non-finite.
        what: String,
        /// Simulated time.
        time_s: f64,
    },
}
