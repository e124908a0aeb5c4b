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
    /// Farthest the rim-side windows reach from the edge: a pixel and a half short of a thin
    /// wall's outer edge (see [`Self::within_wall`]); at least `level_far_px` for a wide one.
    pub rim_far_px: f64,
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
            rim_far_px: 6.0,
        }
    }
}

impl RayParams {
    /// These parameters for a rim `wall_px` wide: the rim-side windows stop 1.5 px short of the
    /// wall's outer edge (bilinear samples of an area-sampled step differ from the levels either
    /// side up to 1.5 px from it), and never closer to the edge than 0.5 px.
    pub fn within_wall(mut self, wall_px: f64) -> Self {
        self.rim_far_px = (wall_px - 1.5).clamp(0.5, self.level_far_px);
        self
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

use crate::perception::ray_samples::RaySamples;
pub use crate::perception::ray_samples::{sample_bilinear, sample_ray};

/// `profile[from..=to]`, indices clamped to the profile, and where it starts.
fn stretch(profile: &[f64], from: isize, to: isize) -> (usize, &[f64]) {
    let last = profile.len() as isize - 1;
    let (a, b) = (from.clamp(0, last) as usize, to.clamp(0, last) as usize);
    (a, &profile[a..=b])
}

/// The sum of each of `stretches`, each added up in order from its first value as
/// `iter().sum()` does (the same bits), all stepped together so that their chains of additions
/// overlap rather than wait on one another.
fn sums_together<const N: usize>(stretches: [&[f64]; N]) -> [f64; N] {
    let longest = stretches.iter().map(|v| v.len()).max().unwrap_or(0);
    let mut sums = [-0.0; N];
    for i in 0..longest {
        for (sum, values) in sums.iter_mut().zip(&stretches) {
            if let Some(&v) = values.get(i) {
                *sum += v;
            }
        }
    }
    sums
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
    let steps = RaySteps::new(params);
    refine_ray_in_steps(image, centre, ray, expected_radius_px, &steps, scratch)
}

/// A [`RayParams`]' distances in samples, worked out once for all the rays of a bore.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RaySteps {
    /// The parameters.
    params: RayParams,
    /// `search_half_px`, `level_near_px`, `level_far_px`, `rim_near_px`, `integral_half_px`,
    /// `rim_far_px` and half a pixel, in samples.
    search: isize,
    near: isize,
    far: isize,
    rim_near: isize,
    half: isize,
    rim_far: isize,
    span: isize,
}

impl RaySteps {
    /// The distances of `params` in samples.
    pub fn new(params: &RayParams) -> Self {
        let step = params.step_px;
        // Truncation of the value plus a half: `round` for these non-negative values, without a
        // libm call (rounding instructions need SSE4.1, beyond the baseline target).
        let steps_of = |d: f64| (d / step + 0.5) as isize;
        Self {
            params: *params,
            search: steps_of(params.search_half_px),
            near: steps_of(params.level_near_px),
            far: steps_of(params.level_far_px),
            rim_near: steps_of(params.rim_near_px),
            half: steps_of(params.integral_half_px),
            rim_far: steps_of(params.rim_far_px),
            span: steps_of(0.5),
        }
    }
}

/// [`refine_ray`] with the parameters' distances in samples worked out beforehand.
pub fn refine_ray_in_steps(
    image: &GrayImage,
    centre: [f64; 2],
    ray: RayDir,
    expected_radius_px: f64,
    steps: &RaySteps,
    scratch: &mut Vec<f64>,
) -> Option<EdgePoint> {
    let params = &steps.params;
    if image.width() == 0 || image.height() == 0 || params.step_px <= 0.0 {
        return None;
    }
    let [c, s] = ray.unit;
    let step = params.step_px;
    let (search, near, far) = (steps.search, steps.near, steps.far);
    let (rim_near, half) = (steps.rim_near, steps.half);
    let reach = search + far.max(half + 1);
    // The profile's first sample may not pass the centre: keep `reach` samples inside.
    let t0 = (expected_radius_px - reach as f64 * step).max(0.0);
    let centre_index = ((expected_radius_px - t0) / step + 0.5) as isize;
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
    let span = steps.span.max(1);
    let (low, high) = (
        (centre_index - search).max(span),
        (centre_index + search).min(last - span),
    );
    if low > high {
        return None;
    }
    // Only the samples the search and then the windows about the chosen step read are taken:
    // first the searched stretch, then what the windows need beyond it.
    let searched = in_chunks((low - span) as usize..(high + span + 1) as usize, count);
    samples.fill(searched.clone(), scratch);
    // The first steepest positive rise, kept by selects rather than branches (which
    // mispredicted on noisy profiles): a rise must beat zero, then every later one the best.
    let (mut best, mut best_rise) = (None, 0.0);
    for j in low..=high {
        let rise = scratch[(j + span) as usize] - scratch[(j - span) as usize];
        let steeper = rise > best_rise;
        best = if steeper { Some(j) } else { best };
        best_rise = if steeper { rise } else { best_rise };
    }
    let j = best?;
    let wing = far.max(near).max(rim_near).max(half);
    let (first, end) = (
        (j - wing).max(0) as usize,
        (j + wing).min(last) as usize + 1,
    );
    samples.fill(in_chunks(first..searched.start.max(first), count), scratch);
    samples.fill(in_chunks(searched.end.min(end)..end, count), scratch);
    let profile = scratch.as_slice();
    // The rim side stops short of a thin wall's outer edge.
    let rim_far = steps.rim_far.clamp(1, far);
    let (rim_near_out, rim_level_near) = (rim_near.min(rim_far - 1).max(0), near.min(rim_far));
    // The level windows, and the flanks fitted by lines so that a ramp (a stain's soft rim, a
    // shadow, uneven light) does not bias the normalisation: all four sums at once.
    let (inner_window, outer_window) = (
        stretch(profile, j - far, j - near).1,
        stretch(profile, j + rim_level_near, j + rim_far).1,
    );
    let flanks = [
        stretch(profile, j - far, j - rim_near),
        stretch(profile, j + rim_near_out, j + rim_far),
    ];
    let [inner_sum, outer_sum, inner_flank_sum, outer_flank_sum] =
        sums_together([inner_window, outer_window, flanks[0].1, flanks[1].1]);
    let inner_level = inner_sum / inner_window.len() as f64;
    let outer_level = outer_sum / outer_window.len() as f64;
    if outer_level - inner_level < params.min_contrast {
        return None;
    }
    let [inner, outer] = Flank::fit_both(flanks, [inner_flank_sum, outer_flank_sum]);
    let (a, b) = ((j - half).max(0), (j + half.min(rim_far)).min(last));
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

/// `range` grown to whole chunks of four samples (the AVX2 sampler's), to the right as far as
/// `count` allows and then to the left, so that no sample is left to the scalar tail. The extra
/// samples are ones the profile holds anyway, and each depends on its index alone: the profile
/// keeps its bits.
fn in_chunks(range: std::ops::Range<usize>, count: usize) -> std::ops::Range<usize> {
    let want = range.len().div_ceil(4) * 4;
    if want == 0 {
        return range;
    }
    let end = (range.start + want).min(count);
    end.saturating_sub(want)..end
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
    #[cfg(test)]
    fn fit(profile: &[f64], from: isize, to: isize) -> Self {
        let values = stretch(profile, from, to);
        let [sum] = sums_together([values.1]);
        let [flank, _] = Self::fit_both([values; 2], [sum; 2]);
        flank
    }

    /// The lines through two stretches of a profile (each with where it starts in the profile
    /// and the sum of its values), each with the bits of a fit of its own. Each fit is chains of
    /// sums, one after the other; stepping both fits' chains together lets them overlap.
    fn fit_both(values: [(usize, &[f64]); 2], sums: [f64; 2]) -> [Self; 2] {
        let longest = values[0].1.len().max(values[1].1.len());
        let n = values.map(|(_, v)| v.len() as f64);
        let mean_offset = n.map(|n| (n - 1.0) / 2.0);
        // Sample `i` of both stretches, where the stretch has one.
        let pair = |i: usize| values.map(|(_, v)| v.get(i).copied());
        let mean_level = [sums[0] / n[0], sums[1] / n[1]];
        // The abscissae `i - mean_offset` are multiples of a half and their squares of a
        // quarter, so stepping them by one and summing their squares in closed form, n (n^2 - 1)
        // / 12, is exact: the same bits as converting each index and summing the squares.
        let sxx = n.map(|n| n * (n * n - 1.0) / 12.0);
        let mut sxy = [0.0; 2];
        let mut x = mean_offset.map(|m| -m);
        for i in 0..longest {
            for k in 0..2 {
                if let Some(v) = pair(i)[k] {
                    sxy[k] += x[k] * (v - mean_level[k]);
                    x[k] += 1.0;
                }
            }
        }
        let slope = [0, 1].map(|k| if sxx[k] > 0.0 { sxy[k] / sxx[k] } else { 0.0 });
        let mut sum_sq = [0.0; 2];
        let mut x = mean_offset.map(|m| -m);
        for i in 0..longest {
            for k in 0..2 {
                if let Some(v) = pair(i)[k] {
                    sum_sq[k] += (v - mean_level[k] - slope[k] * x[k]).powi(2);
                    x[k] += 1.0;
                }
            }
        }
        [0, 1].map(|k| Self {
            mean_index: values[k].0 as f64 + mean_offset[k],
            mean_level: mean_level[k],
            slope: slope[k],
            rms: (sum_sq[k] / n[k]).sqrt(),
        })
    }

    /// The line's level at sample index `k`.
    fn at(&self, k: isize) -> f64 {
        self.mean_level + self.slope * (k as f64 - self.mean_index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::synthetic::disc_scene;

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
    fn flank_fits_have_the_bits_of_the_textbook_sums() {
        let mut rng = crate::rng::SimRng::new(3);
        for n in 1..24usize {
            let profile: Vec<f64> = (0..n).map(|_| rng.range(0.0, 255.0)).collect();
            let fit = Flank::fit(&profile, 0, n as isize - 1);
            // Each abscissa converted from its index, every sum in order.
            let count = n as f64;
            let mean_offset = (count - 1.0) / 2.0;
            let mean_level = profile.iter().sum::<f64>() / count;
            let (mut sxy, mut sxx) = (0.0, 0.0);
            for (i, &v) in profile.iter().enumerate() {
                let x = i as f64 - mean_offset;
                sxy += x * (v - mean_level);
                sxx += x * x;
            }
            let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
            let sum_sq: f64 = profile
                .iter()
                .enumerate()
                .map(|(i, &v)| (v - mean_level - slope * (i as f64 - mean_offset)).powi(2))
                .sum();
            assert_eq!(fit.slope.to_bits(), slope.to_bits(), "n {n}");
            assert_eq!(
                fit.rms.to_bits(),
                (sum_sq / count).sqrt().to_bits(),
                "n {n}"
            );
            assert_eq!(fit.mean_level.to_bits(), mean_level.to_bits(), "n {n}");
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
