//! The image sensor and optics after the render: illumination gradient, vignetting, Gaussian
//! noise and salt-and-pepper, all drawn from a seed so a frame repeats byte for byte.

use image::RgbImage;

use super::sensor_noise::FastNormal;
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
    ///
    /// The model is written out in [`SensorDraw::apply_window_reference`]; this is the same
    /// model at an eighth of the cost: the gain row by row in f32 (eight values at a time where
    /// the CPU has AVX2), the normal deviates from a quantile table (four per random word, a
    /// word's tail check done once on its bits) with exact tails, and salt-and-pepper pixels
    /// found by geometric skips instead of one uniform per pixel. The tests below compare the
    /// two over many frames.
    pub fn apply_window(&self, image: &mut RgbImage, origin_px: (u32, u32), sensor_px: (u32, u32)) {
        if self.is_identity() {
            return;
        }
        let width = image.width() as usize;
        if width == 0 {
            return;
        }
        let (w, h) = (f64::from(sensor_px.0), f64::from(sensor_px.1));
        let (cx, cy) = (
            (w - 1.0) / 2.0 - f64::from(origin_px.0),
            (h - 1.0) / 2.0 - f64::from(origin_px.1),
        );
        let half_diagonal = ((w - 1.0) / 2.0).hypot((h - 1.0) / 2.0).max(1.0);
        let (gs, gc) = self.gradient_angle_rad.sin_cos();
        let inv_r = 1.0 / half_diagonal;
        // Per pixel: gain = (1 + g along) (1 - v r2), along = (dx cos + dy sin) / R,
        // r2 = (dx^2 + dy^2) / R^2, in f32 (the output is whole grey levels).
        let (grad_x, grad_y) = (
            (self.gradient * gc * inv_r) as f32,
            (self.gradient * gs * inv_r) as f32,
        );
        let vig = (self.vignetting * inv_r * inv_r) as f32;
        // Each pixel's dx, gradient term and squared distance once per channel, so that the
        // row loop runs over flat channel arrays (which the compiler turns into SIMD).
        let dxs: Vec<f32> = (0..3 * width)
            .map(|i| ((i / 3) as f64 - cx) as f32)
            .collect();
        let along_x: Vec<f32> = dxs.iter().map(|dx| grad_x * dx).collect();
        let dx2: Vec<f32> = dxs.iter().map(|dx| dx * dx).collect();
        let mut normal = FastNormal::new(self.noise_seed);
        let columns = Columns {
            along_x: &along_x,
            dx2: &dx2,
        };
        let rows = Rows {
            cy,
            grad_y,
            vignetting: vig,
            sigma: self.noise_sigma as f32,
        };
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the function only requires AVX2, which the CPU was just found to have.
            unsafe { expose_avx2(image.as_mut(), &mut normal, &columns, &rows) };
            self.salt_and_pepper(image);
            return;
        }
        expose(image.as_mut(), &mut normal, &columns, &rows);
        self.salt_and_pepper(image);
    }

    /// Sets each pixel, with probability `salt_pepper_fraction`, to black or white: the hit
    /// pixels are found by geometric skips (the gaps between independent Bernoulli hits) from a
    /// stream of their own.
    fn salt_and_pepper(&self, image: &mut RgbImage) {
        let p = self.salt_pepper_fraction;
        if p <= 0.0 {
            return;
        }
        let mut rng = SimRng::derive(self.noise_seed, SALT_PEPPER_STREAM);
        // ln(1 - p), negative; at p = 1 every pixel is hit.
        let log_miss = (-p.min(1.0)).ln_1p();
        let pixels = image.as_mut().chunks_exact_mut(3);
        let count = pixels.len() as u64;
        let skip = |rng: &mut SimRng| misses_before_hit(rng, log_miss, count);
        let mut index = skip(&mut rng);
        let mut pixels = pixels;
        let mut at = 0u64;
        while index < count {
            let Some(pixel) = pixels.nth((index - at) as usize) else {
                break;
            };
            at = index + 1;
            let v = if rng.next_u64() >> 63 == 0 { 0 } else { 255 };
            pixel.fill(v);
            index = index.saturating_add(1).saturating_add(skip(&mut rng));
        }
    }
}

/// Per channel of a row: the gradient term `grad_x dx` and the squared distance `dx^2`.
struct Columns<'a> {
    along_x: &'a [f32],
    dx2: &'a [f32],
}

/// What changes from row to row: `dy = y - cy`, and the frame's constants.
struct Rows {
    cy: f64,
    grad_y: f32,
    vignetting: f32,
    sigma: f32,
}

/// [`expose`] compiled for AVX2: the same IEEE operations in the same order for every value
/// (Rust never fuses a multiply and an add), so the same bytes, eight values at a time.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn expose_avx2(pixels: &mut [u8], normal: &mut FastNormal, columns: &Columns, rows: &Rows) {
    expose(pixels, normal, columns, rows);
}

