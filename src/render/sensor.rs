//! The image sensor and optics after the render: illumination gradient, vignetting, Gaussian
//! noise and salt-and-pepper, all drawn from a seed so a frame repeats byte for byte.

use image::RgbImage;

use crate::rng::SimRng;
use crate::scenario::SensorSection;

/// One frame's drawn sensor effects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorDraw {
    /// Direction of the illumination gradient in the image, rad.
    pub gradient_angle_rad: f64,
    /// Relative brightness change from the image centre to its edge along that direction.
    pub gradient: f64,
    /// Relative darkening at the corners.
    pub vignetting: f64,
    /// Gaussian noise sigma, grey levels.
    pub noise_sigma: f64,
    /// Share of pixels forced to black or white.
    pub salt_pepper_fraction: f64,
    /// Seed of the noise stream.
    pub noise_seed: u64,
}

impl SensorDraw {
    /// Draws a frame's effects from the scenario's sensor settings.
    pub fn draw(sensor: &SensorSection, rng: &mut SimRng) -> Self {
        Self {
            gradient_angle_rad: rng.range(0.0, std::f64::consts::TAU),
            gradient: rng.range(0.0, sensor.illumination_gradient),
            vignetting: sensor.vignetting,
            noise_sigma: sensor.noise_sigma,
            salt_pepper_fraction: sensor.salt_pepper_fraction,
            noise_seed: rng.next_u64(),
        }
    }

    /// Whether the draw changes an image at all.
    pub fn is_identity(&self) -> bool {
        self.gradient == 0.0
            && self.vignetting == 0.0
            && self.noise_sigma == 0.0
            && self.salt_pepper_fraction == 0.0
    }

    /// Applies the effects to a rendered image in place.
    pub fn apply(&self, image: &mut RgbImage) {
        if self.is_identity() {
            return;
        }
        let (w, h) = (f64::from(image.width()), f64::from(image.height()));
        let (cx, cy) = ((w - 1.0) / 2.0, (h - 1.0) / 2.0);
        let half_diagonal = cx.hypot(cy).max(1.0);
        let (gs, gc) = self.gradient_angle_rad.sin_cos();
        let mut rng = SimRng::new(self.noise_seed);
        let mut spare: Option<f64> = None;
        let mut normal = |rng: &mut SimRng| -> f64 {
            if let Some(z) = spare.take() {
                return z;
            }
            let (z, next) = rng.normal_pair();
            spare = Some(next);
            z
        };
        for (x, y, pixel) in image.enumerate_pixels_mut() {
            let (dx, dy) = (f64::from(x) - cx, f64::from(y) - cy);
            let along = (dx * gc + dy * gs) / half_diagonal;
            let r2 = (dx * dx + dy * dy) / (half_diagonal * half_diagonal);
            let gain = (1.0 + self.gradient * along) * (1.0 - self.vignetting * r2);
            for c in &mut pixel.0 {
                let mut value = f64::from(*c) * gain;
                if self.noise_sigma > 0.0 {
                    value += self.noise_sigma * normal(&mut rng);
                }
                *c = value.round().clamp(0.0, 255.0) as u8;
            }
            if self.salt_pepper_fraction > 0.0 && rng.uniform() < self.salt_pepper_fraction {
                let v = if rng.uniform() < 0.5 { 0 } else { 255 };
                pixel.0 = [v; 3];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_has_the_asked_sigma_and_repeats() {
        let draw = SensorDraw {
            gradient_angle_rad: 0.0,
            gradient: 0.0,
            vignetting: 0.0,
            noise_sigma: 4.0,
            salt_pepper_fraction: 0.0,
            noise_seed: 11,
        };
        let mut a = RgbImage::from_pixel(200, 100, image::Rgb([128, 128, 128]));
        let mut b = a.clone();
        draw.apply(&mut a);
        draw.apply(&mut b);
        assert_eq!(a, b);
        let values: Vec<f64> = a.as_raw().iter().map(|&v| f64::from(v) - 128.0).collect();
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sigma = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
        assert!(
            mean.abs() < 0.1 && (sigma - 4.0).abs() < 0.15,
            "{mean} {sigma}"
        );
    }

    #[test]
    fn vignetting_darkens_corners_not_the_centre() {
        let draw = SensorDraw {
            gradient_angle_rad: 0.0,
            gradient: 0.0,
            vignetting: 0.3,
            noise_sigma: 0.0,
            salt_pepper_fraction: 0.0,
            noise_seed: 0,
        };
        let mut image = RgbImage::from_pixel(101, 101, image::Rgb([200, 200, 200]));
        draw.apply(&mut image);
        assert_eq!(image.get_pixel(50, 50).0[0], 200);
        assert_eq!(image.get_pixel(0, 0).0[0], 140);
    }
}
