//! A low-order radial series fitted robustly (iteratively reweighted least squares with
//! Tukey's biweight): the outline of a hole border and the check series of measured edges, both
//! of which an arc displaced by a stain or dirt must not pull.

use crate::perception::roundness::{median_of, series_along};

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
/// radii)`, the directions given as `[cos theta, sin theta]`, by iteratively reweighted least
/// squares with Tukey's biweight: points further than `TUKEY_C` robust scales from the series get no weight, so an arc of displaced points (up to
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
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the function only requires AVX2, which the CPU was just found to have.
        return unsafe { fit_series_robust_avx2(units, radii, order, scale_floor) };
    }
    fit_series_robust_kernel(units, radii, order, scale_floor)
}

/// [`fit_series_robust_kernel`] compiled for AVX2: the weighted sums run in wider lanes, with
/// the same IEEE operations in the same order (Rust never fuses a multiply and an add), so the
/// same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn fit_series_robust_avx2(
    units: &[[f64; 2]],
    radii: &[f64],
    order: usize,
    scale_floor: f64,
) -> Option<RobustSeries> {
    fit_series_robust_kernel(units, radii, order, scale_floor)
}

/// The body of [`fit_series_robust`], inlined into each instruction-set variant.
#[inline(always)]
fn fit_series_robust_kernel(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::roundness::{DEFAULT_MAX_UPR, filtered_roundness_bridged};

    #[test]
    fn both_builds_of_the_robust_fit_give_the_same_bits() {
        let mut rng = crate::rng::SimRng::new(11);
        for trial in 0..200 {
            let n = 10 + (rng.next_u64() % 300) as usize;
            let order = trial % (MAX_ROBUST_ORDER + 1);
            let (units, radii): (Vec<[f64; 2]>, Vec<f64>) = (0..n)
                .map(|i| {
                    let t = std::f64::consts::TAU * i as f64 / n as f64;
                    let outlier = if rng.uniform() < 0.2 {
                        rng.range(-5.0, 5.0)
                    } else {
                        0.0
                    };
                    let r = 30.0 + 0.7 * (2.0 * t).cos() + 0.05 * rng.normal() + outlier;
                    ([t.cos(), t.sin()], r)
                })
                .unzip();
            let fit = |series: Option<RobustSeries>| {
                series.map(|s| {
                    let mut v = vec![s.mean, s.scale];
                    v.extend(s.harmonics.iter().flat_map(|&(a, b)| [a, b]));
                    v.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
                })
            };
            assert_eq!(
                fit(fit_series_robust(&units, &radii, order, 0.01)),
                fit(fit_series_robust_kernel(&units, &radii, order, 0.01)),
                "trial {trial}"
            );
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
}
