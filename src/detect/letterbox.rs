//! Fitting an image into the network's input without distorting it.

use image::RgbImage;
use image::imageops::FilterType;
use ndarray::{Array4, s};

/// The scale and offset that put an image into the network input: input = image x scale +
/// offset. An image of the input's own size passes unchanged (scale 1, no padding).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    /// Input pixels per image pixel.
    pub scale: f32,
    /// Left padding, input px.
    pub offset_x: f32,
    /// Top padding, input px.
    pub offset_y: f32,
}

impl Letterbox {
    /// Scales `image` to fit `width` x `height` (aspect kept), centres it on a `pad`-grey
    /// canvas, and returns the NCHW RGB tensor in 0..1 (byte / 255) with the mapping used.
    ///
    /// An image a whole factor `k` larger than its fitted size (640x480 into 320x256: `k` = 2)
    /// shrinks by `k` x `k` block means, each channel rounded half up; the training side
    /// (`training/common.py`) does exactly the same, so the network sees what it was trained on.
    /// Any other size is scaled bilinearly.
    pub fn apply(image: &RgbImage, width: u32, height: u32, pad: u8) -> (Array4<f32>, Self) {
        let (w, h) = image.dimensions();
        let scale = (width as f32 / w as f32).min(height as f32 / h as f32);
        let (nw, nh) = if w == width && h == height {
            (w, h)
        } else {
            let fit =
                |side: u32, limit: u32| ((side as f32 * scale).round() as u32).clamp(1, limit);
            (fit(w, width), fit(h, height))
        };
        let (ox, oy) = ((width - nw) / 2, (height - nh) / 2);
        let fill = f32::from(pad) / 255.0;
        let mut tensor = Array4::from_elem((1, 3, height as usize, width as usize), fill);
        let k = w / nw;
        if k >= 2 && k * nw == w && k * nh == h {
            let levels = mean_levels(k);
            let mut sums = vec![0; nw as usize * 3];
            for y in 0..nh {
                block_sums(image, k, y, &mut sums);
                write_row(&mut tensor, oy + y, ox, &sums, |sum| levels[sum as usize]);
            }
        } else {
            let resized;
            let source = if (nw, nh) == (w, h) {
                image
            } else {
                resized = image::imageops::resize(image, nw, nh, FilterType::Triangle);
                &resized
            };
            let levels = mean_levels(1);
            for (y, row) in (0..).zip(source.as_raw().chunks_exact(nw as usize * 3)) {
                write_row(&mut tensor, oy + y, ox, row, |byte| {
                    levels[usize::from(byte)]
                });
            }
        }
        let letterbox = Self {
            scale: nw as f32 / w as f32,
            offset_x: ox as f32,
            offset_y: oy as f32,
        };
        (tensor, letterbox)
    }

    /// Maps an input-space box back to image pixels, clipped to an image of `w` x `h`.
    pub fn to_image(&self, b: [f32; 4], w: u32, h: u32) -> [f32; 4] {
        let (w, h) = (w as f32, h as f32);
        [
            ((b[0] - self.offset_x) / self.scale).clamp(0.0, w),
            ((b[1] - self.offset_y) / self.scale).clamp(0.0, h),
            ((b[2] - self.offset_x) / self.scale).clamp(0.0, w),
            ((b[3] - self.offset_y) / self.scale).clamp(0.0, h),
        ]
    }
}

/// Writes interleaved RGB samples, mapped to input values by `value`, into row `y` of each colour
/// plane of `tensor` from column `x`.
fn write_row<T: Copy>(
    tensor: &mut Array4<f32>,
    y: u32,
    x: u32,
    rgb: &[T],
    value: impl Fn(T) -> f32,
) {
    let (y, x) = (y as usize, x as usize);
    let n = rgb.len() / 3;
    for c in 0..3 {
        let mut row = tensor.slice_mut(s![0, c, y, x..x + n]);
        for (out, px) in row.iter_mut().zip(rgb.chunks_exact(3)) {
            *out = value(px[c]);
        }
    }
}

/// The input value for every sum of a `k` x `k` block of bytes: the block's mean, rounded half
/// up, over 255 (a table, so no pixel pays for a division).
fn mean_levels(k: u32) -> Vec<f32> {
    let area = k * k;
    (0..=255 * area)
        .map(|sum| ((sum + area / 2) / area) as f32 / 255.0)
        .collect()
}

