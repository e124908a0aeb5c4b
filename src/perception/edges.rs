//! Canny edge detection (seed paper section 2.4): Gaussian smoothing (sigma 1.4), Sobel
//! gradients, non-maximum suppression and hysteresis between two thresholds.
//!
//! imageproc's implementation does the job: the main bore pipeline never runs Canny (it follows the
//! borders of the thresholded image directly and then refines edges to sub-pixel positions), so
//! Canny only runs in the paper's classic pipeline and in `--compare`, where its cost is reported.

use image::GrayImage;

/// Canny edge map: 255 on edge pixels, 0 elsewhere. Thresholds are on the Sobel gradient
/// magnitude (at most about 1140 for 8-bit images).
///
/// # Panics
///
/// Panics if `low_threshold > high_threshold`.
pub fn canny(image: &GrayImage, low_threshold: f32, high_threshold: f32) -> GrayImage {
    imageproc::edges::canny(image, low_threshold, high_threshold)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    #[test]
    fn a_square_gives_a_thin_closed_edge() {
        let mut image = GrayImage::from_pixel(40, 40, Luma([20]));
        for y in 10..30 {
            for x in 10..30 {
                image.put_pixel(x, y, Luma([220]));
            }
        }
        let edges = canny(&image, 50.0, 150.0);
        assert!(crate::perception::threshold::is_binary(&edges));
        // Every edge pixel lies within 2 px of the square's outline.
        for (x, y, p) in edges.enumerate_pixels() {
            if p[0] == 255 {
                let near_x = (x as i32 - 10).abs() <= 2 || (x as i32 - 29).abs() <= 2;
                let near_y = (y as i32 - 10).abs() <= 2 || (y as i32 - 29).abs() <= 2;
                assert!(near_x || near_y, "edge at ({x}, {y})");
            }
        }
        assert!(edges.pixels().filter(|p| p[0] == 255).count() >= 70);
    }
}
