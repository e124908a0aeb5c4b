//! Denoising filters of the seed paper, eqs. 9-10: mean, median and Gaussian.
//!
//! All filters replicate the border pixels. The 3x3 median is our own kernel: the benchmark
//! (`benches/metrology.rs`, stage `median3_imageproc` vs `median3`) shows imageproc's sliding
//! histogram median is the pipeline's bottleneck at radius 1; imageproc stays the oracle in tests.

use crate::perception::threshold::HistogramTables;
use image::GrayImage;

/// A denoising filter and its size.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum FilterMethod {
    /// Mean of a `(2r+1)^2` window (eq. 9).
    Mean {
        /// Window radius.
        radius_px: u32,
    },
    /// Median of a `(2r+1)^2` window (eq. 10).
    Median {
        /// Window radius.
        radius_px: u32,
    },
    /// Gaussian smoothing.
    Gaussian {
        /// Standard deviation.
        sigma_px: f32,
    },
}

impl FilterMethod {
    /// Short name for tables.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Mean { .. } => "mean",
            Self::Median { .. } => "median",
            Self::Gaussian { .. } => "gaussian",
        }
    }

    /// Applies the filter.
    pub fn apply(&self, image: &GrayImage) -> GrayImage {
        match *self {
            Self::Mean { radius_px } => mean_filter(image, radius_px),
            Self::Median { radius_px } => median_filter(image, radius_px),
            Self::Gaussian { sigma_px } => gaussian_filter(image, sigma_px),
        }
    }
}

/// Mean (box) filter of radius `radius_px`.
pub fn mean_filter(image: &GrayImage, radius_px: u32) -> GrayImage {
    imageproc::filter::box_filter(image, radius_px, radius_px)
}

/// Median filter of radius `radius_px`; radius 1 uses the fast [`median_3x3`].
pub fn median_filter(image: &GrayImage, radius_px: u32) -> GrayImage {
    match radius_px {
        0 => image.clone(),
        1 => median_3x3(image),
        r => imageproc::filter::median_filter(image, r, r),
    }
}

/// Gaussian filter of standard deviation `sigma_px` (no-op for `sigma_px <= 0`).
pub fn gaussian_filter(image: &GrayImage, sigma_px: f32) -> GrayImage {
    if sigma_px <= 0.0 {
        return image.clone();
    }
    imageproc::filter::gaussian_blur_f32(image, sigma_px)
}

/// 3x3 median with replicated borders, equal to `imageproc::filter::median_filter(image, 1, 1)`.
///
/// Each column triple is sorted once (min, mid, max) and shared by three output pixels; the
/// median of nine is then `med(max of mins, med of mids, min of maxes)`. Written as branch-free
/// min/max over rows so the compiler vectorises it, for AVX2 where the CPU has it (chosen at run
/// time; integer min/max give the same bytes either way, tested).
pub fn median_3x3(image: &GrayImage) -> GrayImage {
    median_3x3_counted(image, None)
}

/// [`median_3x3`] and the grey-level histogram of its output (for Otsu's level), counted as
/// each stretch of the output is written: the counting, scalar stores, overlaps the filter's
/// vector work instead of following it in a pass of its own.
pub fn median_3x3_with_histogram(image: &GrayImage) -> (GrayImage, [u32; 256]) {
    let mut histogram = HistogramTables::new();
    let filtered = median_3x3_counted(image, Some(&mut histogram));
    (filtered, histogram.total())
}

/// [`median_3x3`], counting its output into `histogram` when given.
fn median_3x3_counted(image: &GrayImage, histogram: Option<&mut HistogramTables>) -> GrayImage {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the function only requires AVX2, which the CPU was just found to have.
        return unsafe { median_3x3_avx2(image, histogram) };
    }
    median_3x3_kernel(image, histogram)
}

/// [`median_3x3_kernel`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn median_3x3_avx2(image: &GrayImage, histogram: Option<&mut HistogramTables>) -> GrayImage {
    median_3x3_kernel(image, histogram)
}

