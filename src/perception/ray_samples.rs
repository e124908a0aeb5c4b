//! Bilinear samples of an image along a ray: one at a time, or a whole profile with an AVX2
//! kernel where the CPU has it (the same bits as the portable code, tested).

use image::GrayImage;

/// Bilinear sample of `image` at `(x, y)` (pixel centres at integers), clamped to the image.
#[inline]
pub fn sample_bilinear(image: &GrayImage, x: f64, y: f64) -> f64 {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let x = x.clamp(0.0, (w - 1) as f64);
    let y = y.clamp(0.0, (h - 1) as f64);
    // Truncation is floor here (both are clamped to >= 0) and, unlike `floor`, needs no libm call.
    let ([x0, y0], [fx, fy]) = split_position(x, y);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let raw = image.as_raw();
    let p = |xx: usize, yy: usize| f64::from(raw[yy * w + xx]);
    let top = p(x0, y0) + fx * (p(x1, y0) - p(x0, y0));
    let bottom = p(x0, y1) + fx * (p(x1, y1) - p(x0, y1));
    top + fy * (bottom - top)
}

/// Integer part and fraction of a position with non-negative coordinates inside an image. Goes
/// through `i64`, whose conversions to and from `f64` are single instructions on x86-64, where
/// those of `usize` take several; the values are the same (image sides are below 2^32).
#[inline]
fn split_position(x: f64, y: f64) -> ([usize; 2], [f64; 2]) {
    let (x0, y0) = (x as i64, y as i64);
    ([x0 as usize, y0 as usize], [x - x0 as f64, y - y0 as f64])
}

/// Samples the ray from `centre` with unit direction `dir` at `from + step * i`, `i < count`,
/// into `out` (cleared first); equal to [`sample_bilinear`] at each point.
pub fn sample_ray(
    image: &GrayImage,
    centre: [f64; 2],
    dir: [f64; 2],
    from: f64,
    step: f64,
    count: usize,
    out: &mut Vec<f64>,
) {
    out.clear();
    out.resize(count, 0.0);
    let ray = RaySamples {
        image,
        centre,
        dir,
        from,
        step,
    };
    ray.fill(0..count, out);
}

/// Bilinear samples of `image` at the points `(xs[i], ys[i])` into `out[i]`, each equal to
/// [`sample_bilinear`] there: four at a time with AVX2 where the CPU has it and all four lie
/// strictly inside the last pixel row and column, one by one otherwise.
pub fn sample_points(image: &GrayImage, xs: &[f64], ys: &[f64], out: &mut [f64]) {
    let n = xs.len().min(ys.len()).min(out.len());
    let (xs, ys, out) = (&xs[..n], &ys[..n], &mut out[..n]);
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2")
        && image.width() >= 2
        && image.height() >= 2
        && i32::try_from(image.as_raw().len()).is_ok()
    {
        // SAFETY: the function only requires AVX2, which the CPU was just found to have.
        done = unsafe { sample_points_avx2(image, xs, ys, out) };
    }
    for ((o, &x), &y) in out.iter_mut().zip(xs).zip(ys).skip(done) {
        *o = sample_bilinear(image, x, y);
    }
}

/// The whole chunks of four of [`sample_points`] with AVX2 (the same IEEE operations in the
/// same order as [`sample_bilinear`] on each lane: the same bits); returns how many points it
/// sampled. The image must be at least 2x2 and under 2^31 bytes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sample_points_avx2(image: &GrayImage, xs: &[f64], ys: &[f64], out: &mut [f64]) -> usize {
    use std::arch::x86_64::*;
    let raw = image.as_raw();
    let (w, h) = (image.width() as usize, image.height() as usize);
    let zero = _mm256_setzero_pd();
    let (x_end, y_end) = (
        _mm256_set1_pd(w as f64 - 1.0),
        _mm256_set1_pd(h as f64 - 1.0),
    );
    let mut done = 0;
    for ((x, y), o) in xs
        .chunks_exact(4)
        .zip(ys.chunks_exact(4))
        .zip(out.chunks_exact_mut(4))
    {
        // SAFETY: each chunk holds exactly four `f64`.
        let (x, y) = unsafe { (_mm256_loadu_pd(x.as_ptr()), _mm256_loadu_pd(y.as_ptr())) };
        // Strictly inside: every sample has its four neighbours without clamping, where
        // `sample_bilinear`'s clamps change nothing.
        let inside = _mm256_and_pd(
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GE_OQ>(x, zero),
                _mm256_cmp_pd::<_CMP_GE_OQ>(y, zero),
            ),
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_LT_OQ>(x, x_end),
                _mm256_cmp_pd::<_CMP_LT_OQ>(y, y_end),
            ),
        );
        if _mm256_movemask_pd(inside) != 0b1111 {
            break;
        }
        let value = bilinear4_avx2(raw, w, x, y);
        // SAFETY: `o` holds exactly four `f64`.
        unsafe { _mm256_storeu_pd(o.as_mut_ptr(), value) };
        done += 4;
    }
    done
}

