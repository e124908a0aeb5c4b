//! The sensor's effects on a frame binned `k` x `k` on the sensor: what the model of
//! [`super::sensor`] gives at every one of a block's `k^2` pixels, averaged over the block, in
//! one value per block. For the detector's frame ([`super::binned`]).
//!
//! - Gain (light gradient, vignetting): smooth over a block, taken at the block's centre.
//! - Noise: the mean of `k^2` independent deviates of sigma `s`, each pixel rounded to a grey
//!   level (a uniform error of variance 1/12 once the noise dithers it), has sigma
//!   `sqrt((s^2 + 1/12) / k^2)`. Within about two sigma of black or white the full frame clips
//!   each pixel's noise and the binned value only the block's, so there its mean stays nearer
//!   the clip (by up to a fifth of a level at sigma 2 on a level of 3).
//! - Salt-and-pepper: each of the block's `k^2` pixels is hit with probability `p` and set to
//!   black or white, which moves the block's mean by `(0 or 255 - value) / k^2` per hit; the
//!   hits are found by geometric skips over the `k^2`-times finer grid, as on the full frame.

use image::RgbImage;

use super::sensor::{SALT_PEPPER_STREAM, SensorDraw};
use crate::rng::SimRng;

impl SensorDraw {
    /// Applies the effects to `image`, a whole frame binned `bin` x `bin` on the sensor (see
    /// the module). A `bin` of 1 is [`SensorDraw::apply`].
    pub fn apply_binned(&self, image: &mut RgbImage, bin: u32) {
        if bin <= 1 {
            self.apply(image);
            return;
        }
        let area = f64::from(bin * bin);
        let gain_and_noise = SensorDraw {
            noise_sigma: if self.noise_sigma > 0.0 {
                ((self.noise_sigma * self.noise_sigma + 1.0 / 12.0) / area).sqrt()
            } else {
                0.0
            },
            salt_pepper_fraction: 0.0,
            ..*self
        };
        gain_and_noise.apply(image);
        self.binned_salt_and_pepper(image, bin * bin);
    }

