//! Threshold segmentation of the seed paper (section 2.3 (2)): adaptive (mean and Gaussian),
//! Otsu and iterative (isodata). Outputs are binary: 255 for bright (foreground), 0 otherwise.
//!
//! The adaptive mean threshold is our own kernel (running column sums, no division per pixel);
//! the benchmark compares it with imageproc's, which stays the oracle in tests.

use crate::perception::running_sums::{row_running_sums, slide_and_sum};
use image::{GrayImage, Luma};

/// A thresholding method and its parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum ThresholdMethod {
    /// Bright where `p >= mean of the (2r+1)^2 block - delta`.
    AdaptiveMean {
        /// Block radius.
        block_radius_px: u32,
        /// Offset; negative values demand pixels brighter than their surroundings.
        delta: i32,
    },
    /// Bright where `p >= Gaussian-weighted local mean - delta`.
    AdaptiveGaussian {
        /// Standard deviation of the weighting.
        sigma_px: f32,
        /// Offset, as for `AdaptiveMean`.
        delta: i32,
    },
    /// Global level maximising the between-class variance.
    Otsu,
    /// Global level by the iterative (Ridler-Calvard isodata) method.
    Isodata,
}

impl ThresholdMethod {
    /// Short name for tables.
    pub fn name(&self) -> &'static str {
        match self {
            Self::AdaptiveMean { .. } => "adaptive-mean",
            Self::AdaptiveGaussian { .. } => "adaptive-gaussian",
            Self::Otsu => "otsu",
            Self::Isodata => "isodata",
        }
    }

    /// Segments `image` into a binary image.
    pub fn apply(&self, image: &GrayImage) -> GrayImage {
        match *self {
            Self::AdaptiveMean {
                block_radius_px,
                delta,
            } => adaptive_mean_threshold(image, block_radius_px, delta),
            Self::AdaptiveGaussian { sigma_px, delta } => {
                adaptive_gaussian_threshold(image, sigma_px, delta)
            }
            Self::Otsu => binarize(image, otsu_level(image)),
            Self::Isodata => binarize(image, isodata_level(image)),
        }
    }
}

/// Bright (255) where `p >= floor(block mean) - delta`, blocks clipped at the border; equal to
/// `imageproc::contrast::adaptive_threshold` (radius 0 is treated as 1, as that needs `> 0`).
///
/// Runs the same code compiled for AVX2 where the CPU has it (chosen at run time): every step is
/// exact integer or exact `f32` arithmetic, so both builds give the same bytes (tested).
pub fn adaptive_mean_threshold(image: &GrayImage, block_radius_px: u32, delta: i32) -> GrayImage {
    adaptive_mean_threshold_floored(image, block_radius_px, delta, u8::MAX)
}

/// [`adaptive_mean_threshold`], and bright wherever `p > floor` too (a global level under the
/// local one: see [`crate::perception::bore::BoreDetectorParams::bright_above_otsu`]), in the same
/// pass; `floor = 255` adds nothing.
pub fn adaptive_mean_threshold_floored(
    image: &GrayImage,
    block_radius_px: u32,
    delta: i32,
    floor: u8,
) -> GrayImage {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the function only requires AVX2, which the CPU was just found to have.
        return unsafe { adaptive_mean_avx2(image, block_radius_px, delta, floor) };
    }
    adaptive_mean_kernel(image, block_radius_px, delta, floor, false)
}

/// [`adaptive_mean_kernel`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn adaptive_mean_avx2(image: &GrayImage, block_radius_px: u32, delta: i32, floor: u8) -> GrayImage {
    adaptive_mean_kernel(image, block_radius_px, delta, floor, true)
}

