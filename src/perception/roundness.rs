//! Roundness `Rmax - Rmin` about the fitted centre (seed paper eq. 11), on a low-passed profile.
//!
//! The raw eq. 11 takes the extreme of hundreds of noisy edge points, so every bit of edge noise
//! adds to the result. As in roundness metrology practice (ISO 12181-2 filters the profile to a
//! number of undulations per revolution, UPR), the radial profile `r(theta)` about the fitted
//! centre is expanded in a Fourier series up to `max_upr` by quadrature over the sorted angles,
//! and `Rmax - Rmin` is taken on that series. Form errors below the cutoff (ellipse: 2 UPR and its
//! harmonics, 2-/3-lobe bores) pass unchanged; pixel noise is averaged.

use crate::perception::circle_fit::distance;
use crate::perception::error::PerceptionError;
use std::f64::consts::TAU;

/// Default cutoff, undulations per revolution.
pub const DEFAULT_MAX_UPR: usize = 15;

/// A radial profile about a centre, low-passed to `max_upr`.
#[derive(Debug, Clone, PartialEq)]
pub struct RoundnessProfile {
    /// Mean radius (the series' constant term).
    pub mean_radius: f64,
    /// `(a_k, b_k)` for `k = 1..=max_upr`: `r(theta) = mean + sum a_k cos k theta + b_k sin k theta`.
    pub harmonics: Vec<(f64, f64)>,
    /// `Rmax - Rmin` of the filtered profile.
    pub roundness: f64,
    /// RMS of the points' radii about the filtered profile (edge noise).
    pub residual_rms: f64,
    /// Number of points.
    pub point_count: usize,
}

impl RoundnessProfile {
    /// Filtered radius in direction `theta_rad`.
    pub fn radius_at(&self, theta_rad: f64) -> f64 {
        let (s, c) = theta_rad.sin_cos();
        series_along(self.mean_radius, &self.harmonics, [c, s])
    }

    /// One-sigma uncertainty of `roundness` from edge noise: the profile's value at a point has
    /// variance `sigma^2 (2K + 1) / n`, and the roundness is a difference of two such values.
    pub fn roundness_sigma(&self) -> f64 {
        let k = self.harmonics.len() as f64;
        let n = self.point_count.max(1) as f64;
        self.noise_sigma() * (2.0 * (2.0 * k + 1.0) / n).sqrt()
    }

    /// Edge noise per point, corrected for the degrees of freedom of the series.
    pub fn noise_sigma(&self) -> f64 {
        let n = self.point_count as f64;
        let dof = n - 2.0 * self.harmonics.len() as f64 - 1.0;
        if dof <= 0.0 {
            return self.residual_rms;
        }
        self.residual_rms * (n / dof).sqrt()
    }
}

/// `mean + sum_k a_k cos k theta + b_k sin k theta` for `k = 1..=harmonics.len()`, given
/// `unit = [cos theta, sin theta]`.
pub(crate) fn series_along(mean: f64, harmonics: &[(f64, f64)], unit: [f64; 2]) -> f64 {
    let [c1, s1] = unit;
    let (mut c, mut s) = (1.0f64, 0.0f64);
    let mut r = mean;
    for &(a, b) in harmonics {
        // Rotate (cos k theta, sin k theta) by theta.
        let c_next = c * c1 - s * s1;
        s = s * c1 + c * s1;
        c = c_next;
        r += a * c + b * s;
    }
    r
}

/// Median of `values` (reordered); 0 for an empty slice.
pub fn median_of(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// Low-passed radial profile of `points` about `centre` and its `Rmax - Rmin`.
///
/// The Fourier coefficients are integrals over the angle, evaluated by the trapezoidal rule on the
/// points sorted by angle, so uneven angular spacing (dropped rays, an off-centre start) does not
/// bias them. `max_upr` is capped at a quarter of the point count.
pub fn filtered_roundness(
    points: &[[f64; 2]],
    centre: [f64; 2],
    max_upr: usize,
) -> Result<RoundnessProfile, PerceptionError> {
    if points.len() < 8 {
        return Err(PerceptionError::DegenerateFit {
            point_count: points.len(),
        });
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the function only requires AVX2, which the CPU was just found to have.
        return Ok(unsafe { filtered_roundness_avx2(points, centre, max_upr) });
    }
    Ok(filtered_roundness_kernel(points, centre, max_upr))
}

/// [`filtered_roundness_kernel`] compiled for AVX2: the same IEEE operations in the same order
/// for every point and sample (Rust never fuses a multiply and an add), so the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn filtered_roundness_avx2(
    points: &[[f64; 2]],
    centre: [f64; 2],
    max_upr: usize,
) -> RoundnessProfile {
    filtered_roundness_kernel(points, centre, max_upr)
}

