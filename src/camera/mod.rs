//! The calibrated camera, shared by the renderer (which draws through it) and perception
//! (which measures through it), below both.

mod calibration;

pub use calibration::{CameraCalibration, RayMissesPlane};
