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
    ///
    /// The model is written out in [`SensorDraw::apply_window_reference`]; this is the same
    /// model at a fifth of the cost: the gain row by row in f32, the normal deviates from a
    /// quantile table (four per random word) with exact tails, and salt-and-pepper pixels found
    /// by geometric skips instead of one uniform per pixel. The test below compares the two
    /// over many frames.
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
        // Each pixel's dx once per channel, so the per-row loops run over flat channel arrays
        // (which the compiler turns into SIMD).
        let dxs: Vec<f32> = (0..3 * width)
            .map(|i| ((i / 3) as f64 - cx) as f32)
            .collect();
        let mut gains = vec![0.0f32; 3 * width];
        let mut noise = vec![0.0f32; 3 * width];
        let mut normal = FastNormal::new(self.noise_seed);
        let sigma = self.noise_sigma as f32;
        for (y, row) in image.chunks_exact_mut(3 * width).enumerate() {
            let dy = (y as f64 - cy) as f32;
            let (row_along, dy2) = (1.0 + grad_y * dy, dy * dy);
            for (gain, dx) in gains.iter_mut().zip(&dxs) {
                *gain = (row_along + grad_x * dx) * (1.0 - vig * (dx * dx + dy2));
            }
            if sigma > 0.0 {
                normal.fill(&mut noise);
            }
            for ((c, gain), n) in row.iter_mut().zip(&gains).zip(&noise) {
                let value = f32::from(*c) * gain + sigma * n;
                // Rounded to the nearest level by adding 2^23, where an f32's step is 1: the
                // level is then the low bits of the sum. A bit cast vectorises, a float to
                // integer cast does not.
                *c = ((value.clamp(0.0, 255.0) + 8_388_608.0).to_bits() & 0xff) as u8;
            }
        }
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
        let skip = |rng: &mut SimRng| -> u64 {
            if log_miss == f64::NEG_INFINITY {
                return 0;
            }
            // Misses before the next hit: floor(ln U / ln(1 - p)), U uniform in (0, 1].
            let gap = (1.0 - rng.uniform()).ln() / log_miss;
            if gap >= count as f64 {
                count
            } else {
                gap as u64
            }
        };
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

/// Salt of the salt-and-pepper stream, derived from the frame's noise seed.
const SALT_PEPPER_STREAM: u64 = 0x5a17;
/// Bits of a random word that pick a bin of the normal: 4096 equiprobable bins.
const BIN_BITS: u32 = 12;
/// Bits of a random word that pick one of a bin's evenly spaced values.
const PLACE_BITS: u32 = 4;
/// Bits per deviate: four deviates per 64-bit random word.
const DRAW_BITS: u32 = BIN_BITS + PLACE_BITS;
/// Bins of the normal's quantile table.
const BINS: usize = 1 << BIN_BITS;
/// Bins at each end whose deviates are drawn exactly from the tail beyond them (|z| > 2.66):
/// there the density changes too fast across a bin to be taken as flat.
const TAIL_BINS: usize = 16;
/// Table entries: each bin's values.
const ENTRIES: usize = BINS << PLACE_BITS;
/// The first entry past the lower tail bins, and the number of entries between the tails.
const INNER_START: usize = TAIL_BINS << PLACE_BITS;
const INNER_ENTRIES: usize = ENTRIES - 2 * INNER_START;

/// Unit normal deviates, fast: 16 random bits pick an entry of a table that holds, for each of
/// 4096 equiprobable bins of the normal, 16 values evenly spaced across the bin (at the middles
/// of its sixteenths): one table read per deviate, four deviates per random word, no
/// transcendental function. The outer 16 bins at each end (probability 0.8 %) draw exactly from
/// the tail beyond them (Marsaglia's tail method), so no value is out of reach. Flat within a
/// bin is the only approximation: the density changes by at most 6 % across an inner bin, and
/// the variance comes out within 1e-5 of one.
struct FastNormal {
    rng: SimRng,
    table: &'static [f32; ENTRIES],
}

impl FastNormal {
    fn new(seed: u64) -> Self {
        Self {
            rng: SimRng::new(seed),
            table: unit_table(),
        }
    }