/// Applies gain and noise to every row of `pixels` (rows of `columns.dx2.len()` channel
/// values): `value = c (1 + grad_y dy + grad_x dx) (1 - v (dx^2 + dy^2)) + sigma n`, rounded to
/// a grey level.
#[inline(always)]
fn expose(pixels: &mut [u8], normal: &mut FastNormal, columns: &Columns, rows: &Rows) {
    let len = columns.dx2.len();
    let mut noise = vec![0.0f32; len];
    for (y, row) in pixels.chunks_exact_mut(len).enumerate() {
        let dy = (y as f64 - rows.cy) as f32;
        let (along, dy2) = (1.0 + rows.grad_y * dy, dy * dy);
        if rows.sigma > 0.0 {
            normal.fill(&mut noise);
        }
        let values = row.iter_mut().zip(&noise);
        for ((c, n), (ax, d2)) in values.zip(columns.along_x.iter().zip(columns.dx2)) {
            let gain = (along + ax) * (1.0 - rows.vignetting * (d2 + dy2));
            let value = f32::from(*c) * gain + rows.sigma * n;
            // Rounded to the nearest level by adding 2^23, where an f32's step is 1: the level
            // is then the low bits of the sum. A bit cast vectorises, a float to integer cast
            // does not.
            *c = ((value.clamp(0.0, 255.0) + 8_388_608.0).to_bits() & 0xff) as u8;
        }
    }
}