/// The body of [`adaptive_mean_threshold_floored`], inlined into each instruction-set variant;
/// `avx2` only from the AVX2 build (it then runs the row prefixes with AVX2 too).
#[inline(always)]
fn adaptive_mean_kernel(
    image: &GrayImage,
    block_radius_px: u32,
    delta: i32,
    floor: u8,
    avx2: bool,
) -> GrayImage {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let mut out = GrayImage::new(image.width(), image.height());
    if w == 0 || h == 0 {
        return out;
    }
    let r = block_radius_px.max(1) as usize;
    let src = image.as_raw();
    let dst: &mut [u8] = &mut out;
    let mut column_sums = vec![0u32; w];
    // Rows [0, r) are in the window of row 0 before the loop adds row r.
    for row in src.chunks_exact(w).take(r.min(h)) {
        for (s, &p) in column_sums.iter_mut().zip(row) {
            *s += u32::from(p);
        }
    }
    // Column sums reach 255 (2r+1), prefixes 255 (2r+1) w: u32 for any realistic frame. The
    // prefixes are padded with r zeros in front and r copies of the total behind, so that the
    // block of every column, clipped at the border or not, is `padded[x + 2r + 1] - padded[x]`.
    let mut padded = vec![0u32; w + 2 * r + 1];
    // Columns in each block, clipped at the border.
    let columns_in: Vec<f32> = (0..w)
        .map(|x| ((x + r).min(w - 1) - x.saturating_sub(r) + 1) as f32)
        .collect();
    let offset = i64::from(delta) + 1;
    // The decision runs in f32 lanes (SSE2 has no 32-bit integer multiply) so that the compiler
    // vectorises it, exact while every product and sum stays below 2^24; the largest block
    // (all (2r+1)^2 pixels) bounds them all.
    let largest_count = ((2 * r + 1).min(h) * (2 * r + 1).min(w)) as i64;
    let exact_in_f32 = largest_count * offset.abs().max((255 + offset).abs()).max(255) < 1 << 24;
    for y in 0..h {
        let entering = (y + r < h).then(|| &src[(y + r) * w..(y + r + 1) * w]);
        let leaving = (y > r).then(|| &src[(y - r - 1) * w..(y - r) * w]);
        let out = &mut padded[r + 1..r + 1 + w];
        let running = match (entering, leaving) {
            (Some(new), Some(old)) => slide_and_sum(avx2, &mut column_sums, new, old, out),
            (Some(new), None) => {
                for (s, &p) in column_sums.iter_mut().zip(new) {
                    *s += u32::from(p);
                }
                row_running_sums(avx2, &column_sums, out)
            }
            (None, Some(old)) => {
                for (s, &q) in column_sums.iter_mut().zip(old) {
                    *s -= u32::from(q);
                }
                row_running_sums(avx2, &column_sums, out)
            }
            (None, None) => row_running_sums(avx2, &column_sums, out),
        };
        let y_low = y.saturating_sub(r);
        let y_high = (y + r).min(h - 1);
        let rows_in = (y_high - y_low + 1) as i64;
        padded[r + 1 + w..].fill(running);
        let src_row = &src[y * w..(y + 1) * w];
        let out_row = &mut dst[y * w..(y + 1) * w];
        let (high, low) = (&padded[2 * r + 1..], &padded[..w]);
        if exact_in_f32 {
            let (rows_in, offset) = (rows_in as f32, offset as f32);
            for ((((o, &p), &hi), &lo), &columns) in out_row
                .iter_mut()
                .zip(src_row)
                .zip(high)
                .zip(low)
                .zip(&columns_in)
            {
                let sum = hi.wrapping_sub(lo) as i32 as f32;
                let k = f32::from(p) + offset;
                *o = if k * (rows_in * columns) > sum || p > floor {
                    255
                } else {
                    0
                };
            }
        } else {
            // p >= floor(sum / count) - delta  <=>  (p + delta + 1) * count > sum.
            for ((((o, &p), &hi), &lo), &columns) in out_row
                .iter_mut()
                .zip(src_row)
                .zip(high)
                .zip(low)
                .zip(&columns_in)
            {
                let count = rows_in * columns as i64;
                let sum = i64::from(hi.wrapping_sub(lo));
                let k = i64::from(p) + offset;
                *o = if k * count > sum || p > floor { 255 } else { 0 };
            }
        }
    }
    out
}

/// Bright where `p >= Gaussian blur of the image - delta`.
pub fn adaptive_gaussian_threshold(image: &GrayImage, sigma_px: f32, delta: i32) -> GrayImage {
    let blurred = crate::perception::filters::gaussian_filter(image, sigma_px);
    let mut out = GrayImage::new(image.width(), image.height());
    for ((o, p), m) in out.iter_mut().zip(image.iter()).zip(blurred.iter()) {
        *o = if i32::from(*p) >= i32::from(*m) - delta {
            255
        } else {
            0
        };
    }
    out
}

/// Bright (255) where `p > level`.
pub fn binarize(image: &GrayImage, level: u8) -> GrayImage {
    let mut out = image.clone();
    for p in out.iter_mut() {
        *p = if *p > level { 255 } else { 0 };
    }
    out
}

