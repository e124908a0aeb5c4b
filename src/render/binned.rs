//! The detector's frame binned on the sensor: the look's whole frame is read only by the
//! detector, which fits it into its input by `k` x `k` block means (the letterbox's whole-factor
//! path, 1280 x 960 into 320 x 256: `k` = 4). Drawing the `k`-times finer frame to average it
//! away is most of a look's render; a sensor binning `k` x `k` delivers those block means itself.
//! So the frame is drawn at the binned size (with the renderer's MSAA), given the binned sensor's
//! effects ([`super::sensor::SensorDraw::apply_binned`]), and delivered at the frame's pitch with each binned
//! value over its `k` x `k` block: the block means the detector takes are the binned values.

use image::RgbImage;

use super::motion_blur;
use super::{GpuScene, RenderError, Renderer, Shot};
use crate::camera::CameraCalibration;

/// The binning that a reader fitting a `frame_px` large frame into a `reader_px` large input
/// reads through block means: the whole factor `k` (at least 2) by which the frame is larger
/// than its fitted size, or 1 when the fit is not such a factor (the reader then scales the
/// frame some other way, and the frame is drawn unbinned).
///
/// The fit is the detector's letterbox: scale by the smaller of the
/// two side ratios, sides rounded, aspect kept.
pub fn reader_bin(frame_px: (u32, u32), reader_px: (u32, u32)) -> u32 {
    let ((w, h), (width, height)) = (frame_px, reader_px);
    if w == 0 || h == 0 || width == 0 || height == 0 || (w, h) == (width, height) {
        return 1;
    }
    let scale = (width as f32 / w as f32).min(height as f32 / h as f32);
    let fit = |side: u32, limit: u32| ((side as f32 * scale).round() as u32).clamp(1, limit);
    let (nw, nh) = (fit(w, width), fit(h, height));
    let k = w / nw;
    if k >= 2 && k * nw == w && k * nh == h {
        k
    } else {
        1
    }
}

/// `frame` (calibrated for the whole frame) as a sensor binning `bin` x `bin` sees it: focal
/// lengths over the bin, the principal point moved so that each binned pixel's centre is the
/// centre of its block.
pub fn binned_calibration(frame: &CameraCalibration, bin: u32) -> CameraCalibration {
    let k = f64::from(bin);
    let mut camera = *frame;
    camera.fx_px /= k;
    camera.fy_px /= k;
    // Frame pixel u's centre (at u) lies in binned pixel b = u div k, whose centre is at frame
    // position (b + 0.5) k - 0.5.
    camera.cx_px = (frame.cx_px + 0.5) / k - 0.5;
    camera.cy_px = (frame.cy_px + 0.5) / k - 0.5;
    camera
}

/// `binned` delivered at `bin` times its pitch: every value repeated over its `bin` x `bin`
/// block.
pub fn unbin(binned: &RgbImage, bin: u32) -> RgbImage {
    let (w, h) = binned.dimensions();
    let k = bin as usize;
    let row_bytes = w as usize * 3 * k;
    let mut out = vec![0u8; row_bytes * h as usize * k];
    for (source, block) in binned
        .as_raw()
        .chunks_exact(w as usize * 3)
        .zip(out.chunks_exact_mut(row_bytes * k))
    {
        let (first, rest) = block.split_at_mut(row_bytes);
        for (px, wide) in source.chunks_exact(3).zip(first.chunks_exact_mut(3 * k)) {
            for out_px in wide.chunks_exact_mut(3) {
                out_px.copy_from_slice(px);
            }
        }
        for row in rest.chunks_exact_mut(row_bytes) {
            row.copy_from_slice(first);
        }
    }
    let Some(image) = RgbImage::from_raw(w * bin, h * bin, out) else {
        unreachable!("the buffer holds exactly the unbinned image");
    };
    image
}

/// A frame as a sensor binning `bin` x `bin` delivers it: `binned` holds one value per block
/// ([`Shot::render_binned_frame`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BinnedFrame {
    /// The binned values, `bin` times smaller than the frame each way.
    pub binned: RgbImage,
    /// The binning (1: `binned` is the frame itself).
    pub bin: u32,
}

impl BinnedFrame {
    /// The frame at its own pitch, every binned value over its block ([`unbin`]).
    pub fn into_frame(self) -> RgbImage {
        if self.bin < 2 {
            self.binned
        } else {
            unbin(&self.binned, self.bin)
        }
    }
}

