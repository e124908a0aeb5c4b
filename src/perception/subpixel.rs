//! Sub-pixel edge location along rays from a coarse centre.
//!
//! Integer contour pixels sit up to a pixel off the true edge, which adds 1-2 px of false
//! out-of-roundness. Here each ray from the coarse centre is sampled once, with bilinear
//! interpolation at even steps, across a stretch around the expected edge. On that profile:
//! 1. the edge is the steepest dark-to-bright step within the search window: a bore edge is a
//!    sharp step of the full rim contrast, while the boundary of an oil stain (or of the light
//!    pool of a lamp) is a soft ramp, so a stain touching the bore cannot pull the edge outwards;
//! 2. the bore side (inside) and rim side (outside) are fitted by lines on the same ray at fixed
//!    distances from that step, which makes the result immune to illumination gradients and to
//!    the ramp of a stain's soft rim;
//! 3. the edge position is the area (first-moment) estimate of the step normalised by those
//!    lines.
//!
//! Each edge also reports how far its flanks depart from lines, so the caller can tell a clean
//! step from one next to a speck of dirt or on the curved part of a stain's rim.

use image::GrayImage;

/// How rays sample the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayParams {
    /// Half length of the searched stretch around the expected radius.
    pub search_half_px: f64,
    /// Sample spacing of the profile.
    pub step_px: f64,
    /// Distance from the edge to the near end of the level windows.
    pub level_near_px: f64,
    /// Distance from the edge to the far end of the level windows.
    pub level_far_px: f64,
    /// Distance from the edge to the near end of the flanks fitted by lines.
    pub rim_near_px: f64,
    /// Smallest rim-minus-bore difference, grey levels, for a ray to count.
    pub min_contrast: f64,
    /// Half width of the window the edge's area estimate integrates over.
    pub integral_half_px: f64,
}

impl Default for RayParams {
    fn default() -> Self {
        Self {
            search_half_px: 3.5,
            step_px: 0.5,
            level_near_px: 3.0,
            level_far_px: 6.0,
            rim_near_px: 1.5,
            min_contrast: 20.0,
            integral_half_px: 2.0,
        }
    }
}

/// A ray's direction: its angle and unit vector `[cos, sin]`, computed once per ray and shared
/// by every stage that walks along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayDir {
    /// Angle from the x axis (towards y), radians.
    pub angle_rad: f64,
    /// `[cos, sin]` of the angle.
    pub unit: [f64; 2],
}

impl RayDir {
    /// The direction at `angle_rad`.
    pub fn new(angle_rad: f64) -> Self {
        let (s, c) = angle_rad.sin_cos();
        Self {
            angle_rad,
            unit: [c, s],
        }
    }
}

/// One refined edge point and the levels either side of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgePoint {
    /// Edge position `[x, y]`, pixels.
    pub point_px: [f64; 2],
    /// Direction of the ray.
    pub ray: RayDir,
    /// Distance from the ray's origin to the edge.
    pub radius_px: f64,
    /// Mean level inside (bore side), `level_near_px..level_far_px` from the edge.
    pub inner_level: f64,
    /// Mean level outside (rim side), `level_near_px..level_far_px` from the edge.
    pub outer_level: f64,
    /// RMS departure of the levels either side of the edge (`rim_near_px..level_far_px` from
    /// it) from straight lines, the larger of the two sides.
    pub flank_rms: f64,
}

impl EdgePoint {
    /// Rim minus bore level.
    pub fn contrast(&self) -> f64 {
        self.outer_level - self.inner_level
    }

    /// How far the levels either side of the edge depart from straight lines, as a share of the
    /// contrast: about the noise level for a clean step between flat or evenly sloping levels,
    /// large where a speck of dirt or the curved part of a stain's rim lies against the edge.
    pub fn flank_departure(&self) -> f64 {
        self.flank_rms / self.contrast().max(1.0)
    }
}

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

/// Where the samples of one ray lie: sample `i` is at `centre + (from + step i) dir`.
struct RaySamples<'a> {
    image: &'a GrayImage,
    centre: [f64; 2],
    dir: [f64; 2],
    from: f64,
    step: f64,
}