/// `sum_k a_k cos k theta_i + b_k sin k theta_i` for every point `i`, summed over `k` in
/// ascending order, into `out`; `columns[k - 1]` holds `cos k theta_i` for all `i`, then `sin k
/// theta_i`. Harmonic by harmonic over all points, so the loop runs in vector lanes; each point
/// sees the same additions in the same order as a sum over its row.
#[inline(always)]
fn series_values(columns: &[Vec<f64>], harmonics: &[(f64, f64)], out: &mut [f64]) {
    let n = out.len();
    out.fill(0.0);
    for (pair, &(a, b)) in columns.iter().zip(harmonics) {
        let (cos_k, sin_k) = pair.split_at(n.min(pair.len()));
        for ((o, &c), &s) in out.iter_mut().zip(cos_k).zip(sin_k) {
            *o += a * c + b * s;
        }
    }
}

/// The body of [`filtered_roundness`] (at least 8 points), inlined into each instruction-set
/// variant.
#[inline(always)]
fn filtered_roundness_kernel(
    points: &[[f64; 2]],
    centre: [f64; 2],
    max_upr: usize,
) -> RoundnessProfile {
    // (angle, radius, [cos, sin] of the angle): the direction from the offsets themselves, which
    // spares a sine and cosine a point.
    let mut polar: Vec<(f64, f64, [f64; 2])> = points
        .iter()
        .map(|p| {
            let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
            let r = distance(dx, dy);
            let unit = if r > 0.0 {
                [dx / r, dy / r]
            } else {
                [1.0, 0.0]
            };
            (dy.atan2(dx), r, unit)
        })
        .collect();
    polar.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = polar.len();
    let k_max = max_upr.min(n / 4);
    let weights: Vec<f64> = (0..n)
        .map(|i| {
            let span = polar[(i + 1) % n].0 - polar[(i + n - 1) % n].0;
            0.5 * if span <= 0.0 { span + TAU } else { span }
        })
        .collect();
    // cos(k theta_i), sin(k theta_i) for k = 1..=K harmonic by harmonic (for the series at every
    // point, see `series_values`), rotating all points at once: `cos k theta_i` for all `i`, then
    // the sines. (Rotating each point on its own, harmonic after harmonic, chains every step on
    // the one before.)
    let mut columns: Vec<Vec<f64>> = Vec::with_capacity(k_max);
    if k_max > 0 {
        let first: Vec<f64> = (polar.iter().map(|p| p.2[0]))
            .chain(polar.iter().map(|p| p.2[1]))
            .collect();
        for _ in 1..k_max {
            let (cos_1, sin_1) = first.split_at(n);
            let previous = columns.last().unwrap_or(&first);
            let (cos_prev, sin_prev) = previous.split_at(n);
            let pairs = || cos_prev.iter().zip(sin_prev).zip(cos_1.iter().zip(sin_1));
            let next: Vec<f64> = (pairs().map(|((&c, &s), (&c1, &s1))| c * c1 - s * s1))
                .chain(pairs().map(|((&c, &s), (&c1, &s1))| s * c1 + c * s1))
                .collect();
            columns.push(next);
        }
        columns.insert(0, first);
    }
    // The same values point by point (for the quadrature sums), written in order: no zeroing
    // first, no stride through the table.
    let mut basis = Vec::with_capacity(n * k_max);
    for i in 0..n {
        basis.extend(columns.iter().map(|column| (column[i], column[n + i])));
    }
    let mut mean_radius = polar.iter().map(|p| p.1).sum::<f64>() / n as f64;
    let mut harmonics = vec![(0.0f64, 0.0f64); k_max];
    // The series at each point, less its mean: zero before the first pass.
    let mut explained = vec![0.0f64; n];
    // Quadrature of what the series does not yet explain, repeated: on uneven spacing one pass
    // leaks a little of each harmonic into the others; three passes converge to the least-squares
    // series for spacing as even as the detector's rays.
    for pass in 0..3 {
        if pass > 0 {
            series_values(&columns, &harmonics, &mut explained);
        }
        let mut constant = 0.0;
        let mut sums = vec![(0.0f64, 0.0f64); k_max];
        for (i, ((&(_, r, _), &weight), &e)) in
            polar.iter().zip(&weights).zip(&explained).enumerate()
        {
            let residual = weight * (r - (mean_radius + e));
            constant += residual;
            for (sum, &(c, s)) in sums.iter_mut().zip(&basis[i * k_max..(i + 1) * k_max]) {
                sum.0 += residual * c;
                sum.1 += residual * s;
            }
        }
        mean_radius += constant / TAU;
        for (h, &(a, b)) in harmonics.iter_mut().zip(&sums) {
            h.0 += a / std::f64::consts::PI;
            h.1 += b / std::f64::consts::PI;
        }
    }
    series_values(&columns, &harmonics, &mut explained);
    let sum_sq = polar
        .iter()
        .zip(&explained)
        .fold(0.0, |sum, (p, &e)| sum + (p.1 - (mean_radius + e)).powi(2));
    let roundness = series_range(mean_radius, &harmonics);
    RoundnessProfile {
        mean_radius,
        harmonics,
        roundness,
        residual_rms: (sum_sq / n as f64).sqrt(),
        point_count: n,
    }
}

