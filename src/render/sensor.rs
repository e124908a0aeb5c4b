//! The image sensor and optics after the render: illumination gradient, vignetting, Gaussian
//! noise and salt-and-pepper, all drawn from a seed so a frame repeats byte for byte.

use std::sync::OnceLock;

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
        let size = image.dimensions();
        self.apply_window(image, (0, 0), size);
    }

    /// Applies the effects to a window of a larger sensor read out on its own: `image` holds
    /// the sensor's pixels from `origin_px` on, of a sensor `sensor_px` large, so the light
    /// gradient and vignetting fall on it as they fall on that part of the whole sensor.
    pub fn apply_window(&self, image: &mut RgbImage, origin_px: (u32, u32), sensor_px: (u32, u32)) {
        if self.is_identity() {
            return;
        }
        let (w, h) = (f64::from(sensor_px.0), f64::from(sensor_px.1));
        let (cx, cy) = (
            (w - 1.0) / 2.0 - f64::from(origin_px.0),
            (h - 1.0) / 2.0 - f64::from(origin_px.1),
        );
        let half_diagonal = ((w - 1.0) / 2.0).hypot((h - 1.0) / 2.0).max(1.0);
        let (gs, gc) = self.gradient_angle_rad.sin_cos();
        let mut rng = SimRng::new(self.noise_seed);
        let normal = Ziggurat::get();
        for (x, y, pixel) in image.enumerate_pixels_mut() {
            let (dx, dy) = (f64::from(x) - cx, f64::from(y) - cy);
            let along = (dx * gc + dy * gs) / half_diagonal;
            let r2 = (dx * dx + dy * dy) / (half_diagonal * half_diagonal);
            let gain = (1.0 + self.gradient * along) * (1.0 - self.vignetting * r2);
            for c in &mut pixel.0 {
                let mut value = f64::from(*c) * gain;
                if self.noise_sigma > 0.0 {
                    value += self.noise_sigma * normal.sample(&mut rng);
                }
                // Round half up by truncation (no libm call: f64::round is one per channel).
                *c = (value.clamp(0.0, 255.0) + 0.5) as u8;
            }
            if self.salt_pepper_fraction > 0.0 && rng.uniform() < self.salt_pepper_fraction {
                let v = if rng.uniform() < 0.5 { 0 } else { 255 };
                pixel.0 = [v; 3];
            }
        }
    }
}

/// Layers of the ziggurat.
const LAYERS: usize = 128;
/// Where the base layer of a 128-layer ziggurat for the standard normal meets its tail.
const TAIL_START: f64 = 3.442_619_855_899;
/// The area of each layer (Marsaglia and Tsang, 2000).
const LAYER_AREA: f64 = 9.912_563_035_262_17e-3;

/// Standard normal deviates by Marsaglia and Tsang's ziggurat: exact (a rejection sampler), and
/// about ten times faster than Box-Muller since 99 % of draws take one random word, a multiply
/// and a compare. Image noise draws three per pixel.
struct Ziggurat {
    /// Right edges of the layers, widest (the base, whose area includes the tail) first; the
    /// last is 0.
    x: [f64; LAYERS + 1],
    /// The unnormalised density `exp(-x^2 / 2)` at each edge.
    f: [f64; LAYERS + 1],
}

/// The standard normal density without its normalising factor.
fn bell(x: f64) -> f64 {
    (-0.5 * x * x).exp()
}

impl Ziggurat {
    /// The tables, built on first use.
    fn get() -> &'static Self {
        static TABLES: OnceLock<Ziggurat> = OnceLock::new();
        TABLES.get_or_init(|| {
            let mut x = [0.0; LAYERS + 1];
            x[0] = LAYER_AREA / bell(TAIL_START);
            x[1] = TAIL_START;
            for i in 1..LAYERS - 1 {
                x[i + 1] = (-2.0 * (LAYER_AREA / x[i] + bell(x[i])).ln()).sqrt();
            }
            Self { x, f: x.map(bell) }
        })
    }

    /// One standard normal deviate.
    fn sample(&self, rng: &mut SimRng) -> f64 {
        loop {
            let bits = rng.next_u64();
            let layer = (bits % LAYERS as u64) as usize;
            let negative = bits & LAYERS as u64 != 0;
            // The top 53 bits, apart from the 8 that chose the layer and the sign.
            let x = (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64) * self.x[layer];
            let accepted = if x < self.x[layer + 1] {
                Some(x)
            } else if layer == 0 {
                Some(Self::tail(rng))
            } else {
                let y = self.f[layer] + rng.uniform() * (self.f[layer + 1] - self.f[layer]);
                (y < bell(x)).then_some(x)
            };
            if let Some(value) = accepted {
                return if negative { -value } else { value };
            }
        }
    }

    /// A deviate beyond [`TAIL_START`] (Marsaglia's tail method).
    fn tail(rng: &mut SimRng) -> f64 {
        loop {
            let a = -(1.0 - rng.uniform()).ln() / TAIL_START;
            let b = -(1.0 - rng.uniform()).ln();
            if 2.0 * b > a * a {
                return TAIL_START + a;
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
    fn ziggurat_deviates_are_standard_normal() {
        let normal = Ziggurat::get();
        assert!(normal.x[LAYERS - 1] > 0.0 && normal.x[LAYERS - 1] < 0.3);
        let mut rng = SimRng::new(5);
        let n = 2_000_000;
        let draws: Vec<f64> = (0..n).map(|_| normal.sample(&mut rng)).collect();
        let count = n as f64;
        let mean = draws.iter().sum::<f64>() / count;
        let variance = draws.iter().map(|z| (z - mean).powi(2)).sum::<f64>() / count;
        assert!(mean.abs() < 5.0 / count.sqrt(), "mean {mean}");
        assert!(
            (variance - 1.0).abs() < 5.0 * (2.0 / count).sqrt(),
            "variance {variance}"
        );
        // Two-sided tail shares of the standard normal, including beyond the ziggurat's base.
        for (beyond, share) in [
            (0.5, 0.617_075_077),
            (1.0, 0.317_310_508),
            (2.0, 0.045_500_264),
            (3.0, 0.002_699_796),
            (TAIL_START, 5.761_085e-4),
            (4.0, 6.334_248e-5),
        ] {
            let seen = draws.iter().filter(|z| z.abs() > beyond).count() as f64 / count;
            let sigma = (share * (1.0 - share) / count).sqrt();
            assert!(
                (seen - share).abs() < 5.0 * sigma,
                "beyond {beyond}: {seen} vs {share}"
            );
        }
        // Both signs, both halves of the base layer.
        let negative = draws.iter().filter(|z| **z < 0.0).count() as f64 / count;
        assert!((negative - 0.5).abs() < 5.0 * (0.25 / count).sqrt());
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