/// The per-channel sums of the `k` x `k` blocks making output row `y` of `image` shrunk `k`
/// times, into `sums` (interleaved RGB, one triple per output pixel).
fn block_sums(image: &RgbImage, k: u32, y: u32, sums: &mut [u32]) {
    let k = k as usize;
    let stride = image.width() as usize * 3;
    sums.fill(0);
    for source_row in image.as_raw()[y as usize * k * stride..][..k * stride].chunks_exact(stride) {
        for (sum, block) in sums.chunks_exact_mut(3).zip(source_row.chunks_exact(3 * k)) {
            for px in block.chunks_exact(3) {
                sum[0] += u32::from(px[0]);
                sum[1] += u32::from(px[1]);
                sum[2] += u32::from(px[2]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn native_size_passes_unchanged() {
        let image = RgbImage::from_fn(8, 6, |x, y| image::Rgb([x as u8 * 10, y as u8 * 20, 7]));
        let (t, lb) = Letterbox::apply(&image, 8, 6, 114);
        assert_eq!(
            lb,
            Letterbox {
                scale: 1.0,
                offset_x: 0.0,
                offset_y: 0.0
            }
        );
        assert_eq!(t[[0, 0, 5, 7]], 70.0 / 255.0);
        assert_eq!(t[[0, 1, 5, 7]], 100.0 / 255.0);
        assert_eq!(t[[0, 2, 0, 0]], 7.0 / 255.0);
    }

    #[test]
    fn a_square_image_is_padded_left_and_right_and_maps_back() {
        let image = RgbImage::from_pixel(100, 100, image::Rgb([255, 255, 255]));
        let (t, lb) = Letterbox::apply(&image, 64, 48, 114);
        assert_eq!(lb.scale, 0.48);
        assert_eq!((lb.offset_x, lb.offset_y), (8.0, 0.0));
        assert_eq!(t[[0, 0, 10, 0]], 114.0 / 255.0);
        assert_eq!(t[[0, 0, 10, 8]], 1.0);
        assert_eq!(t[[0, 0, 10, 56]], 114.0 / 255.0);
        let back = lb.to_image([8.0, 0.0, 32.0, 24.0], 100, 100);
        assert_eq!(back, [0.0, 0.0, 50.0, 50.0]);
    }

    #[test]
    fn a_whole_factor_shrinks_by_rounded_block_means_and_pads_rows() {
        // 8x6 into 4x4: k = 2, fitted 4x3, padding 0 rows above and 1 below.
        let image = RgbImage::from_fn(8, 6, |x, y| {
            image::Rgb([(x + 8 * y) as u8, if (x + y) % 2 == 0 { 1 } else { 2 }, 255])
        });
        let (t, lb) = Letterbox::apply(&image, 4, 4, 114);
        assert_eq!(
            lb,
            Letterbox {
                scale: 0.5,
                offset_x: 0.0,
                offset_y: 0.0
            }
        );
        // Block (2, 1) covers x 4..6, y 2..4: red 20, 21, 28, 29 -> 24.5 -> 25.
        assert_eq!(t[[0, 0, 1, 2]], 25.0 / 255.0);
        // Green 1, 2, 2, 1 -> 1.5 -> 2 (half rounds up).
        assert_eq!(t[[0, 1, 1, 2]], 2.0 / 255.0);
        assert_eq!(t[[0, 2, 2, 3]], 1.0);
        assert_eq!(t[[0, 0, 3, 1]], 114.0 / 255.0);
    }

    #[test]
    fn a_camera_frame_fits_the_input_by_block_means_of_its_factor() {
        // 1280x960 into 320x256 (k = 4): 320x240 and 8 grey rows above and below.
        let image = RgbImage::from_fn(1280, 960, |x, y| {
            image::Rgb([(x % 4 * 4 + y % 4) as u8, 9, 0])
        });
        let (t, lb) = Letterbox::apply(&image, 320, 256, 114);
        assert_eq!((lb.scale, lb.offset_x, lb.offset_y), (0.25, 0.0, 8.0));
        // Each block holds 0..16 once: mean 7.5 -> 8.
        assert_eq!(t[[0, 0, 8, 0]], 8.0 / 255.0);
        assert_eq!(t[[0, 0, 247, 319]], 8.0 / 255.0);
        assert_eq!(t[[0, 1, 100, 100]], 9.0 / 255.0);
        assert_eq!(t[[0, 2, 7, 5]], 114.0 / 255.0);
        assert_eq!(t[[0, 2, 248, 5]], 114.0 / 255.0);
        let back = lb.to_image([0.0, 8.0, 320.0, 248.0], 1280, 960);
        assert_eq!(back, [0.0, 0.0, 1280.0, 960.0]);
    }
}