/// Four bilinear samples of the `w`-pixel-wide image `raw` at `x`, `y` (each inside, with its
/// four neighbours), with the same IEEE operations in the same order as [`sample_bilinear`] on
/// each lane: the same bits. Each gather reads four bytes: the top pair from its first two, the
/// bottom pair from the last two of a read starting two bytes early (so it never passes the
/// image's end); clamping the start indices keeps every read inside the image whatever the
/// positions. The image must be at least 2x2 and under 2^31 bytes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn bilinear4_avx2(
    raw: &[u8],
    w: usize,
    x: std::arch::x86_64::__m256d,
    y: std::arch::x86_64::__m256d,
) -> std::arch::x86_64::__m256d {
    use std::arch::x86_64::*;
    let last_start = raw.len().saturating_sub(w + 2) as i32;
    let (low, high) = (_mm_setzero_si128(), _mm_set1_epi32(last_start));
    let (width, byte) = (_mm_set1_epi32(w as i32), _mm_set1_epi32(0xff));
    let bottom_offset = _mm_set1_epi32(w as i32 - 2);
    let (x0, y0) = (_mm256_cvttpd_epi32(x), _mm256_cvttpd_epi32(y));
    let fx = _mm256_sub_pd(x, _mm256_cvtepi32_pd(x0));
    let fy = _mm256_sub_pd(y, _mm256_cvtepi32_pd(y0));
    let start = _mm_add_epi32(_mm_mullo_epi32(y0, width), x0);
    let start = _mm_min_epi32(_mm_max_epi32(start, low), high);
    // SAFETY: `start` lies in `[0, len - w - 2]`, so the four bytes read from `start` and from
    // `start + w - 2` are inside `raw`.
    let (top, bottom) = unsafe {
        (
            _mm_i32gather_epi32::<1>(raw.as_ptr().cast(), start),
            _mm_i32gather_epi32::<1>(raw.as_ptr().cast(), _mm_add_epi32(start, bottom_offset)),
        )
    };
    let level = |v: __m128i| _mm256_cvtepi32_pd(_mm_and_si128(v, byte));
    let (p00, p01) = (level(top), level(_mm_srli_epi32::<8>(top)));
    let (p10, p11) = (
        level(_mm_srli_epi32::<16>(bottom)),
        level(_mm_srli_epi32::<24>(bottom)),
    );
    let top = _mm256_add_pd(p00, _mm256_mul_pd(fx, _mm256_sub_pd(p01, p00)));
    let bottom = _mm256_add_pd(p10, _mm256_mul_pd(fx, _mm256_sub_pd(p11, p10)));
    _mm256_add_pd(top, _mm256_mul_pd(fy, _mm256_sub_pd(bottom, top)))
}

/// Where the samples of one ray lie: sample `i` is at `centre + (from + step i) dir`.
pub(crate) struct RaySamples<'a> {
    /// The sampled image.
    pub(crate) image: &'a GrayImage,
    /// The ray's origin.
    pub(crate) centre: [f64; 2],
    /// The ray's unit direction.
    pub(crate) dir: [f64; 2],
    /// Distance of sample 0 from the origin.
    pub(crate) from: f64,
    /// Distance between samples.
    pub(crate) step: f64,
}

