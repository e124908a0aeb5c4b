//! Areas of interest: a window of the sensor read out at its full pitch while the whole frame is
//! delivered at a coarser one, as industrial cameras bin the full frame and read an area of
//! interest unbinned. The metrology measures a part's bore in such a window.

use image::RgbImage;

use super::motion_blur;
use super::{GpuScene, RenderError, Renderer, Shot};
use crate::camera::CameraCalibration;

/// Window sides are rounded up to a multiple of this many sensor pixels, so that a renderer
/// meets only a few window sizes (it keeps render targets per size).
const SIDE_QUANTUM_PX: u32 = 64;

/// A window of the sensor, in sensor pixels, where the sensor has `scale` pixels per frame pixel
/// along each axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorWindow {
    /// Sensor pixels per frame pixel, per axis.
    pub scale: u32,
    /// First column and row, sensor pixels.
    pub origin_px: (u32, u32),
    /// Width and height, sensor pixels.
    pub size_px: (u32, u32),
    /// The whole sensor's width and height, sensor pixels.
    pub sensor_px: (u32, u32),
}

impl SensorWindow {
    /// The window covering the frame-pixel rectangle `[x0, y0, x1, y1]` of a `frame_px` large
    /// frame, its sides rounded up to a multiple of 64 sensor pixels about the rectangle's centre
    /// and kept on the sensor. `None` when the rectangle misses the frame or `scale` is 0.
    pub fn covering(rect_px: [f64; 4], frame_px: (u32, u32), scale: u32) -> Option<Self> {
        let [x0, y0, x1, y1] = rect_px;
        if scale == 0 || !(x1 > x0 && y1 > y0) {
            return None;
        }
        let sensor = (frame_px.0 * scale, frame_px.1 * scale);
        let s = f64::from(scale);
        // Frame pixel u covers sensor pixels u * scale .. (u + 1) * scale.
        let span = |low: f64, high: f64, limit: u32| -> Option<(u32, u32)> {
            let (a, b) = ((low * s).floor().max(0.0), ((high + 1.0) * s).ceil());
            let b = b.min(f64::from(limit));
            if b <= a {
                return None;
            }
            let side = ((b - a) as u32).div_ceil(SIDE_QUANTUM_PX) * SIDE_QUANTUM_PX;
            let side = side.min(limit);
            let centre = (a + b) / 2.0;
            let start = (centre - f64::from(side) / 2.0).round().max(0.0) as u32;
            Some((start.min(limit - side), side))
        };
        let (ox, w) = span(x0, x1, sensor.0)?;
        let (oy, h) = span(y0, y1, sensor.1)?;
        Some(Self {
            scale,
            origin_px: (ox, oy),
            size_px: (w, h),
            sensor_px: sensor,
        })
    }

    /// The camera `frame` (calibrated for the whole frame) as seen through this window: focal
    /// lengths times the scale, the principal point moved into the window's pixels.
    pub fn calibration(&self, frame: &CameraCalibration) -> CameraCalibration {
        let s = f64::from(self.scale);
        let mut camera = *frame;
        camera.fx_px *= s;
        camera.fy_px *= s;
        // Pixel centres lie at integers: frame pixel u's centre is sensor position
        // (u + 0.5) * scale - 0.5.
        camera.cx_px = (frame.cx_px + 0.5) * s - 0.5 - f64::from(self.origin_px.0);
        camera.cy_px = (frame.cy_px + 0.5) * s - 0.5 - f64::from(self.origin_px.1);
        camera
    }

    /// A window pixel position in frame pixels.
    pub fn to_frame(&self, p: [f64; 2]) -> [f64; 2] {
        let s = f64::from(self.scale);
        [
            (p[0] + f64::from(self.origin_px.0) + 0.5) / s - 0.5,
            (p[1] + f64::from(self.origin_px.1) + 0.5) / s - 0.5,
        ]
    }
}

impl Shot {
    /// Renders `window` of the shot's sensor from the shot's scene as uploaded to `renderer`
    /// ([`Renderer::upload`]): the same scene, camera pose, light and stains as the frame, with
    /// the sensor's effects where that window lies on it.
    pub fn render_window(
        &self,
        renderer: &mut Renderer,
        gpu: &GpuScene,
        window: &SensorWindow,
    ) -> Result<RgbImage, RenderError> {
        let mut exposure = self.exposure.clone();
        exposure.camera = window.calibration(&self.exposure.camera);
        (exposure.width_px, exposure.height_px) = window.size_px;
        let blur = self.scene.blur.as_ref();
        let mut image = motion_blur::render(renderer, gpu, &exposure, blur, Renderer::render)?;
        self.sensor
            .apply_window(&mut image, window.origin_px, window.sensor_px);
        Ok(image)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Point3};

    #[test]
    fn windows_cover_the_rectangle_in_quantised_sides_on_the_sensor() {
        let Some(w) = SensorWindow::covering([100.0, 200.0, 180.0, 260.0], (1280, 960), 2) else {
            panic!("no window");
        };
        assert_eq!(w.sensor_px, (2560, 1920));
        assert_eq!(w.size_px, (192, 128));
        let (ox, oy) = w.origin_px;
        assert!(ox <= 200 && ox + 192 >= 362, "{ox}");
        assert!(oy <= 400 && oy + 128 >= 522, "{oy}");
        // At the sensor's corner the window stays on it.
        let Some(c) = SensorWindow::covering([1270.0, 950.0, 1279.0, 959.0], (1280, 960), 2) else {
            panic!("no window");
        };
        assert_eq!(
            (c.origin_px.0 + c.size_px.0, c.origin_px.1 + c.size_px.1),
            (2560, 1920)
        );
        assert!(SensorWindow::covering([5.0, 5.0, 5.0, 9.0], (1280, 960), 2).is_none());
    }

    #[test]
    fn a_point_projects_to_the_same_frame_position_through_the_window() {
        let frame = CameraCalibration {
            fx_px: 1500.0,
            fy_px: 1500.0,
            cx_px: 639.5,
            cy_px: 479.5,
            world_from_camera: Isometry3::identity(),
            end_face_height_m: 0.0,
        };
        let Some(window) = SensorWindow::covering([300.0, 200.0, 420.0, 330.0], (1280, 960), 3)
        else {
            panic!("no window");
        };
        let seen = window.calibration(&frame);
        let p = Point3::new(-0.07, -0.05, 0.6);
        let (Some(in_frame), Some(in_window)) = (frame.project(&p), seen.project(&p)) else {
            panic!("behind the camera");
        };
        let back = window.to_frame(in_window);
        assert!((back[0] - in_frame[0]).abs() < 1e-9 && (back[1] - in_frame[1]).abs() < 1e-9);
    }
}
