//! Validation of the camera, its lights and its sensor: every check names the key and the
//! reason; a camera outside [`CAMERA_ENVELOPE`] is refused with the envelope in the message.

use super::Scenario;
use super::ScenarioError;
use super::camera_sections::{CAMERA_ENVELOPE, CameraSection};
use super::validate::{Checker, MAX_CELL_REACH_M};

/// Tilt past the envelope's edge still accepted, degrees (rounding of given coordinates).
const EDGE_SLACK_DEG: f64 = 0.02;
/// Distance past the envelope's edges still accepted, m.
const EDGE_SLACK_M: f64 = 1e-4;
/// Longest exposure a scenario may give, ms: beyond it a belt frame is a smear.
pub const MAX_EXPOSURE_MS: f64 = 50.0;

impl Scenario {
    /// Checks `[camera]`, `[lights]` and `[sensor]`.
    pub(super) fn validate_camera(&self, c: &Checker) -> Result<(), ScenarioError> {
        let camera = &self.camera;
        let envelope = CAMERA_ENVELOPE;
        let outside = |key: &str, what: String| c.fail(key, format!("{what}; {envelope}"));
        let [w, h] = camera.resolution_px;
        let [w_low, h_low] = envelope.min_resolution_px;
        let [w_high, h_high] = envelope.max_resolution_px;
        if !(w_low..=w_high).contains(&w) || !(h_low..=h_high).contains(&h) {
            return Err(outside(
                "camera.resolution_px",
                format!("{w} x {h} pixels is outside the envelope"),
            ));
        }
        let [fov_low, fov_high] = envelope.horizontal_fov_deg;
        let fov = camera.horizontal_fov_deg;
        if !(fov.is_finite() && (fov_low..=fov_high).contains(&fov)) {
            return Err(outside(
                "camera.horizontal_fov_deg",
                format!("must lie in [{fov_low}, {fov_high}] degrees, got {fov}"),
            ));
        }
        let [roll_low, roll_high] = envelope.roll_deg;
        let roll = camera.roll_deg;
        if !(roll.is_finite() && (roll_low..=roll_high).contains(&roll)) {
            return Err(outside(
                "camera.roll_deg",
                format!("must lie in [{roll_low}, {roll_high}] degrees, got {roll}"),
            ));
        }
        if !matches!(camera.msaa_samples, 1 | 4) {
            return Err(c.fail("camera.msaa_samples", "must be 1 or 4"));
        }
        if !(1..=4).contains(&camera.supersample) {
            return Err(c.fail("camera.supersample", "must lie in [1, 4]"));
        }
        if !(1..=4).contains(&camera.roi_scale) {
            return Err(c.fail("camera.roi_scale", "must lie in [1, 4]"));
        }
        c.in_range(
            "camera.exposure_ms",
            camera.exposure_ms,
            0.0,
            MAX_EXPOSURE_MS,
        )?;
        if let Some(p) = camera.position_m {
            c.point_within("camera.position_m", &p, MAX_CELL_REACH_M)?;
        }
        if let Some(p) = camera.look_at_m {
            c.point_within("camera.look_at_m", &p, MAX_CELL_REACH_M)?;
        }
        let (eye, target) = camera.eye_and_target(&self.conveyor);
        let view = [target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]];
        let length = view.iter().map(|v| v * v).sum::<f64>().sqrt();
        // The axis is set by the point looked at when one is given, else by the position.
        let axis_key = if camera.look_at_m.is_some() {
            "camera.look_at_m"
        } else {
            "camera.position_m"
        };
        if length < 1e-6 {
            return Err(c.fail(axis_key, "the camera looks at its own centre"));
        }
        let (tilt, distance) = camera.tilt_and_distance(&self.conveyor);
        // Slack for an axis or a distance given at the envelope's very edge in rounded
        // coordinates (0.1 mm at 0.4 m turns the axis by 0.014 degrees).
        if tilt.is_nan() || tilt > envelope.max_tilt_deg + EDGE_SLACK_DEG {
            return Err(outside(
                axis_key,
                format!(
                    "the optical axis is {tilt:.1} degrees from vertical, more than {} \
                     (camera at {eye:?} m looking at {target:?} m)",
                    envelope.max_tilt_deg
                ),
            ));
        }
        let [d_low, d_high] = envelope.distance_m;
        if !(d_low - EDGE_SLACK_M..=d_high + EDGE_SLACK_M).contains(&distance) {
            return Err(outside(
                "camera.position_m",
                format!(
                    "the camera is {distance:.3} m from the pick station {:?} m, outside \
                     [{d_low}, {d_high}] m",
                    CameraSection::pick_station(&self.conveyor)
                ),
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
