//! Fitting an image into the network's input without distorting it.

use image::RgbImage;
use image::imageops::FilterType;
use ndarray::Array4;

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
    /// Scales `image` to fit `width` x `height` (aspect kept, bilinear), centres it on a
    /// `pad`-grey canvas, and returns the NCHW RGB tensor in 0..1 with the mapping used.
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
        let resized;
        let source = if (nw, nh) == (w, h) {
            image
        } else {
            resized = image::imageops::resize(image, nw, nh, FilterType::Triangle);
            &resized
        };
        let (ox, oy) = ((width - nw) / 2, (height - nh) / 2);
        let fill = f32::from(pad) / 255.0;
        let mut tensor = Array4::from_elem((1, 3, height as usize, width as usize), fill);
        for (x, y, pixel) in source.enumerate_pixels() {
            let (tx, ty) = ((x + ox) as usize, (y + oy) as usize);
            for c in 0..3 {
                tensor[[0, c, ty, tx]] = f32::from(pixel[c]) / 255.0;
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
}
