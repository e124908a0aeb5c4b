//! The camera model shared by the renderer and perception: pinhole intrinsics, the camera pose
//! and the end-face plane.
//!
//! Conventions: the camera frame is x right, y down, z forward (along the optical axis), so a
//! pixel `(u, v)` (pixel centres at integers) views the ray `((u - cx) / fx, (v - cy) / fy, 1)`.
//! The world's z axis points up; tube end faces lie in the plane `z = end_face_height_m`.
//! No lens distortion is modelled (the rendered camera has none). Units: metres, radians.

use nalgebra::{Isometry3, Point3, Vector3};

/// A pixel's viewing ray does not meet the plane asked for in front of the camera.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("the ray through pixel ({x_px:.2}, {y_px:.2}) does not meet the end-face plane")]
pub struct RayMissesPlane {
    /// Pixel x.
    pub x_px: f64,
    /// Pixel y.
    pub y_px: f64,
}

/// A calibrated pinhole camera looking at the end-face plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraCalibration {
    /// Focal length along x, pixels.
    pub fx_px: f64,
    /// Focal length along y, pixels.
    pub fy_px: f64,
    /// Principal point x, pixels.
    pub cx_px: f64,
    /// Principal point y, pixels.
    pub cy_px: f64,
    /// Camera pose in the world.
    pub world_from_camera: Isometry3<f64>,
    /// Height of the tubes' end faces above the world origin.
    pub end_face_height_m: f64,
}

impl CameraCalibration {
    /// A square-pixel camera of `width_px` x `height_px` with horizontal field of view
    /// `horizontal_fov_rad`, its principal point at the image centre (pixel centres at integers,
    /// so the centre is `((width - 1) / 2, (height - 1) / 2)`).
    pub fn from_fov(
        width_px: u32,
        height_px: u32,
        horizontal_fov_rad: f64,
        world_from_camera: Isometry3<f64>,
        end_face_height_m: f64,
    ) -> Self {
        let f_px = f64::from(width_px) / 2.0 / (horizontal_fov_rad / 2.0).tan();
        Self {
            fx_px: f_px,
            fy_px: f_px,
            cx_px: (f64::from(width_px) - 1.0) / 2.0,
            cy_px: (f64::from(height_px) - 1.0) / 2.0,
            world_from_camera,
            end_face_height_m,
        }
    }

    /// The pose of a camera at `eye_in_world` looking at `target_in_world`, its image x axis as
    /// close to `right_in_world` as the viewing direction allows (camera x right, y down, z
    /// forward). `None` when the eye and target coincide or `right_in_world` is along the view.
    pub fn look_at(
        eye_in_world: &Point3<f64>,
        target_in_world: &Point3<f64>,
        right_in_world: &Vector3<f64>,
    ) -> Option<Isometry3<f64>> {
        let z = (target_in_world - eye_in_world).try_normalize(1e-12)?;
        let x = (right_in_world - z * z.dot(right_in_world)).try_normalize(1e-9)?;
        let y = z.cross(&x);
        let rotation =
            nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_columns(&[x, y, z]));
        Some(Isometry3::from_parts(
            nalgebra::Translation3::from(eye_in_world.coords),
            nalgebra::UnitQuaternion::from_rotation_matrix(&rotation),
        ))
    }

    /// The same camera with the end-face plane at `end_face_height_m`.
    pub fn with_end_face_height(mut self, end_face_height_m: f64) -> Self {
        self.end_face_height_m = end_face_height_m;
        self
    }

    /// The camera's centre in the world.
    pub fn origin_in_world(&self) -> Point3<f64> {
        Point3::from(self.world_from_camera.translation.vector)
    }

    /// Direction (unit length, world frame) of the ray through pixel `(x_px, y_px)`.
    pub fn pixel_to_ray(&self, x_px: f64, y_px: f64) -> Vector3<f64> {
        let ray_in_camera = Vector3::new(
            (x_px - self.cx_px) / self.fx_px,
            (y_px - self.cy_px) / self.fy_px,
            1.0,
        );
        (self.world_from_camera.rotation * ray_in_camera).normalize()
    }

    /// Where the ray through pixel `(x_px, y_px)` meets the horizontal plane `z = height_m`.
    pub fn pixel_to_height(
        &self,
        x_px: f64,
        y_px: f64,
        height_m: f64,
    ) -> Result<Point3<f64>, RayMissesPlane> {
        let ray_in_world = self.pixel_to_ray(x_px, y_px);
        let origin_in_world = self.origin_in_world();
        let t = (height_m - origin_in_world.z) / ray_in_world.z;
        if !t.is_finite() || t <= 0.0 {
            return Err(RayMissesPlane { x_px, y_px });
        }
        Ok(origin_in_world + ray_in_world * t)
    }

    /// Image size in pixels on the end-face plane of one metre there, near pixel `(x_px, y_px)`.
    pub fn px_per_m_at(&self, x_px: f64, y_px: f64) -> Result<f64, RayMissesPlane> {
        let a = self.pixel_to_plane(x_px - 0.5, y_px)?;
        let b = self.pixel_to_plane(x_px + 0.5, y_px)?;
        Ok(1.0 / (b - a).norm())
    }

    /// Where the ray through pixel `(x_px, y_px)` meets the end-face plane, world frame.
    pub fn pixel_to_plane(&self, x_px: f64, y_px: f64) -> Result<Point3<f64>, RayMissesPlane> {
        self.pixel_to_height(x_px, y_px, self.end_face_height_m)
    }

    /// Pixel of a world point (the inverse of [`Self::pixel_to_plane`] on the plane).
    pub fn project(&self, point_in_world: &Point3<f64>) -> Option<[f64; 2]> {
        let point_in_camera = self
            .world_from_camera
            .inverse_transform_point(point_in_world);
        if point_in_camera.z <= 0.0 {
            return None;
        }
        Some([
            self.fx_px * point_in_camera.x / point_in_camera.z + self.cx_px,
            self.fy_px * point_in_camera.y / point_in_camera.z + self.cy_px,
        ])
    }
}

