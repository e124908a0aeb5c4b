//! Motion blur over the camera's exposure: a frame taken while the belt runs integrates the
//! light of every moving object over the exposure time. The blur is rendered, not painted on:
//! the exposure is cut into sub-frames, each renders the scene with every object moved along
//! its own velocity (read from the physics when the scene was built) to that sub-frame's
//! instant, and the sub-frames average. Things at rest stay sharp; items on the belt smear
//! along the image direction of the belt's travel, by as many pixels as the belt carries them
//! during the exposure; the robot, when it moves in view, smears along its own motion.
//!
//! The sub-frames sit at the middles of equal slices of the exposure, centred on the moment the
//! scene was read, so the blurred image's centroid is the snapshot's. Their spacing is at most
//! [`SUB_FRAME_STEP_M`] of the fastest object's travel (well under the area of interest's pixel
//! pitch at the default camera), at most [`MAX_SUB_FRAMES`] of them.

use image::RgbImage;
use nalgebra::Vector3;

use super::error::RenderError;
use super::gpu_scene::GpuScene;
use super::renderer::{Exposure, Renderer};
use super::scene::Scene;
use crate::cell::Cell;
use crate::math::vector_from_physics;

/// Largest travel of any object between two sub-frames, m.
pub const SUB_FRAME_STEP_M: f64 = 0.000_1;
/// Most sub-frames one exposure is cut into.
pub const MAX_SUB_FRAMES: usize = 32;
/// Objects slower than this count as at rest, m/s.
const AT_REST_M_S: f64 = 1e-4;

/// The motion over one exposure: its length and each scene object's velocity.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionBlur {
    /// Exposure time, s.
    pub exposure_s: f64,
    /// Each scene object's linear velocity in the world, m/s, in the scene's object order.
    pub velocities_m_s: Vec<Vector3<f64>>,
}

impl MotionBlur {
    /// The motion of `scene`'s objects as `cell`'s physics has them now, over an exposure of
    /// `exposure_ms`; `None` for an instant frame (0 ms) or a scene at rest.
    pub fn of_cell(scene: &Scene, cell: &Cell, exposure_ms: f64) -> Option<Self> {
        if exposure_ms <= 0.0 {
            return None;
        }
        let bodies = &cell.world.physics.bodies;
        let velocities_m_s: Vec<Vector3<f64>> = scene
            .objects
            .iter()
            .map(|object| {
                object
                    .body
                    .and_then(|b| bodies.get(b))
                    .map_or_else(Vector3::zeros, |rb| vector_from_physics(rb.linvel()))
            })
            .collect();
        let blur = Self {
            exposure_s: exposure_ms * 1e-3,
            velocities_m_s,
        };
        (blur.sub_frames() > 1).then_some(blur)
    }

    /// The longest travel of any object during the exposure, m.
    pub fn longest_travel_m(&self) -> f64 {
        let fastest = self
            .velocities_m_s
            .iter()
            .map(|v| v.norm())
            .filter(|&v| v >= AT_REST_M_S)
            .fold(0.0, f64::max);
        fastest * self.exposure_s
    }

    /// How many sub-frames the exposure is cut into.
    pub fn sub_frames(&self) -> usize {
        let steps = (self.longest_travel_m() / SUB_FRAME_STEP_M).ceil();
        (steps as usize).clamp(1, MAX_SUB_FRAMES)
    }

    /// The instants of the sub-frames, s from the moment the scene was read.
    pub fn instants_s(&self) -> Vec<f64> {
        let n = self.sub_frames();
        (0..n)
            .map(|k| ((k as f64 + 0.5) / n as f64 - 0.5) * self.exposure_s)
            .collect()
    }
}

/// Renders `gpu` as `exposure` sees it, blurred by `blur` when there is one: the average of
/// the sub-frames, each rendered by `render_one` with the objects moved to its instant. Without
/// a blur it is `render_one`'s image as is.
pub(super) fn render(
    renderer: &mut Renderer,
    gpu: &GpuScene,
    exposure: &Exposure,
    blur: Option<&MotionBlur>,
    render_one: impl Fn(&mut Renderer, &GpuScene, &Exposure) -> Result<RgbImage, RenderError>,
) -> Result<RgbImage, RenderError> {
    let Some(blur) = blur.filter(|b| b.velocities_m_s.len() == gpu.poses.len()) else {
        return render_one(renderer, gpu, exposure);
    };
    let mut sum: Vec<u32> = Vec::new();
    let mut size = (0, 0);
    let instants = blur.instants_s();
    for &t_s in &instants {
        let moved = GpuScene {
            vertices: gpu.vertices.clone(),
            ranges: gpu.ranges.clone(),
            draw_order: gpu.draw_order.clone(),
            poses: gpu
                .poses
                .iter()
                .zip(&blur.velocities_m_s)
                .map(|(pose, v)| {
                    let mut pose = *pose;
                    pose.translation.vector += v * t_s;
                    pose
                })
                .collect(),
            bounds: gpu.bounds.clone(),
        };
        let image = render_one(renderer, &moved, exposure)?;
        if sum.is_empty() {
            size = image.dimensions();
            sum = vec![0; image.as_raw().len()];
        }
        for (s, &p) in sum.iter_mut().zip(image.as_raw()) {
            *s += u32::from(p);
        }
    }
    let n = instants.len() as u32;
    let pixels = sum.iter().map(|&s| ((s + n / 2) / n) as u8).collect();
    RgbImage::from_raw(size.0, size.1, pixels)
        .ok_or_else(|| RenderError::Gpu("blurred frame of the wrong size".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blur(speed_m_s: f64, exposure_ms: f64) -> MotionBlur {
        MotionBlur {
            exposure_s: exposure_ms * 1e-3,
            velocities_m_s: vec![Vector3::zeros(), Vector3::new(speed_m_s, 0.0, 0.0)],
        }
    }

    #[test]
    fn sub_frames_cover_the_travel_at_the_step_and_centre_on_the_snapshot() {
        for (speed, ms) in [(0.1, 1.0), (0.25, 2.0), (0.5, 4.0), (0.25, 0.3)] {
            let b = blur(speed, ms);
            let n = b.sub_frames();
            let travel = speed * ms * 1e-3;
            assert!((travel / n as f64) <= SUB_FRAME_STEP_M + 1e-12 || n == MAX_SUB_FRAMES);
            let instants = b.instants_s();
            assert_eq!(instants.len(), n);
            let mean: f64 = instants.iter().sum::<f64>() / n as f64;
            assert!(mean.abs() < 1e-12, "{mean}");
            let span = instants[n - 1] - instants[0];
            assert!((span - b.exposure_s * (n - 1) as f64 / n as f64).abs() < 1e-12);
        }
    }

    #[test]
    fn a_scene_at_rest_takes_one_frame() {
        assert_eq!(blur(0.0, 5.0).sub_frames(), 1);
        assert_eq!(blur(1e-6, 5.0).sub_frames(), 1);
        assert_eq!(blur(10.0, 50.0).sub_frames(), MAX_SUB_FRAMES);
    }
}