    /// Salt-and-pepper over the `area` pixels behind each binned one: every hit moves its
    /// block's mean towards black or white by `1 / area` of the way from its value before the hits.
    fn binned_salt_and_pepper(&self, image: &mut RgbImage, area: u32) {
        let p = self.salt_pepper_fraction;
        if p <= 0.0 {
            return;
        }
        let mut rng = SimRng::derive(self.noise_seed, SALT_PEPPER_STREAM);
        let log_miss = (-p.min(1.0)).ln_1p();
        let pixels = image.as_mut();
        let count = (pixels.len() / 3) as u64 * u64::from(area);
        let skip = |rng: &mut SimRng| super::sensor::misses_before_hit(rng, log_miss, count);
        let area_f = f64::from(area);
        // The block being hit: its first byte, its values before any hit, and the sum of its
        // hits' targets less those values.
        let mut block: Option<(usize, [f64; 3], [f64; 3])> = None;
        let mut index = skip(&mut rng);
        while index < count {
            let at = (index / u64::from(area)) as usize * 3;
            let target = if rng.next_u64() >> 63 == 0 {
                0.0
            } else {
                255.0
            };
            let (clean, pulls) = match &mut block {
                Some((first, clean, pulls)) if *first == at => (*clean, pulls),
                _ => {
                    let clean = [0, 1, 2].map(|c| f64::from(pixels[at + c]));
                    let (_, _, pulls) = block.insert((at, clean, [0.0; 3]));
                    (clean, pulls)
                }
            };
            for c in 0..3 {
                pulls[c] += target - clean[c];
                let value = clean[c] + pulls[c] / area_f;
                pixels[at + c] = value.round().clamp(0.0, 255.0) as u8;
            }
            index = index.saturating_add(1).saturating_add(skip(&mut rng));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `image` shrunk `k` times by block means, each channel rounded half up (the detector's
    /// letterbox).
    fn block_means(image: &RgbImage, k: u32) -> RgbImage {
        let area = k * k;
        RgbImage::from_fn(image.width() / k, image.height() / k, |x, y| {
            let mut sums = [0u32; 3];
            for dy in 0..k {
                for dx in 0..k {
                    let px = image.get_pixel(x * k + dx, y * k + dy);
                    for (sum, value) in sums.iter_mut().zip(px.0) {
                        *sum += u32::from(value);
                    }
                }
            }
            image::Rgb(sums.map(|s| ((s + area / 2) / area) as u8))
        })
    }

    fn mean_sd(values: &[f64]) -> (f64, f64) {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        (mean, var.sqrt())
    }

    /// Channel values of the binned model and of the full frame's model averaged over blocks,
    /// for `frames` frames of a flat `level` frame.
    fn both(level: u8, bin: u32, draw: impl Fn(u64) -> SensorDraw) -> [Vec<f64>; 2] {
        let (w, h) = (160 * bin, 120 * bin);
        let mut binned_values = Vec::new();
        let mut averaged_values = Vec::new();
        for frame in 0..4 {
            let draw = draw(500 + frame);
            let mut binned = RgbImage::from_pixel(w / bin, h / bin, image::Rgb([level; 3]));
            draw.apply_binned(&mut binned, bin);
            let mut full = RgbImage::from_pixel(w, h, image::Rgb([level; 3]));
            draw.apply(&mut full);
            let averaged = block_means(&full, bin);
            binned_values.extend(binned.as_raw().iter().map(|&v| f64::from(v)));
            averaged_values.extend(averaged.as_raw().iter().map(|&v| f64::from(v)));
        }
        [binned_values, averaged_values]
    }

    #[test]
    fn binned_noise_has_the_averaged_frames_mean_and_sigma() {
        for bin in [2, 4] {
            for sigma in [1.0, 2.0, 4.0] {
                // Away from black and white: there the full frame clips each pixel's noise
                // and the binned model only the block's (module docs).
                for level in [20u8, 60, 128, 235] {
                    let [binned, averaged] = both(level, bin, |seed| SensorDraw {
                        gradient_angle_rad: 0.0,
                        gradient: 0.0,
                        vignetting: 0.0,
                        noise_sigma: sigma,
                        salt_pepper_fraction: 0.0,
                        noise_seed: seed,
                    });
                    let ((mb, sb), (ma, sa)) = (mean_sd(&binned), mean_sd(&averaged));
                    // The block means are rounded half up from whole sums, which lifts them
                    // by 1 / (2 k^2) on average; the binned value is rounded to the nearest.
                    let lift = 0.5 / f64::from(bin * bin);
                    assert!(
                        (mb + lift - ma).abs() < 0.05,
                        "bin {bin} sigma {sigma} level {level}: {mb} vs {ma}"
                    );
                    assert!(
                        (sb - sa).abs() < 0.06 + 0.03 * sa,
                        "bin {bin} sigma {sigma} level {level}: sd {sb} vs {sa}"
                    );
                }
            }
        }
    }

    #[test]
    fn binned_gain_is_the_averaged_frames() {
        let draw = SensorDraw {
            gradient_angle_rad: 0.7,
            gradient: 0.12,
            vignetting: 0.2,
            noise_sigma: 0.0,
            salt_pepper_fraction: 0.0,
            noise_seed: 0,
        };
        let bin = 4;
        let mut binned = RgbImage::from_pixel(160, 120, image::Rgb([200; 3]));
        draw.apply_binned(&mut binned, bin);
        let mut full = RgbImage::from_pixel(640, 480, image::Rgb([200; 3]));
        draw.apply(&mut full);
        let averaged = block_means(&full, bin);
        let worst = binned
            .as_raw()
            .iter()
            .zip(averaged.as_raw())
            .map(|(a, b)| a.abs_diff(*b))
            .max();
        assert!(worst <= Some(1), "{worst:?}");
    }

    #[test]
    fn binned_salt_and_pepper_moves_as_many_blocks_by_as_much() {
        let p = 0.004;
        let bin = 4;
        let [binned, averaged] = both(128, bin, |seed| SensorDraw {
            gradient_angle_rad: 0.0,
            gradient: 0.0,
            vignetting: 0.0,
            noise_sigma: 0.0,
            salt_pepper_fraction: p,
            noise_seed: seed,
        });
        // Values of hit blocks: 128 +- 128 / 16 per hit (one hit: 120 or 136).
        let hit = |values: &[f64]| values.iter().filter(|&&v| v != 128.0).count() as f64;
        let (hb, ha) = (hit(&binned), hit(&averaged));
        let n = binned.len() as f64;
        // A block is hit with probability 1 - (1 - p)^16 (6.2 %); five standard errors.
        let expected = n * (1.0 - (1.0 - p).powi(16));
        let tolerance = 5.0 * (expected).sqrt();
        assert!((hb - expected).abs() < tolerance, "{hb} vs {expected}");
        assert!((ha - expected).abs() < tolerance, "{ha} vs {expected}");
        for v in binned.iter().filter(|&&v| v != 128.0) {
            let steps = (v - 128.0) / 8.0;
            assert!(
                (steps - steps.round()).abs() < 0.1 && steps.abs() <= 4.5,
                "{v}"
            );
        }
        let (mb, ma) = (mean_sd(&binned).0, mean_sd(&averaged).0);
        assert!((mb - ma).abs() < 0.1, "{mb} vs {ma}");
    }
}
