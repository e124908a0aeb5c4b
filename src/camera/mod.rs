//! The calibrated camera, shared by the renderer (which draws through it) and perception
//! (which measures through it), below both.

mod calibration;
mod camera_json;

#[cfg(test)]
pub(crate) use calibration::overhead_camera;
pub use calibration::{CameraCalibration, RayMissesPlane};
pub use camera_json::CameraJson;
