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
fn series_along(mean: f64, harmonics: &[(f64, f64)], unit: [f64; 2]) -> f64 {
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

/// A low-order series `r(theta)` fitted robustly to radii that may include gross outliers: the
/// arcs of an edge hidden or displaced by a stain, a speck of dirt, a neighbour.
#[derive(Debug, Clone, PartialEq)]
pub struct RobustSeries {
    /// Constant term.
    pub mean: f64,
    /// `(a_k, b_k)` for `k = 1..=order`.
    pub harmonics: Vec<(f64, f64)>,
    /// Robust scale of the residuals (1.4826 times their median absolute value, at least the
    /// floor given to the fit).
    pub scale: f64,
}

impl RobustSeries {
    /// The series in direction `theta_rad`.
    pub fn radius_at(&self, theta_rad: f64) -> f64 {
        let (s, c) = theta_rad.sin_cos();
        self.radius_along([c, s])
    }

    /// The series in the direction `unit = [cos theta, sin theta]`.
    pub fn radius_along(&self, unit: [f64; 2]) -> f64 {
        series_along(self.mean, &self.harmonics, unit)
    }
}

/// Tuning constant of Tukey's biweight, in robust scales (95 % efficiency on Gaussian data).
const TUKEY_C: f64 = 4.685;

/// Highest order [`fit_series_robust`] fits.
pub const MAX_ROBUST_ORDER: usize = 4;

/// Parameters of a series of [`MAX_ROBUST_ORDER`].
const ROBUST_PARAMS: usize = 2 * MAX_ROBUST_ORDER + 1;

/// Fits `r(theta) = mean + sum_{k <= order} a_k cos k theta + b_k sin k theta` to `(units,
/// radii)`, the directions given as `[cos theta, sin theta]`, by iteratively reweighted least squares with Tukey's biweight: points further than
/// `TUKEY_C` robust scales from the series get no weight, so an arc of displaced points (up to
/// about a third of them) does not pull the series. Starts from the median radius, so the
/// outliers never enter an unweighted first fit. `scale_floor` bounds the robust scale from
/// below (the residuals of exact data would otherwise reject everything). `None` for an `order`
/// above [`MAX_ROBUST_ORDER`], with fewer than `2 order + 2` points or a singular system.
pub fn fit_series_robust(
    units: &[[f64; 2]],
    radii: &[f64],
    order: usize,
    scale_floor: f64,
) -> Option<RobustSeries> {
    let n = radii.len().min(units.len());
    let params = 2 * order + 1;
    if order > MAX_ROBUST_ORDER || n <= params {
        return None;
    }
    // cos m theta and sin m theta up to twice the order, for the normal equations (see
    // `harmonic_sums`), and the basis rows 1, cos theta, sin theta, ..., cos K theta, sin K theta
    // (zero-padded) taken from them.
    let doubled: Vec<HarmonicRow> = units[..n]
        .iter()
        .map(|&[c1, s1]| {
            let [mut cos_row, mut sin_row] = [[0.0; DOUBLE_HARMONICS]; 2];
            let (mut c, mut s) = (1.0f64, 0.0f64);
            cos_row[0] = 1.0;
            for (cos_m, sin_m) in cos_row
                .iter_mut()
                .zip(&mut sin_row)
                .take(2 * order + 1)
                .skip(1)
            {
                let c_next = c * c1 - s * s1;
                s = s * c1 + c * s1;
                c = c_next;
                *cos_m = c;
                *sin_m = s;
            }
            [cos_row, sin_row]
        })
        .collect();
    let basis: Vec<[f64; ROBUST_PARAMS]> = doubled
        .iter()
        .map(|[c, s]| {
            let mut row = [0.0; ROBUST_PARAMS];
            row[0] = 1.0;
            for k in 1..=order {
                row[2 * k - 1] = c[k];
                row[2 * k] = s[k];
            }
            row
        })
        .collect();
    let mut coefficients = [0.0; ROBUST_PARAMS];
    let mut work: Vec<f64> = radii[..n].to_vec();
    coefficients[0] = median_of(&mut work);
    let dot = |row: &[f64; ROBUST_PARAMS], c: &[f64; ROBUST_PARAMS]| -> f64 {
        row.iter().zip(c).map(|(a, b)| a * b).sum()
    };
    let mut residuals: Vec<f64> = basis
        .iter()
        .zip(radii)
        .map(|(row, r)| r - dot(row, &coefficients))
        .collect();
    let mut scale = scale_floor;
    for _ in 0..MAX_IRLS_ITERATIONS {
        work.clear();
        work.extend(residuals.iter().map(|r| r.abs()));
        scale = (1.4826 * median_of(&mut work)).max(scale_floor);
        let cutoff = TUKEY_C * scale;
        // The weighted sums of cos m theta and sin m theta give every entry of the normal
        // matrix (products of harmonics are sums of harmonics): 17 sums a point, lane by lane,
        // instead of 45 products.
        let mut sums = [[0.0; DOUBLE_HARMONICS]; 2];
        let mut rhs = [0.0; ROBUST_PARAMS];
        for ((row, doubled_row), (&residual, &r)) in
            basis.iter().zip(&doubled).zip(residuals.iter().zip(radii))
        {
            let u = residual / cutoff;
            if u.abs() >= 1.0 {
                continue;
            }
            let w = (1.0 - u * u).powi(2);
            for (sum_row, values) in sums.iter_mut().zip(doubled_row) {
                for (sum, &v) in sum_row.iter_mut().zip(values) {
                    *sum += w * v;
                }
            }
            let wr = w * r;
            for (h, &b) in rhs.iter_mut().zip(row) {
                *h += wr * b;
            }
        }
        // Unused orders get an identity block and a zero right-hand side: zero coefficients.
        let mut system = nalgebra::SMatrix::<f64, ROBUST_PARAMS, ROBUST_PARAMS>::identity();
        for a in 0..params {
            for b in 0..=a {
                let value = normal_entry(&sums, a, b);
                system[(a, b)] = value;
                system[(b, a)] = value;
            }
        }
        let solution = system
            .cholesky()?
            .solve(&nalgebra::SVector::<f64, ROBUST_PARAMS>::from(rhs));
        let next: [f64; ROBUST_PARAMS] = solution.into();
        let change = next
            .iter()
            .zip(&coefficients)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        coefficients = next;
        for ((res, row), &r) in residuals.iter_mut().zip(&basis).zip(radii) {
            *res = r - dot(row, &coefficients);
        }
        if change < 1e-3 * scale {
            break;
        }
    }
    Some(RobustSeries {
        mean: coefficients[0],
        harmonics: (0..order)
            .map(|k| (coefficients[1 + 2 * k], coefficients[2 + 2 * k]))
            .collect(),
        scale,
    })
}

/// Harmonics `m = 0..=2 MAX_ROBUST_ORDER` whose sums make up a robust fit's normal equations.
const DOUBLE_HARMONICS: usize = 2 * MAX_ROBUST_ORDER + 1;

/// `[cos m theta, sin m theta]` for `m < DOUBLE_HARMONICS` (zero past twice the fit's order).
type HarmonicRow = [[f64; DOUBLE_HARMONICS]; 2];

/// Entry `(a, b)` of the normal matrix of the basis `1, cos theta, sin theta, ..., cos K theta,
/// sin K theta` from the weighted sums `sums = [sum w cos m theta, sum w sin m theta]`, by
/// `cos j cos k = (cos (j-k) + cos (j+k)) / 2`, `sin j sin k = (cos (j-k) - cos (j+k)) / 2` and
/// `cos j sin k = (sin (j+k) + sin (k-j)) / 2`.
fn normal_entry(sums: &HarmonicRow, a: usize, b: usize) -> f64 {
    // Basis function `a` as (is a cosine, harmonic); the constant is cos 0 theta.
    let term = |a: usize| match a {
        0 => (true, 0),
        a if a % 2 == 1 => (true, a.div_ceil(2)),
        a => (false, a / 2),
    };
    let ((cos_a, j), (cos_b, k)) = (term(a), term(b));
    let [cos_sums, sin_sums] = sums;
    // sum w sin (to - from) theta.
    let sin_of_difference = |from: usize, to: usize| {
        if to >= from {
            sin_sums[to - from]
        } else {
            -sin_sums[from - to]
        }
    };
    let (difference, sum) = (j.abs_diff(k), j + k);
    0.5 * match (cos_a, cos_b) {
        (true, true) => cos_sums[difference] + cos_sums[sum],
        (false, false) => cos_sums[difference] - cos_sums[sum],
        (true, false) => sin_sums[sum] + sin_of_difference(j, k),
        (false, true) => sin_sums[sum] + sin_of_difference(k, j),
    }
}

/// Most reweighting rounds of [`fit_series_robust`]; it usually settles in five or six.
const MAX_IRLS_ITERATIONS: usize = 12;

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

    #[test]
    fn robust_series_ignores_a_displaced_arc() {
        // A 3-lobe profile with a 40 degree arc pushed 3 px outwards (an edge read on a stain).
        let (angles, radii): (Vec<f64>, Vec<f64>) = (0..360)
            .map(|i| {
                let t = f64::from(i).to_radians();
                let displaced = if (100..140).contains(&i) { 3.0 } else { 0.0 };
                (t, 50.0 + 0.8 * (3.0 * t + 0.4).cos() + displaced)
            })
            .unzip();
        let units: Vec<[f64; 2]> = angles.iter().map(|t| [t.cos(), t.sin()]).collect();
        let Some(series) = fit_series_robust(&units, &radii, 4, 0.01) else {
            panic!("no fit");
        };
        assert!((series.mean - 50.0).abs() < 1e-3, "{series:?}");
        let (a3, b3) = series.harmonics[2];
        assert!((a3.hypot(b3) - 0.8).abs() < 1e-3, "{series:?}");
        for (&t, &r) in angles.iter().zip(&radii).take(100) {
            assert!((series.radius_at(t) - r).abs() < 1e-3);
        }
        // Bridging the arc with the series restores the roundness of the clean profile.
        let point = |t: f64, r: f64| [r * t.cos(), r * t.sin()];
        let kept: Vec<[f64; 2]> = (0..360)
            .filter(|i| !(100..140).contains(i))
            .map(|i| point(angles[i], radii[i]))
            .collect();
        let bridges: Vec<[f64; 2]> = (100..140)
            .map(|i| point(angles[i], series.radius_at(angles[i])))
            .collect();
        let profile = filtered_roundness_bridged(&kept, &bridges, [0.0, 0.0], DEFAULT_MAX_UPR)
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(
            (profile.roundness - 1.6).abs() < 0.01,
            "{}",
            profile.roundness
        );
        assert_eq!(profile.point_count, kept.len());
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