/// Sets bright (255) every pixel of `binary` whose level in `image` is above `level` (both images
/// the same size).
pub fn brighten_above(binary: &mut GrayImage, image: &GrayImage, level: u8) {
    for (b, &p) in binary.iter_mut().zip(image.iter()) {
        if p > level {
            *b = 255;
        }
    }
}

/// Otsu's level: pixels `> level` form the bright class. Equal to
/// `imageproc::contrast::otsu_level` (tested), whose histogram walks the image pixel by pixel
/// through its generic accessors and was a tenth of the bore detector's time.
pub fn otsu_level(image: &GrayImage) -> u8 {
    let mut histogram = HistogramTables::new();
    histogram.add(image.as_raw());
    otsu_level_of_histogram(&histogram.total(), image.width() * image.height())
}

/// Otsu's level of a grey-level histogram of `total_weight` pixels (see [`otsu_level`]).
pub fn otsu_level_of_histogram(histogram: &[u32; 256], total_weight: u32) -> u8 {
    // The same operations in the same order as imageproc's, so the same level.
    let total_sum = histogram
        .iter()
        .enumerate()
        .fold(0f64, |sum, (t, &h)| sum + (t as u32 * h) as f64);
    let (mut background_sum, mut background_weight) = (0f64, 0u32);
    let (mut largest_variance, mut best) = (0f64, 0u8);
    for (level, &count) in histogram.iter().enumerate() {
        background_weight += count;
        if background_weight == 0 {
            continue;
        }
        let foreground_weight = total_weight - background_weight;
        if foreground_weight == 0 {
            break;
        }
        background_sum += (level as u32 * count) as f64;
        let background_mean = background_sum / f64::from(background_weight);
        let foreground_mean = (total_sum - background_sum) / f64::from(foreground_weight);
        let variance = f64::from(background_weight)
            * f64::from(foreground_weight)
            * (background_mean - foreground_mean).powi(2);
        if variance > largest_variance {
            largest_variance = variance;
            best = level as u8;
        }
    }
    best
}

/// A grey-level histogram, counted in eight interleaved tables so that runs of equal levels (a
/// flat belt, a rim) do not wait on each other's increments, from whole 8-byte words.
pub(crate) struct HistogramTables {
    tables: [[u32; 256]; 8],
}

impl HistogramTables {
    /// An empty histogram.
    pub(crate) fn new() -> Self {
        Self {
            tables: [[0; 256]; 8],
        }
    }

    /// Counts the levels of `pixels`.
    #[inline(always)]
    pub(crate) fn add(&mut self, pixels: &[u8]) {
        let mut chunks = pixels.chunks_exact(8);
        for c in &mut chunks {
            let mut word = c.first_chunk::<8>().map_or(0, |b| u64::from_le_bytes(*b));
            for table in &mut self.tables {
                table[(word & 0xff) as usize] += 1;
                word >>= 8;
            }
        }
        for &p in chunks.remainder() {
            self.tables[0][usize::from(p)] += 1;
        }
    }

    /// The count of each level.
    pub(crate) fn total(&self) -> [u32; 256] {
        let mut total = [0u32; 256];
        for (i, t) in total.iter_mut().enumerate() {
            *t = self.tables.iter().map(|table| table[i]).sum();
        }
        total
    }
}

/// Iterative (isodata, Ridler-Calvard) level: the midpoint of the two class means, iterated
/// to a fixed point from the image mean. Pixels `> level` form the bright class.
pub fn isodata_level(image: &GrayImage) -> u8 {
    let mut histogram = [0u64; 256];
    for &p in image.iter() {
        histogram[usize::from(p)] += 1;
    }
    let total: u64 = histogram.iter().sum();
    if total == 0 {
        return 0;
    }
    let weighted: u64 = histogram
        .iter()
        .enumerate()
        .map(|(i, &n)| i as u64 * n)
        .sum();
    let mut level = weighted as f64 / total as f64;
    for _ in 0..256 {
        let split = level.floor() as usize;
        let (mut n_low, mut s_low) = (0u64, 0u64);
        for (i, &n) in histogram.iter().enumerate().take(split + 1) {
            n_low += n;
            s_low += i as u64 * n;
        }
        let (n_high, s_high) = (total - n_low, weighted - s_low);
        if n_low == 0 || n_high == 0 {
            break;
        }
        let next = 0.5 * (s_low as f64 / n_low as f64 + s_high as f64 / n_high as f64);
        if (next - level).abs() < 0.5 {
            level = next;
            break;
        }
        level = next;
    }
    level.floor().clamp(0.0, 255.0) as u8
}

