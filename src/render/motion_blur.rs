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
//! [`SUB_FRAME_STEP_PX`] of that render's pixel (at its centre, on the end-face plane) of the
//! travel of the fastest object that render sees (the arm swinging a part to a bin out of view
//! adds none), at most [`MAX_SUB_FRAMES`] of them: the area of interest, read at
//! the sensor's full pitch, takes as many as its pixels need, the binned frame the detector reads
//! a few (a sixteenth of the area of interest's at the default camera's 4x4 binning).

use image::RgbImage;
use nalgebra::Vector3;

use super::cull::View;
use super::error::RenderError;
use super::gpu_scene::GpuScene;
use super::renderer::{Exposure, Renderer};
use super::scene::Scene;
use crate::cell::Cell;
use crate::math::vector_from_physics;

/// Largest travel of any object between two sub-frames, m, where a render's pixel size is not
/// known (and the travel below which a scene counts as at rest).
pub const SUB_FRAME_STEP_M: f64 = 0.000_1;
/// Largest travel of any object between two sub-frames, pixels of the render at its centre.
pub const SUB_FRAME_STEP_PX: f64 = 0.5;
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
        (blur.sub_frames(SUB_FRAME_STEP_M) > 1).then_some(blur)
    }

    /// The longest travel of any object during the exposure, m.
    pub fn longest_travel_m(&self) -> f64 {
        self.longest_travel_of_m(0..self.velocities_m_s.len())
    }

    /// The longest travel of the objects `seen` (indices in the scene's object order) during
    /// the exposure, m.
    pub fn longest_travel_of_m(&self, seen: impl IntoIterator<Item = usize>) -> f64 {
        let fastest = seen
            .into_iter()
            .filter_map(|i| self.velocities_m_s.get(i))
            .map(|v| v.norm())
            .filter(|&v| v >= AT_REST_M_S)
            .fold(0.0, f64::max);
        fastest * self.exposure_s
    }

    /// How many sub-frames the exposure is cut into, at most `step_m` of travel apart.
    pub fn sub_frames(&self, step_m: f64) -> usize {
        sub_frames_for(self.longest_travel_m(), step_m)
    }

    /// The instants of the sub-frames at most `step_m` of travel apart, s from the moment the
    /// scene was read.
    pub fn instants_s(&self, step_m: f64) -> Vec<f64> {
        self.instants_of(self.sub_frames(step_m))
    }

    /// The instants of `n` sub-frames, s from the moment the scene was read.
    fn instants_of(&self, n: usize) -> Vec<f64> {
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
    let travel_m = blur.longest_travel_of_m(seen(gpu, exposure));
    let instants = blur.instants_of(sub_frames_for(travel_m, step_m(exposure)));
    if instants.len() == 1 {
        return render_one(renderer, gpu, exposure);
    }
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

/// How many sub-frames cover `travel_m` at most `step_m` apart.
fn sub_frames_for(travel_m: f64, step_m: f64) -> usize {
    let steps = (travel_m / step_m).ceil();
    (steps as usize).clamp(1, MAX_SUB_FRAMES)
}

/// The objects of `gpu` that a render through `exposure`'s camera sees, as the renderer culls
/// them (their bounds in the frustum and not behind an occluder).
fn seen(gpu: &GpuScene, exposure: &Exposure) -> Vec<usize> {
    let camera_from_world = exposure.camera.world_from_camera.inverse();
    let camera_from_object: Vec<_> = gpu.poses.iter().map(|p| camera_from_world * p).collect();
    View::of_exposure(exposure).visible(&gpu.bounds, &camera_from_object, &gpu.draw_order)
}

/// The sub-frame step of a render through `exposure`'s camera: [`SUB_FRAME_STEP_PX`] of its
/// pixel at the image's centre on the camera's end-face plane ([`SUB_FRAME_STEP_M`] where that
/// ray misses the plane).
pub fn step_m(exposure: &Exposure) -> f64 {
    let centre = (
        (f64::from(exposure.width_px) - 1.0) / 2.0,
        (f64::from(exposure.height_px) - 1.0) / 2.0,
    );
    match exposure.camera.px_per_m_at(centre.0, centre.1) {
        Ok(px_per_m) if px_per_m > 0.0 => SUB_FRAME_STEP_PX / px_per_m,
        _ => SUB_FRAME_STEP_M,
    }
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
            let n = b.sub_frames(SUB_FRAME_STEP_M);
            let travel = speed * ms * 1e-3;
            assert!((travel / n as f64) <= SUB_FRAME_STEP_M + 1e-12 || n == MAX_SUB_FRAMES);
            let instants = b.instants_s(SUB_FRAME_STEP_M);
            assert_eq!(instants.len(), n);
            let mean: f64 = instants.iter().sum::<f64>() / n as f64;
            assert!(mean.abs() < 1e-12, "{mean}");
            let span = instants[n - 1] - instants[0];
            assert!((span - b.exposure_s * (n - 1) as f64 / n as f64).abs() < 1e-12);
        }
    }

    #[test]
    fn a_scene_at_rest_takes_one_frame() {
        assert_eq!(blur(0.0, 5.0).sub_frames(SUB_FRAME_STEP_M), 1);
        assert_eq!(blur(1e-6, 5.0).sub_frames(SUB_FRAME_STEP_M), 1);
        assert_eq!(
            blur(10.0, 50.0).sub_frames(SUB_FRAME_STEP_M),
            MAX_SUB_FRAMES
        );
    }

    #[test]
    fn the_step_is_half_a_pixel_of_each_render_so_a_binned_frame_takes_fewer_sub_frames() {
        use crate::camera::CameraCalibration;
        use crate::render::binned::binned_calibration;
        use crate::rng::SimRng;
        use nalgebra::{Point3, Vector3};
        let mut rng = SimRng::new(26);
        for _ in 0..40 {
            let station = Point3::new(rng.range(-0.2, 0.2), -0.45, 0.7);
            let eye = station + Vector3::new(0.0, rng.range(-0.3, 0.3), rng.range(0.35, 1.2));
            let pose = CameraCalibration::look_at(&eye, &station, &Vector3::x()).expect("a view");
            let width = [640, 1024, 1280, 2048][rng.below(4) as usize];
            let fov = rng.range(35.0_f64, 80.0).to_radians();
            let camera = CameraCalibration::from_fov(width, width * 3 / 4, fov, pose, station.z);
            let exposure = |camera: CameraCalibration, w: u32, h: u32| Exposure {
                camera,
                width_px: w,
                height_px: h,
                ambient: 0.3,
                lights: Vec::new(),
                stains: Vec::new(),
            };
            let full = step_m(&exposure(camera, width, width * 3 / 4));
            let centre = (
                (f64::from(width) - 1.0) / 2.0,
                (f64::from(width * 3 / 4) - 1.0) / 2.0,
            );
            let pixel_m = 1.0
                / camera
                    .px_per_m_at(centre.0, centre.1)
                    .expect("on the plane");
            assert!((full - SUB_FRAME_STEP_PX * pixel_m).abs() < 1e-12);
            let binned = step_m(&exposure(
                binned_calibration(&camera, 4),
                width / 4,
                width * 3 / 16,
            ));
            assert!((binned / full - 4.0).abs() < 0.01, "{binned} vs {full}");
            // A belt at 0.1-0.6 m/s over a 0.5-4 ms exposure: the binned frame never takes more
            // sub-frames than the full-pitch one, and each keeps to its own half pixel.
            let b = blur(rng.range(0.1, 0.6), rng.range(0.5, 4.0));
            let (n_full, n_binned) = (b.sub_frames(full), b.sub_frames(binned));
            assert!(n_binned <= n_full);
            for (n, step) in [(n_full, full), (n_binned, binned)] {
                assert!(b.longest_travel_m() / n as f64 <= step + 1e-12 || n == MAX_SUB_FRAMES);
            }
        }
    }
}