/// `Rmax - Rmin` of the series `mean + sum_k a_k cos k theta + b_k sin k theta`, sampled densely.
#[inline(always)]
pub(crate) fn series_range(mean_radius: f64, harmonics: &[(f64, f64)]) -> f64 {
    // Dense enough that the sampled extremes of a K-UPR series are within ~1e-3 of the true ones.
    let samples = 32 * (harmonics.len() + 1);
    // Sample directions by rotating one step at a time (no sine and cosine per sample; the
    // rounding this accumulates over a revolution is far below a micro-radian).
    let (step_sin, step_cos) = (TAU / samples as f64).sin_cos();
    let mut units = Vec::with_capacity(samples);
    let mut unit = [1.0f64, 0.0f64];
    for _ in 0..samples {
        units.push(unit);
        unit = [
            unit[0] * step_cos - unit[1] * step_sin,
            unit[1] * step_cos + unit[0] * step_sin,
        ];
    }
    // The series at every sample, harmonic by harmonic (vector lanes), each sample rotating its
    // own `(cos k theta, sin k theta)` as `series_along` does.
    let mut radius = vec![mean_radius; samples];
    let mut rotated: Vec<[f64; 2]> = vec![[1.0, 0.0]; samples];
    for &(a, b) in harmonics {
        for ((r, [c, s]), &[c1, s1]) in radius.iter_mut().zip(&mut rotated).zip(&units) {
            let c_next = *c * c1 - *s * s1;
            *s = *s * c1 + *c * s1;
            *c = c_next;
            *r += a * *c + b * *s;
        }
    }
    let (r_min, r_max) = radius
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &r| {
            (lo.min(r), hi.max(r))
        });
    r_max - r_min
}

