//! The camera object of `twincell render`'s `shot.json`, written by `render` and read back by
//! `measure --calibration` and the Python package: one type for every direction, so they cannot
//! drift apart.

use super::CameraCalibration;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// A pinhole camera as JSON: intrinsics in pixels and its pose in the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraJson {
    /// Image width, px.
    pub width_px: u32,
    /// Image height, px.
    pub height_px: u32,
    /// Focal length along x, px.
    pub fx_px: f64,
    /// Focal length along y, px.
    pub fy_px: f64,
    /// Principal point x, px.
    pub cx_px: f64,
    /// Principal point y, px.
    pub cy_px: f64,
    /// Row-major 4x4 pose of the camera in the world (x right, y down, z forward).
    pub world_from_camera: [[f64; 4]; 4],
}

impl CameraJson {
    /// The JSON of `camera` for an image of `width_px` x `height_px`.
    pub fn new(camera: &CameraCalibration, width_px: u32, height_px: u32) -> Self {
        let m = camera.world_from_camera.to_homogeneous();
        Self {
            width_px,
            height_px,
            fx_px: camera.fx_px,
            fy_px: camera.fy_px,
            cx_px: camera.cx_px,
            cy_px: camera.cy_px,
            world_from_camera: std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)])),
        }
    }

    /// The calibration it describes, with the end-face plane at z = 0; the error is the field
    /// that is wrong and why.
    pub fn calibration(&self) -> Result<CameraCalibration, (&'static str, String)> {
        for (field, v) in [("fx_px", self.fx_px), ("fy_px", self.fy_px)] {
            if !(v.is_finite() && v > 0.0) {
                return Err((field, format!("{v} is not > 0")));
            }
        }
        let m = self.world_from_camera;
        let rotation = Matrix3::new(
            m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
        );
        if (rotation.transpose() * rotation - Matrix3::identity()).norm() > 1e-6
            || m[3] != [0.0, 0.0, 0.0, 1.0]
        {
            return Err((
                "world_from_camera",
                "not a rigid transform (rotation and translation, last row 0 0 0 1)".into(),
            ));
        }
        let rotation =
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
        Ok(CameraCalibration {
            fx_px: self.fx_px,
            fy_px: self.fy_px,
            cx_px: self.cx_px,
            cy_px: self.cy_px,
            world_from_camera: Isometry3::from_parts(
                Translation3::new(m[0][3], m[1][3], m[2][3]),
                rotation,
            ),
            end_face_height_m: 0.0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_calibration_survives_the_json_round_trip() {
        let camera = CameraCalibration {
            fx_px: 812.5,
            fy_px: 809.25,
            cx_px: 319.5,
            cy_px: 241.0,
            world_from_camera: Isometry3::from_parts(
                Translation3::new(0.05, -0.45, 1.6),
                UnitQuaternion::from_euler_angles(3.1, 0.02, -0.4),
            ),
            end_face_height_m: 0.0,
        };
        let text = serde_json::to_string(&CameraJson::new(&camera, 640, 480)).unwrap();
        let back: CameraJson = serde_json::from_str(&text).unwrap();
        assert_eq!((back.width_px, back.height_px), (640, 480));
        let restored = back.calibration().unwrap();
        assert_eq!(restored.fx_px, camera.fx_px);
        assert_eq!(restored.cy_px, camera.cy_px);
        let moved = restored.world_from_camera.inverse() * camera.world_from_camera;
        assert!(moved.translation.vector.norm() < 1e-12);
        assert!(moved.rotation.angle() < 1e-9);
    }

    #[test]
    fn a_bad_focal_length_or_pose_names_its_field() {
        let camera = CameraCalibration {
            fx_px: 800.0,
            fy_px: 800.0,
            cx_px: 320.0,
            cy_px: 240.0,
            world_from_camera: Isometry3::identity(),
            end_face_height_m: 0.0,
        };
        let mut json = CameraJson::new(&camera, 640, 480);
        json.fy_px = -1.0;
        assert_eq!(json.calibration().unwrap_err().0, "fy_px");
        let mut json = CameraJson::new(&camera, 640, 480);
        json.world_from_camera[0][0] = 2.0;
        assert_eq!(json.calibration().unwrap_err().0, "world_from_camera");
    }
}