/// A camera 1 m above a plane at 0.1 m, looking straight down and slightly rolled: a fixture
/// for the tests of the camera and of what is measured through it.
#[cfg(test)]
pub(crate) fn overhead_camera() -> CameraCalibration {
    let rotation = nalgebra::UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.3);
    CameraCalibration {
        fx_px: 1200.0,
        fy_px: 1200.0,
        cx_px: 320.0,
        cy_px: 240.0,
        world_from_camera: Isometry3::from_parts(
            nalgebra::Translation3::new(0.1, -0.05, 1.0),
            rotation,
        ),
        end_face_height_m: 0.1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_pixel_to_plane() {
        let calibration = overhead_camera();
        let Ok(point) = calibration.pixel_to_plane(100.5, 400.25) else {
            panic!("ray misses");
        };
        assert!((point.z - 0.1).abs() < 1e-12);
        let Some(pixel) = calibration.project(&point) else {
            panic!("behind camera");
        };
        assert!((pixel[0] - 100.5).abs() < 1e-9 && (pixel[1] - 400.25).abs() < 1e-9);
    }

    #[test]
    fn fov_camera_looking_down_maps_centre_and_edges() {
        let eye = Point3::new(0.05, -0.45, 1.3);
        let Some(world_from_camera) =
            CameraCalibration::look_at(&eye, &Point3::new(0.05, -0.45, 0.7), &Vector3::x())
        else {
            panic!("degenerate look-at");
        };
        let fov = 40f64.to_radians();
        let calibration = CameraCalibration::from_fov(640, 480, fov, world_from_camera, 0.7);
        // The optical axis hits the point below the camera at the image centre.
        let Some(centre) = calibration.project(&Point3::new(0.05, -0.45, 0.7)) else {
            panic!("behind camera");
        };
        assert!((centre[0] - 319.5).abs() < 1e-9 && (centre[1] - 239.5).abs() < 1e-9);
        // The left edge of pixel 0 lies at half the field of view; +x world is image right,
        // +y world is image up.
        let half_width_m = 0.6 * (fov / 2.0).tan();
        let Some(left) = calibration.project(&Point3::new(0.05 - half_width_m, -0.45, 0.7)) else {
            panic!("behind camera");
        };
        assert!((left[0] + 0.5).abs() < 1e-9, "{left:?}");
        let Some(up) = calibration.project(&Point3::new(0.05, -0.40, 0.7)) else {
            panic!("behind camera");
        };
        assert!(up[1] < 239.5);
        let ray = calibration.pixel_to_ray(centre[0], centre[1]);
        assert!((ray - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        let Ok(px_per_m) = calibration.px_per_m_at(319.5, 239.5) else {
            panic!("ray misses");
        };
        assert!((px_per_m - calibration.fx_px / 0.6).abs() < 1e-6);
    }
}
