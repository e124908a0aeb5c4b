//! The sensor model's definition, written out pixel by pixel in f64 with an exact normal
//! sampler: the reference that the fast path in [`super::sensor`] is tested against (same
//! statistics, different streams), and the before figure of `cargo bench --bench render`.
//!
//! For each pixel at `(dx, dy)` from the sensor's centre, `along = (dx cos a + dy sin a) / R`
//! and `r2 = (dx^2 + dy^2) / R^2` with `R` the half diagonal; each channel becomes
//! `round(clamp(c (1 + g along) (1 - v r2) + sigma z, 0, 255))` with `z` standard normal and
//! independent across pixels, channels and frames; then, with probability `p`, the whole pixel
//! is set to black or white (even odds).

use std::sync::OnceLock;

use image::RgbImage;

use super::sensor::SensorDraw;
use crate::rng::SimRng;

impl SensorDraw {
    /// Applies the effects as [`SensorDraw::apply_window`] does, by the model's definition:
    /// one exact normal deviate per channel (a ziggurat) and one uniform per pixel for the
    /// salt-and-pepper. About five times slower than the fast path; kept as its reference.
    pub fn apply_window_reference(
        &self,
        image: &mut RgbImage,
        origin_px: (u32, u32),
        sensor_px: (u32, u32),
    ) {
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
}
