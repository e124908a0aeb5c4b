//! Validation of the camera, its lights and its sensor: every check names the key and the
//! reason.

use super::Scenario;
use super::validate::{Checker, MAX_CELL_REACH_M, ScenarioError};

impl Scenario {
    /// Checks `[camera]`, `[lights]` and `[sensor]`.
    pub(super) fn validate_camera(&self, c: &Checker) -> Result<(), ScenarioError> {
        let camera = &self.camera;
        let [w, h] = camera.resolution_px;
        if !(16..=8192).contains(&w) || !(16..=8192).contains(&h) {
            return Err(c.fail(
                "camera.resolution_px",
                format!("each side must lie in [16, 8192] pixels, got {w} x {h}"),
            ));
        }
        c.in_range(
            "camera.horizontal_fov_deg",
            camera.horizontal_fov_deg,
            1.0,
            150.0,
        )?;
        if !matches!(camera.msaa_samples, 1 | 4) {
            return Err(c.fail("camera.msaa_samples", "must be 1 or 4"));
        }
        if !(1..=4).contains(&camera.supersample) {
            return Err(c.fail("camera.supersample", "must lie in [1, 4]"));
        }
        if !(1..=4).contains(&camera.roi_scale) {
            return Err(c.fail("camera.roi_scale", "must lie in [1, 4]"));
        }
        if let Some(p) = camera.position_m {
            c.point_within("camera.position_m", &p, MAX_CELL_REACH_M)?;
        }
        if let Some(p) = camera.look_at_m {
            c.point_within("camera.look_at_m", &p, MAX_CELL_REACH_M)?;
        }
        let (eye, target) = camera.eye_and_target(&self.conveyor);
        let view = [target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]];
        let length = view.iter().map(|v| v * v).sum::<f64>().sqrt();
        if length < 1e-6 || view[2] > -0.5 * length {
            return Err(c.fail(
                "camera.look_at_m",
                "the camera must look down at the belt (within 60 degrees of straight down)",
            ));
        }
        let top_z = self.conveyor.belt_center_m[2]
            + self
                .part_types
                .iter()
                .map(|p| p.height_mm / 1000.0)
                .fold(0.0, f64::max);
        if eye[2] <= top_z + 0.05 {
            return Err(c.fail(
                "camera.position_m",
                "must be at least 5 cm above the tallest part's end face",
            ));
        }
        let lighting = &self.lighting;
        c.in_range("lighting.ambient", lighting.ambient, 0.0, 2.0)?;
        if lighting.lights.len() > 4 {
            return Err(c.fail("lighting.lights", "at most 4 lights"));
        }
        for (i, light) in lighting.lights.iter().enumerate() {
            c.finite(&format!("lighting.lights[{i}].direction"), &light.direction)?;
            if light.direction.iter().map(|v| v * v).sum::<f64>() < 1e-12 {
                return Err(c.fail(
                    format!("lighting.lights[{i}].direction"),
                    "must not be zero",
                ));
            }
            c.in_range(
                &format!("lighting.lights[{i}].intensity"),
                light.intensity,
                0.0,
                10.0,
            )?;
        }
        let sensor = &self.sensor;
        c.in_range("sensor.noise_sigma", sensor.noise_sigma, 0.0, 64.0)?;
        c.in_range(
            "sensor.salt_pepper_fraction",
            sensor.salt_pepper_fraction,
            0.0,
            0.2,
        )?;
        c.in_range(
            "sensor.illumination_gradient",
            sensor.illumination_gradient,
            0.0,
            0.9,
        )?;
        c.in_range("sensor.vignetting", sensor.vignetting, 0.0, 0.9)?;
        if sensor.max_stains > 16 {
            return Err(c.fail("sensor.max_stains", "at most 16 stains per end face"));
        }
        if sensor.max_dirt > 16 {
            return Err(c.fail("sensor.max_dirt", "at most 16 dirt specks per end face"));
        }
        c.in_range(
            "sensor.light_jitter_deg",
            sensor.light_jitter_deg,
            0.0,
            45.0,
        )?;
        c.in_range("sensor.intensity_jitter", sensor.intensity_jitter, 0.0, 0.9)?;
        c.in_range("sensor.pose_jitter_m", sensor.pose_jitter_m, 0.0, 0.05)?;
        c.in_range("sensor.pose_jitter_deg", sensor.pose_jitter_deg, 0.0, 5.0)?;
        Ok(())
    }
}
