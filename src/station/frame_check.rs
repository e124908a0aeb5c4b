//! Whether a frame the camera delivered can be trusted at all: a camera whose shutter, lamp
//! or link has failed delivers frames with nothing in them, and a controller that ran its
//! detector on one would take "nothing detected" for an empty station.

use image::RgbImage;

/// The brightest a blank frame's pixels may be (of 255): a lit belt reads far above it, and a
/// failed sensor's dark noise stays under it.
pub const BLANK_LEVEL: u8 = 24;

/// Whether `image` is blank: no pixel brighter than [`BLANK_LEVEL`] in any channel.
pub fn frame_is_blank(image: &RgbImage) -> bool {
    image.as_raw().iter().all(|&v| v <= BLANK_LEVEL)
}

/// The frame a blacked-out camera delivers: `width` x `height`, all black.
pub fn black_frame(width: u32, height: u32) -> RgbImage {
    RgbImage::new(width, height)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;

    #[test]
    fn a_black_frame_and_dark_noise_are_blank_and_one_lit_pixel_is_not() {
        assert!(frame_is_blank(&black_frame(64, 48)));
        let mut rng = SimRng::new(4);
        let mut noisy = black_frame(64, 48);
        for p in noisy.pixels_mut() {
            p.0 = [0; 3].map(|_| rng.below(u64::from(BLANK_LEVEL) + 1) as u8);
        }
        assert!(frame_is_blank(&noisy));
        noisy.put_pixel(10, 10, image::Rgb([0, BLANK_LEVEL + 1, 0]));
        assert!(!frame_is_blank(&noisy));
    }
}