/// The body of [`median_3x3`], inlined into each instruction-set variant.
#[inline(always)]
fn median_3x3_kernel(image: &GrayImage, mut histogram: Option<&mut HistogramTables>) -> GrayImage {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let mut out = GrayImage::new(image.width(), image.height());
    if w == 0 || h == 0 {
        return out;
    }
    let src = image.as_raw();
    let dst: &mut [u8] = &mut out;
    // Sorted column triples, padded by one replicated column on each side: the border pixel's
    // own triple (replicating a column replicates its triple), so no row is copied.
    let pw = w + 2;
    let mut lo = vec![0u8; pw];
    let mut mid = vec![0u8; pw];
    let mut hi = vec![0u8; pw];
    for y in 0..h {
        let row = |r: usize| &src[r * w..(r + 1) * w];
        let (a, b, c) = (row(y.saturating_sub(1)), row(y), row((y + 1).min(h - 1)));
        for (((((l, m), u), &p), &q), &r) in lo[1..=w]
            .iter_mut()
            .zip(&mut mid[1..=w])
            .zip(&mut hi[1..=w])
            .zip(a)
            .zip(b)
            .zip(c)
        {
            let (s0, s1) = (p.min(q), p.max(q));
            let s2 = s1.min(r);
            *u = s1.max(r);
            *l = s0.min(s2);
            *m = s0.max(s2);
        }
        for v in [&mut lo, &mut mid, &mut hi] {
            v[0] = v[1];
            v[w + 1] = v[w];
        }
        let out_row = &mut dst[y * w..(y + 1) * w];
        for (x, o) in out_row.iter_mut().enumerate() {
            let max_lo = lo[x].max(lo[x + 1]).max(lo[x + 2]);
            let min_hi = hi[x].min(hi[x + 1]).min(hi[x + 2]);
            let (m0, m1, m2) = (mid[x], mid[x + 1], mid[x + 2]);
            let med_mid = m0.min(m1).max(m0.max(m1).min(m2));
            *o = median3(max_lo, med_mid, min_hi);
        }
        if let Some(histogram) = histogram.as_deref_mut() {
            histogram.add(out_row);
        }
    }
    out
}

#[inline]
fn median3(a: u8, b: u8, c: u8) -> u8 {
    a.min(b).max(a.max(b).min(c))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn image_from(width: u32, height: u32, data: Vec<u8>) -> GrayImage {
        GrayImage::from_raw(width, height, data).unwrap_or_else(|| GrayImage::new(1, 1))
    }

    proptest! {
        #[test]
        fn median_3x3_matches_imageproc(
            (w, h, data) in (1u32..150, 1u32..24).prop_flat_map(|(w, h)| {
                (Just(w), Just(h), proptest::collection::vec(any::<u8>(), (w * h) as usize))
            })
        ) {
            let image = image_from(w, h, data);
            let ours = median_3x3(&image);
            let oracle = imageproc::filter::median_filter(&image, 1, 1);
            prop_assert_eq!(ours.as_raw(), oracle.as_raw());
            // The baseline build too, whichever the dispatch picked.
            let portable = median_3x3_kernel(&image, None);
            prop_assert_eq!(portable.as_raw(), oracle.as_raw());
            // Counted as written: the same image, and its histogram.
            let (counted, histogram) = median_3x3_with_histogram(&image);
            prop_assert_eq!(counted.as_raw(), oracle.as_raw());
            let mut expected = [0u32; 256];
            for &p in oracle.as_raw() {
                expected[usize::from(p)] += 1;
            }
            prop_assert_eq!(histogram, expected);
        }

        #[test]
        fn filters_keep_a_constant_image(level in any::<u8>(), radius in 1u32..4) {
            let image = GrayImage::from_pixel(17, 11, image::Luma([level]));
            for method in [
                FilterMethod::Mean { radius_px: radius },
                FilterMethod::Median { radius_px: radius },
            ] {
                prop_assert!(method.apply(&image).pixels().all(|p| p[0] == level));
            }
            // imageproc's f32 Gaussian truncates after each of its two passes.
            let gaussian = FilterMethod::Gaussian { sigma_px: radius as f32 }.apply(&image);
            prop_assert!(gaussian.pixels().all(|p| p[0].abs_diff(level) <= 2));
        }
    }

    #[test]
    fn median_removes_an_impulse() {
        let mut image = GrayImage::from_pixel(5, 5, image::Luma([10]));
        image.put_pixel(2, 2, image::Luma([255]));
        assert!(median_3x3(&image).pixels().all(|p| p[0] == 10));
    }
}