impl Shot {
    /// Renders the frame a look's detector reads, binned `bin` x `bin` on the sensor (see the
    /// module), from the shot's scene as already uploaded to `renderer`: the image at the
    /// frame's size, each `bin` x `bin` block one binned value. A `bin` of 1, or one that does
    /// not divide the frame, draws the frame as [`Shot::render_uploaded`] does.
    pub fn render_binned(
        &self,
        renderer: &mut Renderer,
        gpu: &GpuScene,
        bin: u32,
    ) -> Result<RgbImage, RenderError> {
        self.render_binned_frame(renderer, gpu, bin)
            .map(BinnedFrame::into_frame)
    }

    /// [`Self::render_binned`]'s frame as the binned values themselves, before they are spread
    /// over their blocks: for a reader that takes the block means (the detector's letterbox),
    /// which are these values.
    pub fn render_binned_frame(
        &self,
        renderer: &mut Renderer,
        gpu: &GpuScene,
        bin: u32,
    ) -> Result<BinnedFrame, RenderError> {
        let (w, h) = (self.exposure.width_px, self.exposure.height_px);
        if bin < 2 || w % bin != 0 || h % bin != 0 {
            let frame = self.render_uploaded(renderer, gpu)?;
            return Ok(BinnedFrame {
                binned: frame,
                bin: 1,
            });
        }
        let mut exposure = self.exposure.clone();
        exposure.camera = binned_calibration(&self.exposure.camera, bin);
        (exposure.width_px, exposure.height_px) = (w / bin, h / bin);
        let blur = self.scene.blur.as_ref();
        let mut binned = motion_blur::render(renderer, gpu, &exposure, blur, Renderer::render)?;
        self.sensor.apply_binned(&mut binned, bin);
        Ok(BinnedFrame { binned, bin })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Point3};

    #[test]
    fn the_reader_bin_is_the_letterboxs_whole_factor() {
        assert_eq!(reader_bin((1280, 960), (320, 256)), 4);
        assert_eq!(reader_bin((640, 480), (320, 256)), 2);
        assert_eq!(reader_bin((320, 240), (320, 256)), 1);
        assert_eq!(reader_bin((320, 256), (320, 256)), 1);
        // 1000 x 750 fits as 320 x 240: no whole factor, read bilinearly.
        assert_eq!(reader_bin((1000, 750), (320, 256)), 1);
        // A wide frame: 1920 x 1080 fits as 320 x 180, six times smaller.
        assert_eq!(reader_bin((1920, 1080), (320, 256)), 6);
        assert_eq!(reader_bin((0, 480), (320, 256)), 1);
    }

    #[test]
    fn a_point_falls_in_the_binned_pixel_of_its_frame_pixel() {
        let frame = CameraCalibration {
            fx_px: 1500.0,
            fy_px: 1480.0,
            cx_px: 639.5,
            cy_px: 479.5,
            world_from_camera: Isometry3::identity(),
            end_face_height_m: 0.0,
        };
        for bin in [2, 3, 4] {
            let binned = binned_calibration(&frame, bin);
            for p in [
                Point3::new(-0.07, -0.05, 0.6),
                Point3::new(0.11, 0.02, 0.9),
                Point3::new(0.0, 0.0, 0.5),
            ] {
                let (Some(f), Some(b)) = (frame.project(&p), binned.project(&p)) else {
                    panic!("behind the camera");
                };
                let k = f64::from(bin);
                for axis in 0..2 {
                    // Frame position u lies at binned position (u + 0.5) / k - 0.5.
                    let expected = (f[axis] + 0.5) / k - 0.5;
                    assert!((b[axis] - expected).abs() < 1e-9, "{bin} {axis}");
                }
            }
        }
    }

    #[test]
    fn unbinned_blocks_average_back_to_the_binned_values() {
        let binned = RgbImage::from_fn(5, 3, |x, y| image::Rgb([x as u8 * 40, y as u8 * 70, 9]));
        let wide = unbin(&binned, 4);
        assert_eq!(wide.dimensions(), (20, 12));
        for (x, y, px) in wide.enumerate_pixels() {
            assert_eq!(px, binned.get_pixel(x / 4, y / 4), "({x}, {y})");
        }
    }
}