/// Whether every pixel is 0 or 255.
pub fn is_binary(image: &GrayImage) -> bool {
    image.pixels().all(|&Luma([p])| p == 0 || p == 255)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arbitrary_image() -> impl Strategy<Value = GrayImage> {
        (1u32..30, 1u32..30).prop_flat_map(|(w, h)| {
            proptest::collection::vec(any::<u8>(), (w * h) as usize).prop_map(move |data| {
                GrayImage::from_raw(w, h, data).unwrap_or_else(|| GrayImage::new(1, 1))
            })
        })
    }

    proptest! {
        #[test]
        fn adaptive_mean_matches_imageproc(
            image in arbitrary_image(), radius in 1u32..12, delta in -40i32..40
        ) {
            let ours = adaptive_mean_threshold(&image, radius, delta);
            let oracle = imageproc::contrast::adaptive_threshold(&image, radius, delta);
            prop_assert_eq!(ours.as_raw(), oracle.as_raw());
            // The baseline build too, whichever the dispatch picked.
            let portable = adaptive_mean_kernel(&image, radius, delta, u8::MAX, false);
            prop_assert_eq!(portable.as_raw(), oracle.as_raw());
        }

        #[test]
        fn a_floored_adaptive_mean_is_imageproc_or_above_the_floor(
            image in arbitrary_image(), radius in 1u32..25, delta in -40i32..40, floor in any::<u8>()
        ) {
            let mut oracle = imageproc::contrast::adaptive_threshold(&image, radius, delta);
            brighten_above(&mut oracle, &image, floor);
            let ours = adaptive_mean_threshold_floored(&image, radius, delta, floor);
            prop_assert_eq!(ours.as_raw(), oracle.as_raw());
            let portable = adaptive_mean_kernel(&image, radius, delta, floor, false);
            prop_assert_eq!(portable.as_raw(), oracle.as_raw());
        }

        #[test]
        fn adaptive_mean_matches_imageproc_at_the_default_block(
            seed in any::<u64>(), delta in -300i32..300
        ) {
            // The detector's block (radius 20) on a frame wider than two blocks, so the interior
            // fast path runs, with offsets up to where its f32 products would stop being exact.
            let mut rng = crate::rng::SimRng::new(seed);
            let data: Vec<u8> = (0..97 * 61).map(|_| (rng.next_u64() % 256) as u8).collect();
            let image = GrayImage::from_raw(97, 61, data).unwrap_or_else(|| GrayImage::new(1, 1));
            let ours = adaptive_mean_threshold(&image, 20, delta);
            let oracle = imageproc::contrast::adaptive_threshold(&image, 20, delta);
            prop_assert_eq!(ours.as_raw(), oracle.as_raw());
            let portable = adaptive_mean_kernel(&image, 20, delta, u8::MAX, false);
            prop_assert_eq!(portable.as_raw(), oracle.as_raw());
        }

        #[test]
        fn otsu_level_matches_imageproc(image in arbitrary_image(), low in any::<u8>()) {
            // Also a two-level image, where the variance has a clear maximum.
            let mut two = image.clone();
            for p in two.iter_mut().step_by(3) {
                *p = low;
            }
            for image in [image, two] {
                prop_assert_eq!(otsu_level(&image), imageproc::contrast::otsu_level(&image));
            }
        }

        #[test]
        fn every_threshold_output_is_binary(image in arbitrary_image()) {
            for method in [
                ThresholdMethod::AdaptiveMean { block_radius_px: 3, delta: -5 },
                ThresholdMethod::AdaptiveGaussian { sigma_px: 2.0, delta: -5 },
                ThresholdMethod::Otsu,
                ThresholdMethod::Isodata,
            ] {
                prop_assert!(is_binary(&method.apply(&image)));
            }
        }

        #[test]
        fn isodata_splits_two_levels(low in 0u8..100, high in 150u8..=255) {
            let mut image = GrayImage::from_pixel(10, 10, Luma([low]));
            for x in 0..5 {
                for y in 0..10 {
                    image.put_pixel(x, y, Luma([high]));
                }
            }
            let level = isodata_level(&image);
            prop_assert!(level >= low && level < high);
        }
    }
}