impl RaySamples<'_> {
    /// Position of sample `i`.
    #[inline]
    fn at(&self, i: usize) -> [f64; 2] {
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
    fn fill(&self, range: std::ops::Range<usize>, out: &mut [f64]) {
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
    fn fill_inside(&self, first: usize, out: &mut [f64]) {
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
        // Each gather reads four bytes: the top pair from its first two, the bottom pair from
        // the last two of a read starting two bytes early (so it never passes the image's end).
        // Clamping the start indices keeps every read inside the image whatever the positions.
        let last_start = raw.len().saturating_sub(w + 2) as i32;
        let (low, high) = (_mm_setzero_si128(), _mm_set1_epi32(last_start));
        let (width, byte) = (_mm_set1_epi32(w as i32), _mm_set1_epi32(0xff));
        let bottom_offset = _mm_set1_epi32(w as i32 - 2);
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
            let (x0, y0) = (_mm256_cvttpd_epi32(x), _mm256_cvttpd_epi32(y));
            let fx = _mm256_sub_pd(x, _mm256_cvtepi32_pd(x0));
            let fy = _mm256_sub_pd(y, _mm256_cvtepi32_pd(y0));
            let start = _mm_add_epi32(_mm_mullo_epi32(y0, width), x0);
            let start = _mm_min_epi32(_mm_max_epi32(start, low), high);
            // SAFETY: `start` lies in `[0, len - w - 2]`, so the four bytes read from `start`
            // and from `start + w - 2` are inside `raw` (`w >= 2` for a sample to be inside).
            let (top, bottom) = unsafe {
                (
                    _mm_i32gather_epi32::<1>(raw.as_ptr().cast(), start),
                    _mm_i32gather_epi32::<1>(
                        raw.as_ptr().cast(),
                        _mm_add_epi32(start, bottom_offset),
                    ),
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
            let value = _mm256_add_pd(top, _mm256_mul_pd(fy, _mm256_sub_pd(bottom, top)));
            // SAFETY: `chunk` holds exactly four `f64`.
            unsafe { _mm256_storeu_pd(chunk.as_mut_ptr(), value) };
            i += 4;
        }
        self.fill_inside(i, chunks.into_remainder());
    }
}

/// Mean of `profile[from..=to]`, indices clamped to the profile.
fn window_mean(profile: &[f64], from: isize, to: isize) -> f64 {
    let last = profile.len() as isize - 1;
    let (a, b) = (from.clamp(0, last) as usize, to.clamp(0, last) as usize);
    profile[a..=b].iter().sum::<f64>() / (b - a + 1) as f64
}

/// Locates the dark-to-bright edge on the ray from `centre` at `angle_rad` near
/// `expected_radius_px`. `None` when the profile has no rising step there, the contrast is too
/// low, or the area estimate strays from the step. `scratch` holds the profile.
///
/// The steepest rise (central differences over one pixel) within `search_half_px` of the expected
/// radius picks the edge; the levels either side are measured `level_near_px..level_far_px` from
/// it. Its position is then the area (first-moment) estimate `t = b - integral_a^b n(t) dt` of the
/// normalised profile `n = (I - inner(t)) / (outer(t) - inner(t))` over `[a, b]`,
/// `integral_half_px` either side of the step, where `inner(t)` and `outer(t)` are lines fitted
/// to the flanks `rim_near_px..level_far_px` from the step (a ramp on either side, such as a
/// stain's soft rim, then biases nothing). For an area-sampled step edge and any symmetric blur that integral
/// is exact, where linear interpolation of the half-level crossing is biased by up to 0.09 px.
pub fn refine_ray(
    image: &GrayImage,
    centre: [f64; 2],
    ray: RayDir,
    expected_radius_px: f64,
    params: &RayParams,
    scratch: &mut Vec<f64>,
) -> Option<EdgePoint> {
    if image.width() == 0 || image.height() == 0 || params.step_px <= 0.0 {
        return None;
    }
    let [c, s] = ray.unit;
    let step = params.step_px;
    let steps_of = |d: f64| (d / step).round() as isize;
    let (search, near, far) = (
        steps_of(params.search_half_px),
        steps_of(params.level_near_px),
        steps_of(params.level_far_px),
    );
    let (rim_near, half) = (
        steps_of(params.rim_near_px),
        steps_of(params.integral_half_px),
    );
    let reach = search + far.max(half + 1);
    // The profile's first sample may not pass the centre: keep `reach` samples inside.
    let t0 = (expected_radius_px - reach as f64 * step).max(0.0);
    let centre_index = ((expected_radius_px - t0) / step).round() as isize;
    let count = (centre_index + reach + 1) as usize;
    let samples = RaySamples {
        image,
        centre,
        dir: ray.unit,
        from: t0,
        step,
    };
    scratch.clear();
    scratch.resize(count, 0.0);
    let last = count as isize - 1;
    // Steepest rise over one pixel (two steps apart at the default spacing).
    let span = steps_of(0.5).max(1);
    let (low, high) = (
        (centre_index - search).max(span),
        (centre_index + search).min(last - span),
    );
    if low > high {
        return None;
    }
    // Only the samples the search and then the windows about the chosen step read are taken:
    // first the searched stretch, then what the windows need beyond it.
    let searched = (low - span) as usize..(high + span + 1) as usize;
    samples.fill(searched.clone(), scratch);
    let mut best: Option<(isize, f64)> = None;
    for j in low..=high {
        let rise = scratch[(j + span) as usize] - scratch[(j - span) as usize];
        if rise > 0.0 && best.is_none_or(|(_, b)| rise > b) {
            best = Some((j, rise));
        }
    }
    let (j, _) = best?;
    let wing = far.max(near).max(rim_near).max(half);
    let (first, end) = (
        (j - wing).max(0) as usize,
        (j + wing).min(last) as usize + 1,
    );
    samples.fill(first..searched.start.max(first), scratch);
    samples.fill(searched.end.min(end)..end, scratch);
    let profile = scratch.as_slice();
    let (j, _) = best?;
    let inner_level = window_mean(profile, j - far, j - near);
    let outer_level = window_mean(profile, j + near, j + far);
    if outer_level - inner_level < params.min_contrast {
        return None;
    }
    // The flanks as lines, so that a ramp (a stain's soft rim, a shadow, uneven light) does not
    // bias the normalisation.
    let inner = Flank::fit(profile, j - far, j - rim_near);
    let outer = Flank::fit(profile, j + rim_near, j + far);
    let (a, b) = ((j - half).max(0), (j + half).min(last));
    let mut integral = 0.0;
    for k in a..=b {
        let weight = if k == a || k == b { 0.5 } else { 1.0 };
        let (low, high) = (inner.at(k), outer.at(k));
        if high - low < params.min_contrast {
            return None;
        }
        integral += weight * (profile[k as usize] - low) / (high - low);
    }
    let t = t0 + step * b as f64 - integral * step;
    let t_step = t0 + step * j as f64;
    if (t - t_step).abs() > 1.0 {
        return None;
    }
    Some(EdgePoint {
        point_px: [centre[0] + t * c, centre[1] + t * s],
        ray,
        radius_px: t,
        inner_level,
        outer_level,
        flank_rms: inner.rms.max(outer.rms),
    })
}

/// A least-squares line through a stretch of a ray profile.
struct Flank {
    /// Mean sample index.
    mean_index: f64,
    /// Mean level.
    mean_level: f64,
    /// Level change per sample.
    slope: f64,
    /// RMS of the samples about the line.
    rms: f64,
}

impl Flank {
    /// The line through `profile[from..=to]` (indices clamped to the profile).
    fn fit(profile: &[f64], from: isize, to: isize) -> Self {
        let last = profile.len() as isize - 1;
        let (a, b) = (from.clamp(0, last) as usize, to.clamp(0, last) as usize);
        let values = &profile[a..=b];
        let n = values.len() as f64;
        let mean_offset = (n - 1.0) / 2.0;
        let mean_level = values.iter().sum::<f64>() / n;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (i, &v) in values.iter().enumerate() {
            let x = i as f64 - mean_offset;
            sxy += x * (v - mean_level);
            sxx += x * x;
        }
        let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        let sum_sq: f64 = values
            .iter()
            .enumerate()
            .map(|(i, &v)| (v - mean_level - slope * (i as f64 - mean_offset)).powi(2))
            .sum();
        Self {
            mean_index: a as f64 + mean_offset,
            mean_level,
            slope,
            rms: (sum_sq / n).sqrt(),
        }
    }

    /// The line's level at sample index `k`.
    fn at(&self, k: isize) -> f64 {
        self.mean_level + self.slope * (k as f64 - self.mean_index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::synthetic::{BoreShape, Illumination, Noise, Scene, Tube};

    fn disc_scene(cx: f64, cy: f64, r: f64) -> GrayImage {
        Scene {
            width_px: 160,
            height_px: 160,
            belt_level: 40.0,
            tubes: vec![Tube {
                centre_px: [cx, cy],
                bore: BoreShape::Circle { radius_px: r },
                outer_radius_px: r + 20.0,
                rim_level: 200.0,
                bore_level: 20.0,
            }],
            bottles: vec![],
            stains: vec![],
            illumination: Illumination::EVEN,
            noise: Noise::NONE,
            noise_seed: 0,
        }
        .render()
    }

    #[test]
    fn rays_find_an_anti_aliased_circle_to_a_few_hundredths() {
        let (cx, cy, r) = (80.3, 79.6, 40.27);
        let image = disc_scene(cx, cy, r);
        let (mut worst, mut sum): (f64, f64) = (0.0, 0.0);
        for i in 0..360 {
            let angle = f64::from(i).to_radians();
            // Start off-centre, with a coarse radius a pixel off.
            let centre = [cx + 0.7, cy - 0.4];
            let Some(edge) = refine_ray(
                &image,
                centre,
                RayDir::new(angle),
                r + 1.0,
                &RayParams::default(),
                &mut Vec::new(),
            ) else {
                panic!("ray {i} found no edge");
            };
            let d = (edge.point_px[0] - cx).hypot(edge.point_px[1] - cy);
            worst = worst.max((d - r).abs());
            sum += d - r;
        }
        // Bilinear sampling of a pixel grid leaves a small error that varies quickly along the
        // edge (the roundness filter removes most of it); the mean error is the radius bias.
        assert!(worst < 0.08, "worst radial error {worst}");
        assert!(
            (sum / 360.0).abs() < 0.02,
            "mean radial error {}",
            sum / 360.0
        );
    }

    #[test]
    fn a_stain_ramp_beside_the_edge_does_not_move_it() {
        let (cx, cy, r) = (80.3, 79.6, 40.27);
        let mut image = disc_scene(cx, cy, r);
        // A stain darkening the rim to 50 % at the edge and fading out linearly over 6 px.
        for (x, y, p) in image.enumerate_pixels_mut() {
            let d = (f64::from(x) - cx).hypot(f64::from(y) - cy) - r;
            if (-1.0..6.0).contains(&d) {
                // Only the rim's share of an edge pixel is stained (the bore level is 20).
                let factor = 0.5 + 0.5 * d.max(0.0) / 6.0;
                p.0[0] = (20.0 + (f64::from(p.0[0]) - 20.0) * factor).round() as u8;
            }
        }
        let mut sum = 0.0;
        for i in 0..360 {
            let angle = f64::from(i).to_radians();
            let Some(edge) = refine_ray(
                &image,
                [cx, cy],
                RayDir::new(angle),
                r + 1.5,
                &RayParams::default(),
                &mut Vec::new(),
            ) else {
                panic!("ray {i} found no edge");
            };
            sum += edge.radius_px - r;
        }
        assert!(
            (sum / 360.0).abs() < 0.05,
            "mean radial error {}",
            sum / 360.0
        );
    }

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

    #[test]
    fn a_flat_ray_has_no_edge() {
        let image = GrayImage::from_pixel(50, 50, image::Luma([100]));
        assert!(
            refine_ray(
                &image,
                [25.0, 25.0],
                RayDir::new(0.0),
                10.0,
                &RayParams::default(),
                &mut Vec::new()
            )
            .is_none()
        );
    }
}