/// Salt of the salt-and-pepper stream, derived from the frame's noise seed.
pub(super) const SALT_PEPPER_STREAM: u64 = 0x5a17;
/// Misses before the next hit of a salt-and-pepper draw with `log_miss` = ln(1 - p) over `count`
/// pixels: floor(ln U / ln(1 - p)), U uniform in (0, 1]; `count` once that runs past the end,
/// 0 at p = 1.
pub(super) fn misses_before_hit(rng: &mut SimRng, log_miss: f64, count: u64) -> u64 {
    if log_miss == f64::NEG_INFINITY {
        return 0;
    }
    let gap = (1.0 - rng.uniform()).ln() / log_miss;
    if gap >= count as f64 {
        count
    } else {
        gap as u64
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

    /// A draw with only noise (and optionally salt-and-pepper), seeded.
    fn noise_only(sigma: f64, salt_pepper: f64, seed: u64) -> SensorDraw {
        SensorDraw {
            gradient_angle_rad: 0.0,
            gradient: 0.0,
            vignetting: 0.0,
            noise_sigma: sigma,
            salt_pepper_fraction: salt_pepper,
            noise_seed: seed,
        }
    }

    /// Output values of `frames` frames of `clean` through the fast path and the reference.
    fn both(clean: &RgbImage, frames: u64, draw: impl Fn(u64) -> SensorDraw) -> [Vec<RgbImage>; 2] {
        let size = clean.dimensions();
        let mut fast = Vec::new();
        let mut reference = Vec::new();
        for frame in 0..frames {
            let draw = draw(1000 + frame);
            let mut a = clean.clone();
            draw.apply_window(&mut a, (0, 0), size);
            fast.push(a);
            let mut b = clean.clone();
            draw.apply_window_reference(&mut b, (0, 0), size);
            reference.push(b);
        }
        [fast, reference]
    }

    fn mean_sd(values: &[f64]) -> (f64, f64) {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        (mean, var.sqrt())
    }

    #[test]
    fn fast_noise_matches_the_reference_at_every_grey_level() {
        // Column x holds grey level x: every level, clamping at both ends included.
        let clean = RgbImage::from_fn(256, 64, |x, _| image::Rgb([x as u8; 3]));
        let sigma = 3.0;
        let [fast, reference] = both(&clean, 24, |seed| noise_only(sigma, 0.0, seed));
        for level in 0..256u32 {
            let column = |frames: &[RgbImage]| -> Vec<f64> {
                frames
                    .iter()
                    .flat_map(|f| (0..64).flat_map(move |y| f.get_pixel(level, y).0))
                    .map(f64::from)
                    .collect()
            };
            let (a, b) = (column(&fast), column(&reference));
            let ((ma, sa), (mb, sb)) = (mean_sd(&a), mean_sd(&b));
            let n = a.len() as f64;
            // Five standard errors of the difference of two independent estimates.
            let mean_tol = 5.0 * (sa * sa / n + sb * sb / n).sqrt() + 1e-9;
            let sd_tol = 5.0 * sigma / (n).sqrt() + 1e-9;
            assert!(
                (ma - mb).abs() <= mean_tol,
                "level {level}: mean {ma} vs {mb}"
            );
            assert!((sa - sb).abs() <= sd_tol, "level {level}: sd {sa} vs {sb}");
            if (10..246).contains(&level) {
                // Away from the clamps both are the model's sigma around the level.
                assert!(
                    (sa - sigma).abs() < 5.0 * sigma / n.sqrt(),
                    "level {level}: sd {sa}"
                );
                assert!(
                    (ma - f64::from(level)).abs() < 5.0 * sigma / n.sqrt(),
                    "level {level}"
                );
            }
        }
    }

    #[test]
    fn fast_noise_has_the_reference_histogram_and_no_spatial_correlation() {
        let (w, h) = (320u32, 240u32);
        let clean = RgbImage::from_pixel(w, h, image::Rgb([128; 3]));
        let [fast, reference] = both(&clean, 12, |seed| noise_only(4.0, 0.0, seed));
        let mut histograms = [[0u64; 256]; 2];
        for (histogram, frames) in histograms.iter_mut().zip([&fast, &reference]) {
            for v in frames.iter().flat_map(|f| f.as_raw()) {
                histogram[usize::from(*v)] += 1;
            }
        }
        // Two-sample chi-square over the levels both see often enough; the rare tails pooled.
        let (mut chi2, mut bins, mut tail) = (0.0, 0usize, [0u64; 2]);
        for (&a, &b) in histograms[0].iter().zip(&histograms[1]) {
            if a + b < 50 {
                tail[0] += a;
                tail[1] += b;
                continue;
            }
            chi2 += (a as f64 - b as f64).powi(2) / (a + b) as f64;
            bins += 1;
        }
        chi2 += (tail[0] as f64 - tail[1] as f64).powi(2) / ((tail[0] + tail[1]).max(1)) as f64;
        let df = bins as f64;
        assert!(
            chi2 < df + 5.0 * (2.0 * df).sqrt(),
            "chi2 {chi2} on {df} bins"
        );
        assert!(tail[0] > 0, "the fast noise never reached the tails");
        // Correlation of the noise with its neighbour to the right, below, and in the next
        // channel: zero for both (independent draws), within five standard errors.
        for frames in [&fast, &reference] {
            let residual =
                |f: &RgbImage, x: u32, y: u32, c: usize| f64::from(f.get_pixel(x, y).0[c]) - 128.0;
            for (name, step) in [
                ("right", (1, 0, 0)),
                ("below", (0, 1, 0)),
                ("channel", (0, 0, 1)),
            ] {
                let (mut sxy, mut sxx, mut n) = (0.0, 0.0, 0.0);
                for f in frames.iter() {
                    for y in 0..h - 1 {
                        for x in 0..w - 1 {
                            let a = residual(f, x, y, 0);
                            let b = residual(f, x + step.0, y + step.1, step.2);
                            sxy += a * b;
                            sxx += a * a;
                            n += 1.0;
                        }
                    }
                }
                let rho = sxy / sxx;
                assert!(rho.abs() < 5.0 / f64::sqrt(n), "{name}: correlation {rho}");
            }
        }
    }

    #[test]
    fn fast_salt_and_pepper_hits_the_reference_share_independently() {
        let (w, h) = (400u32, 300u32);
        let clean = RgbImage::from_pixel(w, h, image::Rgb([128; 3]));
        let p = 0.01;
        let [fast, reference] = both(&clean, 10, |seed| noise_only(0.0, p, seed));
        let n = f64::from(w * h) * 10.0;
        let mut shares = Vec::new();
        for frames in [&fast, &reference] {
            let hits: Vec<bool> = frames
                .iter()
                .flat_map(|f| f.pixels().map(|px| px.0[0] != 128))
                .collect();
            let count = hits.iter().filter(|&&h| h).count() as f64;
            let black = frames
                .iter()
                .flat_map(|f| f.pixels())
                .filter(|px| px.0 == [0; 3])
                .count() as f64;
            assert!(
                (count / n - p).abs() < 5.0 * (p * (1.0 - p) / n).sqrt(),
                "share {}",
                count / n
            );
            assert!(
                (black / count - 0.5).abs() < 5.0 * (0.25 / count).sqrt(),
                "black {black} of {count}"
            );
            // Hits next to hits as often as anywhere: no clumping or spacing.
            let pairs = hits.windows(2).filter(|w| w[0] && w[1]).count() as f64;
            assert!(
                (pairs - n * p * p).abs() < 5.0 * (n * p * p).sqrt() + 1.0,
                "pairs {pairs}"
            );
            shares.push(count / n);
        }
        assert!((shares[0] - shares[1]).abs() < 5.0 * (2.0 * p / n).sqrt());
    }

    #[test]
    fn fast_gain_matches_the_reference_on_a_window() {
        let draw = SensorDraw {
            gradient_angle_rad: 0.7,
            gradient: 0.12,
            vignetting: 0.2,
            noise_sigma: 0.0,
            salt_pepper_fraction: 0.0,
            noise_seed: 3,
        };
        let clean = RgbImage::from_fn(200, 150, |x, y| image::Rgb([(x + y) as u8, 255, 40]));
        let (mut a, mut b) = (clean.clone(), clean);
        draw.apply_window(&mut a, (400, 300), (640, 480));
        draw.apply_window_reference(&mut b, (400, 300), (640, 480));
        let differ = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .filter(|(x, y)| x != y)
            .inspect(|(x, y)| assert!(x.abs_diff(**y) <= 1))
            .count();
        // f32 against f64 may round a value that lies on a half level the other way.
        assert!(differ * 1000 < a.as_raw().len(), "{differ} values differ");
    }
}