    /// Fills `out` with unit deviates, four from each random word.
    fn fill(&mut self, out: &mut [f32]) {
        const PER_WORD: usize = (64 / DRAW_BITS) as usize;
        let (table, rng) = (self.table, &mut self.rng);
        let mut chunks = out.chunks_exact_mut(PER_WORD);
        for chunk in &mut chunks {
            let word = rng.next_u64();
            for (i, value) in chunk.iter_mut().enumerate() {
                let entry = (word >> (i as u32 * DRAW_BITS)) as usize & (ENTRIES - 1);
                *value = deviate(table, rng, entry);
            }
        }
        for value in chunks.into_remainder() {
            let entry = rng.next_u64() as usize & (ENTRIES - 1);
            *value = deviate(table, rng, entry);
        }
    }
}

/// The deviate that table entry `entry` picks; a tail entry draws from `rng`.
#[inline(always)]
fn deviate(table: &[f32; ENTRIES], rng: &mut SimRng, entry: usize) -> f32 {
    if entry.wrapping_sub(INNER_START) < INNER_ENTRIES {
        table[entry & (ENTRIES - 1)]
    } else {
        let tail = normal_tail(rng, tail_edge()) as f32;
        if entry < INNER_START { -tail } else { tail }
    }
}

/// The table of [`FastNormal`]: entry `bin * 16 + k` is the middle of the `k`-th sixteenth of
/// the bin (entries of the tail bins are never read).
fn unit_table() -> &'static [f32; ENTRIES] {
    static TABLE: OnceLock<Box<[f32; ENTRIES]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let edges = unit_edges();
        let places = 1usize << PLACE_BITS;
        let mut table = Box::new([0.0f32; ENTRIES]);
        for (bin, values) in table.chunks_exact_mut(places).enumerate() {
            if !(TAIL_BINS..BINS - TAIL_BINS).contains(&bin) {
                continue;
            }
            let (low, high) = (edges[bin], edges[bin + 1]);
            for (k, value) in values.iter_mut().enumerate() {
                *value = (low + (k as f64 + 0.5) / places as f64 * (high - low)) as f32;
            }
        }
        table
    })
}

/// The unit normal's quantiles at `i / BINS` for every `i` in `0..=BINS` (the outer ones
/// infinite; the tail bins never read theirs).
fn unit_edges() -> &'static [f64; BINS + 1] {
    static TABLE: OnceLock<[f64; BINS + 1]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut table = [0.0; BINS + 1];
        for (i, q) in table.iter_mut().enumerate() {
            *q = match i {
                0 => f64::NEG_INFINITY,
                BINS => f64::INFINITY,
                _ => normal_quantile(i as f64 / BINS as f64),
            };
        }
        table
    })
}

/// Where the tail bins begin: the unit normal's quantile at `1 - TAIL_BINS / BINS`.
fn tail_edge() -> f64 {
    static EDGE: OnceLock<f64> = OnceLock::new();
    *EDGE.get_or_init(|| -normal_quantile(TAIL_BINS as f64 / BINS as f64))
}

/// A unit normal deviate conditioned on exceeding `edge` > 0 (Marsaglia's tail method: exact).
fn normal_tail(rng: &mut SimRng, edge: f64) -> f64 {
    loop {
        let a = -(1.0 - rng.uniform()).ln() / edge;
        let b = -(1.0 - rng.uniform()).ln();
        if 2.0 * b > a * a {
            return edge + a;
        }
    }
}

/// The unit normal's quantile function, by Acklam's rational approximation (relative error
/// below 1.2e-9, far finer than any bin), for `p` in (0, 1).
fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const LOW: f64 = 0.024_25;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
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

    #[test]
    fn the_bins_make_a_unit_normal() {
        let edges = unit_edges();
        let edge = tail_edge();
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-8);
        assert!((edge - 2.660_067_468_617_458).abs() < 1e-6, "{edge}");
        // Second moment of the flat bins, plus the exact tails':
        // E[z^2 | z > a] = 1 + a phi(a) / (1 - Phi(a)).
        let n = BINS as f64;
        let inner: f64 = edges[TAIL_BINS..=BINS - TAIL_BINS]
            .windows(2)
            .map(|e| (e[0] * e[0] + e[0] * e[1] + e[1] * e[1]) / 3.0 / n)
            .sum();
        let share = TAIL_BINS as f64 / n;
        let phi = (-0.5 * edge * edge).exp() / std::f64::consts::TAU.sqrt();
        let variance = inner + 2.0 * share * (1.0 + edge * phi / share);
        assert!((variance - 1.0).abs() < 1e-5, "variance {variance}");
    }
}