impl RaySamples<'_> {
    /// Position of sample `i`.
    #[inline]
    pub(crate) fn at(&self, i: usize) -> [f64; 2] {
        // Through u32 (a sample count never reaches 2^32): one conversion instruction, where
        // usize to f64 takes several on x86-64; the value is the same.
        let t = self.from + self.step * f64::from(i as u32);
        [
            self.centre[0] + t * self.dir[0],
            self.centre[1] + t * self.dir[1],
        ]
    }

    /// Writes samples `range` into `out[range]` (bilinear, as [`sample_bilinear`]). Each sample
    /// depends on its index alone, so filling a profile piecewise gives the same bytes as at once.
    pub(crate) fn fill(&self, range: std::ops::Range<usize>, out: &mut [f64]) {
        let Some(out) = out.get_mut(range.clone()) else {
            return;
        };
        if range.is_empty() {
            return;
        }
        let (w, h) = (self.image.width() as usize, self.image.height() as usize);
        // Both ends strictly inside the last pixel row and column: so is the whole segment, and
        // every sample has its four neighbours without clamping.
        let inside =
            |[x, y]: [f64; 2]| x >= 0.0 && y >= 0.0 && x < (w as f64 - 1.0) && y < (h as f64 - 1.0);
        if !(inside(self.at(range.start)) && inside(self.at(range.end - 1))) {
            for (o, i) in out.iter_mut().zip(range) {
                let [x, y] = self.at(i);
                *o = sample_bilinear(self.image, x, y);
            }
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2")
            && w >= 2
            && h >= 2
            && i32::try_from(self.image.as_raw().len()).is_ok()
        {
            // SAFETY: the function only requires AVX2, which the CPU was just found to have.
            unsafe { self.fill_inside_avx2(range.start, out) };
            return;
        }
        self.fill_inside(range.start, out);
    }

    /// Samples `first..first + out.len()` into `out`, all of whose four neighbours lie inside the
    /// image (see [`Self::fill`]).
    pub(crate) fn fill_inside(&self, first: usize, out: &mut [f64]) {
        let raw = self.image.as_raw();
        let w = self.image.width() as usize;
        for (o, i) in out.iter_mut().zip(first..) {
            let [x, y] = self.at(i);
            let ([x0, y0], [fx, fy]) = split_position(x, y);
            let index = y0 * w + x0;
            let (Some(&[p00, p01]), Some(&[p10, p11])) = (
                raw.get(index..index + 2).and_then(|q| q.first_chunk::<2>()),
                raw.get(index + w..index + w + 2)
                    .and_then(|q| q.first_chunk::<2>()),
            ) else {
                continue;
            };
            let (p00, p01, p10, p11) = (
                f64::from(p00),
                f64::from(p01),
                f64::from(p10),
                f64::from(p11),
            );
            let top = p00 + fx * (p01 - p00);
            let bottom = p10 + fx * (p11 - p10);
            *o = top + fy * (bottom - top);
        }
    }

    /// [`Self::fill_inside`], four samples at a time with AVX2: the same IEEE operations in the
    /// same order on each lane (Rust never fuses a multiply and an add), so the same bits. The
    /// image must be at least 2x2 pixels (or the clamped reads below could leave it) and have
    /// fewer than 2^31 bytes (indices are `i32` lanes); [`Self::fill`] checks both.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn fill_inside_avx2(&self, first: usize, out: &mut [f64]) {
        use std::arch::x86_64::*;
        let raw = self.image.as_raw();
        let w = self.image.width() as usize;
        let (from, step) = (_mm256_set1_pd(self.from), _mm256_set1_pd(self.step));
        let (cx, cy) = (
            _mm256_set1_pd(self.centre[0]),
            _mm256_set1_pd(self.centre[1]),
        );
        let (dx, dy) = (_mm256_set1_pd(self.dir[0]), _mm256_set1_pd(self.dir[1]));
        let lanes = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
        let mut chunks = out.chunks_exact_mut(4);
        let mut i = first;
        for chunk in &mut chunks {
            let index = _mm256_add_pd(_mm256_set1_pd(f64::from(i as u32)), lanes);
            let t = _mm256_add_pd(from, _mm256_mul_pd(step, index));
            let x = _mm256_add_pd(cx, _mm256_mul_pd(t, dx));
            let y = _mm256_add_pd(cy, _mm256_mul_pd(t, dy));
            let value = bilinear4_avx2(raw, w, x, y);
            // SAFETY: `chunk` holds exactly four `f64`.
            unsafe { _mm256_storeu_pd(chunk.as_mut_ptr(), value) };
            i += 4;
        }
        self.fill_inside(i, chunks.into_remainder());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::synthetic::disc_scene;

    #[test]
    fn ray_samples_equal_bilinear_samples_inside_and_across_the_border() {
        let image = disc_scene(60.0, 70.0, 30.0);
        let mut profile = Vec::new();
        for (centre, angle, from) in [
            ([80.0, 80.0], 0.3, 5.0),
            ([150.0, 10.0], -0.7, 0.0),
            ([3.0, 150.0], 2.5, -4.0),
        ] {
            let dir = [f64::cos(angle), f64::sin(angle)];
            sample_ray(&image, centre, dir, from, 0.5, 40, &mut profile);
            for (i, &v) in profile.iter().enumerate() {
                let t = from + 0.5 * i as f64;
                let expected =
                    sample_bilinear(&image, centre[0] + t * dir[0], centre[1] + t * dir[1]);
                assert!((v - expected).abs() < 1e-9, "sample {i}: {v} vs {expected}");
            }
        }
    }

    #[test]
    fn point_samples_have_the_bits_of_bilinear_samples_inside_and_across_the_border() {
        let mut rng = crate::rng::SimRng::new(9);
        let (w, h) = (97u32, 61u32);
        let data: Vec<u8> = (0..w * h).map(|_| (rng.next_u64() % 256) as u8).collect();
        let image = GrayImage::from_raw(w, h, data).unwrap_or_else(|| GrayImage::new(1, 1));
        for trial in 0..300 {
            let n = (rng.next_u64() % 23) as usize;
            // Mostly inside, some on the last row and column exactly, some outside.
            let coordinate = |rng: &mut crate::rng::SimRng, side: u32| match rng.next_u64() % 8 {
                0 => f64::from(side - 1),
                1 => rng.range(-3.0, 0.0),
                2 => rng.range(f64::from(side - 1), f64::from(side) + 3.0),
                _ => rng.range(0.0, f64::from(side - 1)),
            };
            let xs: Vec<f64> = (0..n).map(|_| coordinate(&mut rng, w)).collect();
            let ys: Vec<f64> = (0..n).map(|_| coordinate(&mut rng, h)).collect();
            let mut out = vec![f64::NAN; n];
            sample_points(&image, &xs, &ys, &mut out);
            for i in 0..n {
                assert_eq!(
                    out[i].to_bits(),
                    sample_bilinear(&image, xs[i], ys[i]).to_bits(),
                    "trial {trial} point {i}"
                );
            }
        }
    }

    #[test]
    fn avx2_ray_samples_have_the_same_bits_as_the_portable_ones() {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            let mut rng = crate::rng::SimRng::new(7);
            let (w, h) = (203u32, 157u32);
            let data: Vec<u8> = (0..w * h).map(|_| (rng.next_u64() % 256) as u8).collect();
            let image = GrayImage::from_raw(w, h, data).unwrap_or_else(|| GrayImage::new(1, 1));
            let (mut portable, mut avx2) = (Vec::new(), Vec::new());
            let mut compared = 0;
            for _ in 0..2000 {
                let centre = [rng.range(0.0, f64::from(w)), rng.range(0.0, f64::from(h))];
                let angle = rng.range(0.0, std::f64::consts::TAU);
                let samples = RaySamples {
                    image: &image,
                    centre,
                    dir: [angle.cos(), angle.sin()],
                    from: rng.range(0.0, 30.0),
                    step: rng.range(0.1, 1.0),
                };
                let first = (rng.next_u64() % 8) as usize;
                let count = 1 + (rng.next_u64() % 40) as usize;
                let inside = |[x, y]: [f64; 2]| {
                    x >= 0.0 && y >= 0.0 && x < f64::from(w - 1) && y < f64::from(h - 1)
                };
                if !(inside(samples.at(first)) && inside(samples.at(first + count - 1))) {
                    continue;
                }
                portable.resize(count, 0.0);
                avx2.resize(count, 0.0);
                samples.fill_inside(first, &mut portable);
                // SAFETY: the CPU has AVX2 (checked above).
                unsafe { samples.fill_inside_avx2(first, &mut avx2) };
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&portable), bits(&avx2));
                compared += 1;
            }
            assert!(compared > 200, "only {compared} rays inside");
        }
    }
}