/// [`filtered_roundness`] of `points` about `centre`, with `bridges` (points of a model of the
/// outline) filling the arcs without measured points; the noise figures count the measured
/// points only.
pub fn filtered_roundness_bridged(
    points: &[[f64; 2]],
    bridges: &[[f64; 2]],
    centre: [f64; 2],
    max_upr: usize,
) -> Result<RoundnessProfile, PerceptionError> {
    if bridges.is_empty() {
        return filtered_roundness(points, centre, max_upr);
    }
    let all: Vec<[f64; 2]> = points.iter().chain(bridges).copied().collect();
    let mut profile = filtered_roundness(&all, centre, max_upr)?;
    // Bridge points sit on the series exactly: the residual sum is the measured points' alone.
    let n_all = all.len() as f64;
    let n = points.len().max(1) as f64;
    profile.residual_rms *= (n_all / n).sqrt();
    profile.point_count = points.len();
    Ok(profile)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn lobed_profile_roundness_is_twice_the_amplitude(
            r in 20.0f64..120.0, amp in 0.0f64..5.0, lobes in 2u32..4, phase in 0.0f64..TAU,
            n in 180usize..800, seed in any::<u64>()
        ) {
            // As the bore detector samples: rays at even angles about a coarse centre up to a
            // pixel off, a tenth of them dropped.
            let mut rng = SimRng::new(seed);
            let origin = [10.0 + rng.range(-1.0, 1.0), -5.0 + rng.range(-1.0, 1.0)];
            let points: Vec<[f64; 2]> = (0..n)
                .filter(|_| rng.uniform() > 0.1)
                .map(|i| {
                    let t = TAU * i as f64 / n as f64;
                    // Radius of the lobed curve about (10, -5) in direction t from the origin,
                    // by fixed-point iteration.
                    let mut p = [origin[0] + r * t.cos(), origin[1] + r * t.sin()];
                    for _ in 0..50 {
                        let theta = (p[1] + 5.0).atan2(p[0] - 10.0);
                        let rr = r + amp * (f64::from(lobes) * theta + phase).cos();
                        let (ux, uy) = (t.cos(), t.sin());
                        // Point on the ray at distance s from origin with |p - c| = rr.
                        let (ox, oy) = (origin[0] - 10.0, origin[1] + 5.0);
                        let b = ox * ux + oy * uy;
                        let s = -b + (b * b - (ox * ox + oy * oy - rr * rr)).sqrt();
                        p = [origin[0] + s * ux, origin[1] + s * uy];
                    }
                    p
                })
                .collect();
            let profile = filtered_roundness(&points, [10.0, -5.0], DEFAULT_MAX_UPR)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert!((profile.roundness - 2.0 * amp).abs() < 0.02 + 0.01 * amp);
            prop_assert!((profile.mean_radius - r).abs() < 0.01);
        }
    }

    /// The profile as first written (row by row, every series summed point by point): the
    /// fast kernel must give its bits.
    fn reference_filtered_roundness(
        points: &[[f64; 2]],
        centre: [f64; 2],
        max_upr: usize,
    ) -> Result<RoundnessProfile, PerceptionError> {
        if points.len() < 8 {
            return Err(PerceptionError::DegenerateFit {
                point_count: points.len(),
            });
        }
        // (angle, radius, [cos, sin] of the angle): the direction from the offsets themselves, which
        // spares a sine and cosine a point.
        let mut polar: Vec<(f64, f64, [f64; 2])> = points
            .iter()
            .map(|p| {
                let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
                let r = distance(dx, dy);
                let unit = if r > 0.0 {
                    [dx / r, dy / r]
                } else {
                    [1.0, 0.0]
                };
                (dy.atan2(dx), r, unit)
            })
            .collect();
        polar.sort_by(|a, b| a.0.total_cmp(&b.0));
        let n = polar.len();
        let k_max = max_upr.min(n / 4);
        let weights: Vec<f64> = (0..n)
            .map(|i| {
                let span = polar[(i + 1) % n].0 - polar[(i + n - 1) % n].0;
                0.5 * if span <= 0.0 { span + TAU } else { span }
            })
            .collect();
        // cos(k theta_i), sin(k theta_i) for k = 1..=K, row by row.
        let mut basis = vec![(0.0f64, 0.0f64); n * k_max];
        for (row, &(_, _, [c1, s1])) in basis.chunks_exact_mut(k_max.max(1)).zip(&polar) {
            let (mut c, mut s) = (c1, s1);
            for cell in row.iter_mut() {
                *cell = (c, s);
                let c_next = c * c1 - s * s1;
                s = s * c1 + c * s1;
                c = c_next;
            }
        }
        let series_at = |mean: f64, harmonics: &[(f64, f64)], i: usize| -> f64 {
            let row = &basis[i * k_max..(i + 1) * k_max];
            mean + row
                .iter()
                .zip(harmonics)
                .map(|(&(c, s), &(a, b))| a * c + b * s)
                .sum::<f64>()
        };
        let mut mean_radius = polar.iter().map(|p| p.1).sum::<f64>() / n as f64;
        let mut harmonics = vec![(0.0f64, 0.0f64); k_max];
        // Quadrature of what the series does not yet explain, repeated: on uneven spacing one pass
        // leaks a little of each harmonic into the others; three passes converge to the least-squares
        // series for spacing as even as the detector's rays.
        for _ in 0..3 {
            let mut constant = 0.0;
            let mut sums = vec![(0.0f64, 0.0f64); k_max];
            for (i, (&(_, r, _), &weight)) in polar.iter().zip(&weights).enumerate() {
                let residual = weight * (r - series_at(mean_radius, &harmonics, i));
                constant += residual;
                for (sum, &(c, s)) in sums.iter_mut().zip(&basis[i * k_max..(i + 1) * k_max]) {
                    sum.0 += residual * c;
                    sum.1 += residual * s;
                }
            }
            mean_radius += constant / TAU;
            for (h, &(a, b)) in harmonics.iter_mut().zip(&sums) {
                h.0 += a / std::f64::consts::PI;
                h.1 += b / std::f64::consts::PI;
            }
        }
        let sum_sq: f64 = (0..n)
            .map(|i| (polar[i].1 - series_at(mean_radius, &harmonics, i)).powi(2))
            .sum();
        let mut profile = RoundnessProfile {
            mean_radius,
            harmonics,
            roundness: 0.0,
            residual_rms: (sum_sq / n as f64).sqrt(),
            point_count: n,
        };
        // Dense enough that the sampled extremes of a K-UPR series are within ~1e-3 of the true ones.
        let samples = 32 * (k_max + 1);
        let (mut r_min, mut r_max) = (f64::INFINITY, f64::NEG_INFINITY);
        // Sample directions by rotating one step at a time (no sine and cosine per sample; the
        // rounding this accumulates over a revolution is far below a micro-radian).
        let (step_sin, step_cos) = (TAU / samples as f64).sin_cos();
        let mut unit = [1.0f64, 0.0f64];
        for _ in 0..samples {
            let r = series_along(profile.mean_radius, &profile.harmonics, unit);
            r_min = r_min.min(r);
            r_max = r_max.max(r);
            unit = [
                unit[0] * step_cos - unit[1] * step_sin,
                unit[1] * step_cos + unit[0] * step_sin,
            ];
        }
        profile.roundness = r_max - r_min;
        Ok(profile)
    }

    proptest! {
        #[test]
        fn the_profile_kernels_give_the_reference_bits(
            n in 8usize..400, amp in 0.0f64..3.0, noise in 0.0f64..0.5, seed in any::<u64>(),
            max_upr in 0usize..20
        ) {
            let mut rng = SimRng::new(seed);
            let kept: Vec<usize> = (0..n).filter(|_| rng.uniform() > 0.1).collect();
            let points: Vec<[f64; 2]> = kept
                .into_iter()
                .map(|i| {
                    let t = TAU * i as f64 / n as f64 + 0.01 * rng.normal();
                    let rr = 40.0 + amp * (3.0 * t).cos() + noise * rng.normal();
                    [3.0 + rr * t.cos(), -2.0 + rr * t.sin()]
                })
                .collect();
            prop_assume!(points.len() >= 8);
            let centre = [3.1, -1.9];
            let reference = reference_filtered_roundness(&points, centre, max_upr)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            let bits = |p: &RoundnessProfile| {
                let mut v = vec![p.mean_radius, p.roundness, p.residual_rms];
                v.extend(p.harmonics.iter().flat_map(|&(a, b)| [a, b]));
                v.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
            };
            let portable = filtered_roundness_kernel(&points, centre, max_upr);
            prop_assert_eq!(bits(&portable), bits(&reference));
            let dispatched = filtered_roundness(&points, centre, max_upr)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert_eq!(bits(&dispatched), bits(&reference));
        }
    }

    #[test]
    fn noise_is_averaged_not_accumulated() {
        let mut rng = SimRng::new(3);
        let points: Vec<[f64; 2]> = (0..720)
            .map(|i| {
                let t = TAU * i as f64 / 720.0;
                let rr = 50.0 + 0.1 * rng.normal();
                [rr * t.cos(), rr * t.sin()]
            })
            .collect();
        let raw = crate::perception::circle_fit::raw_roundness(&points, [0.0, 0.0]);
        let profile = filtered_roundness(&points, [0.0, 0.0], DEFAULT_MAX_UPR)
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(raw > 0.5, "raw {raw}");
        assert!(profile.roundness < 0.15, "filtered {}", profile.roundness);
        assert!((profile.noise_sigma() - 0.1).abs() < 0.02);
    }
}
