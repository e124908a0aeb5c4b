//! Least-squares circle fits (seed paper section 2.5): algebraic (Kasa, Pratt) for a start,
//! then geometric (Gauss-Newton on the orthogonal distances) for the result.
//!
//! Units are those of the points (pixels in the image, metres on the end-face plane).

use crate::perception::error::PerceptionError;
use nalgebra::{Matrix3, Vector3};

/// A fitted circle, in the units of the points it was fitted to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleFit {
    /// Centre `[x, y]`.
    pub centre: [f64; 2],
    /// Radius.
    pub radius: f64,
    /// Root mean square of the geometric residuals `|p - c| - r`.
    pub rms_residual: f64,
    /// Number of points fitted.
    pub point_count: usize,
}

/// `sqrt(dx^2 + dy^2)`: within an ulp of `f64::hypot` for the magnitudes of image and end-face
/// coordinates (no overflow or underflow to guard against) and several times cheaper than libm's
/// `hypot`, which these fits call for every point on every iteration.
#[inline]
pub(crate) fn distance(dx: f64, dy: f64) -> f64 {
    (dx * dx + dy * dy).sqrt()
}

/// Centroid and points shifted to it (conditioning for the algebraic fits).
fn centred(points: &[[f64; 2]]) -> Result<([f64; 2], Vec<[f64; 2]>), PerceptionError> {
    if points.len() < 3 {
        return Err(PerceptionError::DegenerateFit {
            point_count: points.len(),
        });
    }
    let n = points.len() as f64;
    let mean = [
        points.iter().map(|p| p[0]).sum::<f64>() / n,
        points.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    Ok((
        mean,
        points
            .iter()
            .map(|p| [p[0] - mean[0], p[1] - mean[1]])
            .collect(),
    ))
}

fn finish(
    points: &[[f64; 2]],
    centre: [f64; 2],
    radius: f64,
) -> Result<CircleFit, PerceptionError> {
    if !(centre[0].is_finite() && centre[1].is_finite() && radius.is_finite() && radius > 0.0) {
        return Err(PerceptionError::DegenerateFit {
            point_count: points.len(),
        });
    }
    let sum_sq: f64 = points
        .iter()
        .map(|p| (distance(p[0] - centre[0], p[1] - centre[1]) - radius).powi(2))
        .sum();
    Ok(CircleFit {
        centre,
        radius,
        rms_residual: (sum_sq / points.len() as f64).sqrt(),
        point_count: points.len(),
    })
}

/// Kasa's algebraic fit: minimises `sum (x^2 + y^2 + D x + E y + F)^2`. Fast, biased towards
/// smaller circles on short arcs.
pub fn fit_kasa(points: &[[f64; 2]]) -> Result<CircleFit, PerceptionError> {
    let (mean, q) = centred(points)?;
    let mut normal = Matrix3::<f64>::zeros();
    let mut rhs = Vector3::<f64>::zeros();
    for p in &q {
        let row = Vector3::new(p[0], p[1], 1.0);
        let z = p[0] * p[0] + p[1] * p[1];
        normal += row * row.transpose();
        rhs -= row * z;
    }
    let Some(solution) = normal.lu().solve(&rhs) else {
        return Err(PerceptionError::DegenerateFit {
            point_count: points.len(),
        });
    };
    let (a, b) = (-solution[0] / 2.0, -solution[1] / 2.0);
    let radius = (a * a + b * b - solution[2]).sqrt();
    finish(points, [a + mean[0], b + mean[1]], radius)
}

/// Pratt's algebraic fit (Chernov's Newton solution of its characteristic polynomial): nearly
/// unbiased, a better start than Kasa on partial arcs.
pub fn fit_pratt(points: &[[f64; 2]]) -> Result<CircleFit, PerceptionError> {
    let (mean, q) = centred(points)?;
    let n = q.len() as f64;
    let (mut mxx, mut myy, mut mxy, mut mxz, mut myz, mut mzz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for p in &q {
        let (x, y) = (p[0], p[1]);
        let z = x * x + y * y;
        mxx += x * x;
        myy += y * y;
        mxy += x * y;
        mxz += x * z;
        myz += y * z;
        mzz += z * z;
    }
    let (mxx, myy, mxy, mxz, myz, mzz) = (mxx / n, myy / n, mxy / n, mxz / n, myz / n, mzz / n);
    let mz = mxx + myy;
    let cov_xy = mxx * myy - mxy * mxy;
    let a2 = 4.0 * cov_xy - 3.0 * mz * mz - mzz;
    let a1 = mzz * mz + 4.0 * cov_xy * mz - mxz * mxz - myz * myz - mz * mz * mz;
    let a0 =
        mxz * mxz * myy + myz * myz * mxx - mzz * cov_xy - 2.0 * mxz * myz * mxy + mz * mz * cov_xy;
    let mut x = 0.0f64;
    let mut y = f64::INFINITY;
    for _ in 0..30 {
        let y_new = a0 + x * (a1 + x * (a2 + 4.0 * x * x));
        if y_new.abs() > y.abs() {
            x = 0.0;
            break;
        }
        y = y_new;
        let dy = a1 + x * (2.0 * a2 + 16.0 * x * x);
        let x_new = x - y / dy;
        if !x_new.is_finite() || x_new < 0.0 {
            x = 0.0;
            break;
        }
        let converged = (x_new - x).abs() <= 1e-14 * x_new.abs().max(1e-300);
        x = x_new;
        if converged {
            break;
        }
    }
    let det = x * x - x * mz + cov_xy;
    let cx = (mxz * (myy - x) - myz * mxy) / det / 2.0;
    let cy = (myz * (mxx - x) - mxz * mxy) / det / 2.0;
    let radius = (cx * cx + cy * cy + mz + 2.0 * x).sqrt();
    finish(points, [cx + mean[0], cy + mean[1]], radius)
}

/// Geometric fit: Gauss-Newton on `sum (|p - c| - r)^2`, started from Pratt's fit.
pub fn fit_geometric(points: &[[f64; 2]]) -> Result<CircleFit, PerceptionError> {
    let start = fit_pratt(points).or_else(|_| fit_kasa(points))?;
    refine_geometric(points, start)
}

/// Gauss-Newton refinement of a circle on `sum (|p - c| - r)^2` from `start`.
pub fn refine_geometric(
    points: &[[f64; 2]],
    start: CircleFit,
) -> Result<CircleFit, PerceptionError> {
    let [mut a, mut b] = start.centre;
    let mut r = start.radius;
    for _ in 0..50 {
        // The six distinct entries of the symmetric normal matrix, each the same sum of the same
        // products as the full outer product would give it.
        let [mut s00, mut s01, mut s02, mut s11, mut s12, mut s22] = [0.0f64; 6];
        let [mut g0, mut g1, mut g2] = [0.0f64; 3];
        for p in points {
            let (dx, dy) = (p[0] - a, p[1] - b);
            let d = distance(dx, dy);
            if d <= f64::EPSILON {
                continue;
            }
            let (r0, r1, r2) = (-dx / d, -dy / d, -1.0);
            let residual = d - r;
            s00 += r0 * r0;
            s01 += r0 * r1;
            s02 += r0 * r2;
            s11 += r1 * r1;
            s12 += r1 * r2;
            s22 += r2 * r2;
            g0 += r0 * residual;
            g1 += r1 * residual;
            g2 += r2 * residual;
        }
        let jtj = Matrix3::new(s00, s01, s02, s01, s11, s12, s02, s12, s22);
        let jtr = Vector3::new(g0, g1, g2);
        if gauss_newton_step(&jtj, &jtr, &mut [&mut a, &mut b, &mut r], points.len())? {
            break;
        }
    }
    finish(points, [a, b], r)
}

/// A gap between neighbouring points (by angle about the centre) counts in their weights up to
/// this many times the median gap: an arc without points (hidden, or its edges rejected) weighs
/// the points at its ends at most 1.5 times an evenly spaced point, not by its length.
pub const MAX_GAP_SHARE: f64 = 2.0;

/// Geometric fit over the revolution: each point weighted by its share of the angle about the
/// centre, so that the circle is the least-squares circle of the profile `r(theta)` integrated
/// over the angle (ISO 12181's reference circle), whatever the points' angular density.
///
/// Edge points found on rays spread evenly in an image lie unevenly on the end-face plane of a
/// tilted camera (denser where the plane is foreshortened): unweighted, the denser arcs pull the
/// centre, and a lobed bore's harmonics, seen through that density, move it by a few per cent
/// of the lobes' height (0.035 mm for a 3-lobe bore 0.86 mm out of round, seen at 30°): the
/// roundness about that centre reads it as out of round. Started from [`fit_geometric`]; the weights are worked out again about
/// each new centre.
pub fn fit_geometric_over_angle(points: &[[f64; 2]]) -> Result<CircleFit, PerceptionError> {
    let mut fit = fit_geometric(points)?;
    for _ in 0..3 {
        let weights = angular_shares(points, fit.centre);
        let next = refine_weighted(points, &weights, fit)?;
        let moved = distance(
            next.centre[0] - fit.centre[0],
            next.centre[1] - fit.centre[1],
        );
        fit = next;
        if moved <= 1e-9 * fit.radius {
            break;
        }
    }
    Ok(fit)
}

/// Each point's share of the angle about `centre`: half the angles to its neighbours either side
/// (by angle), each gap capped at [`MAX_GAP_SHARE`] times the median gap; scaled to a mean of 1.
pub fn angular_shares(points: &[[f64; 2]], centre: [f64; 2]) -> Vec<f64> {
    let n = points.len();
    if n < 3 {
        return vec![1.0; n];
    }
    let angles: Vec<f64> = points
        .iter()
        .map(|p| (p[1] - centre[1]).atan2(p[0] - centre[0]))
        .collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| angles[i].total_cmp(&angles[j]));
    // gaps[k]: from the k-th point by angle to the next, wrapping round.
    let mut gaps: Vec<f64> = (0..n)
        .map(|k| {
            let (a, b) = (angles[order[k]], angles[order[(k + 1) % n]]);
            if k + 1 == n {
                b + std::f64::consts::TAU - a
            } else {
                b - a
            }
        })
        .collect();
    let mut sorted = gaps.clone();
    let mid = n / 2;
    let (_, median, _) = sorted.select_nth_unstable_by(mid, f64::total_cmp);
    let cap = MAX_GAP_SHARE * *median;
    for gap in &mut gaps {
        *gap = gap.min(cap);
    }
    let mut shares = vec![0.0; n];
    for k in 0..n {
        shares[order[k]] = 0.5 * (gaps[(k + n - 1) % n] + gaps[k]);
    }
    let mean = shares.iter().sum::<f64>() / n as f64;
    if mean > 0.0 {
        for share in &mut shares {
            *share /= mean;
        }
    }
    shares
}

/// Gauss-Newton refinement of a circle on `sum w (|p - c| - r)^2` from `start`.
fn refine_weighted(
    points: &[[f64; 2]],
    weights: &[f64],
    start: CircleFit,
) -> Result<CircleFit, PerceptionError> {
    let [mut a, mut b] = start.centre;
    let mut r = start.radius;
    for _ in 0..50 {
        let mut jtj = Matrix3::<f64>::zeros();
        let mut jtr = Vector3::<f64>::zeros();
        for (p, &w) in points.iter().zip(weights) {
            let (dx, dy) = (p[0] - a, p[1] - b);
            let d = distance(dx, dy);
            if d <= f64::EPSILON {
                continue;
            }
            let row = Vector3::new(-dx / d, -dy / d, -1.0);
            jtj += row * row.transpose() * w;
            jtr += row * (w * (d - r));
        }
        if gauss_newton_step(&jtj, &jtr, &mut [&mut a, &mut b, &mut r], points.len())? {
            break;
        }
    }
    finish(points, [a, b], r)
}

/// One Gauss-Newton step of a circle fit: solves `jtj * step = -jtr` and adds the step to
/// `[a, b, r]`; whether the step was small enough to stop. `point_count` names a degenerate fit.
fn gauss_newton_step(
    jtj: &Matrix3<f64>,
    jtr: &Vector3<f64>,
    params: &mut [&mut f64; 3],
    point_count: usize,
) -> Result<bool, PerceptionError> {
    let Some(step) = jtj.lu().solve(&(-jtr)) else {
        return Err(PerceptionError::DegenerateFit { point_count });
    };
    for (p, d) in params.iter_mut().zip(step.iter()) {
        **p += d;
    }
    Ok(step.norm() <= 1e-12 * params[2].abs().max(1.0))
}

/// Roundness by eq. 11: `Rmax - Rmin` of the points' distances from `centre`.
pub fn raw_roundness(points: &[[f64; 2]], centre: [f64; 2]) -> f64 {
    let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in points {
        let d = distance(p[0] - centre[0], p[1] - centre[1]);
        min = min.min(d);
        max = max.max(d);
    }
    if min.is_finite() { max - min } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;
    use proptest::prelude::*;

    fn noisy_circle(
        cx: f64,
        cy: f64,
        r: f64,
        n: usize,
        sigma: f64,
        arc: f64,
        seed: u64,
    ) -> Vec<[f64; 2]> {
        let mut rng = SimRng::new(seed);
        (0..n)
            .map(|i| {
                let t = arc * i as f64 / n as f64;
                let rr = r + sigma * rng.normal();
                [cx + rr * t.cos(), cy + rr * t.sin()]
            })
            .collect()
    }

    proptest! {
        #[test]
        fn every_fit_recovers_an_exact_circle(
            cx in -500.0f64..500.0, cy in -500.0f64..500.0, r in 1.0f64..300.0, n in 5usize..200
        ) {
            let points = noisy_circle(cx, cy, r, n, 0.0, std::f64::consts::TAU, 1);
            for fit in [fit_kasa(&points), fit_pratt(&points), fit_geometric(&points)] {
                let fit = fit.map_err(|e| TestCaseError::fail(e.to_string()))?;
                prop_assert!((fit.centre[0] - cx).abs() < 1e-6 * r.max(1.0));
                prop_assert!((fit.centre[1] - cy).abs() < 1e-6 * r.max(1.0));
                prop_assert!((fit.radius - r).abs() < 1e-6 * r.max(1.0));
            }
        }

        #[test]
        fn geometric_fit_recovers_a_noisy_circle(
            cx in 0.0f64..640.0, cy in 0.0f64..480.0, r in 15.0f64..150.0, seed in any::<u64>()
        ) {
            let sigma = 0.2;
            let n = 400;
            let fit = fit_geometric(&noisy_circle(cx, cy, r, n, sigma, std::f64::consts::TAU, seed))
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            // Five standard errors of the centre (sigma * sqrt(2 / n)) and the radius.
            let tol = 5.0 * sigma * (2.0 / n as f64).sqrt();
            prop_assert!((fit.centre[0] - cx).abs() < tol);
            prop_assert!((fit.centre[1] - cy).abs() < tol);
            prop_assert!((fit.radius - r).abs() < tol);
            prop_assert!((fit.rms_residual - sigma).abs() < 0.3 * sigma);
        }

        #[test]
        fn pratt_and_geometric_beat_kasa_on_a_half_arc(seed in any::<u64>()) {
            let points = noisy_circle(0.0, 0.0, 50.0, 200, 1.0, std::f64::consts::PI, seed);
            let geometric = fit_geometric(&points).map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert!((geometric.radius - 50.0).abs() < 1.0);
        }
    }

    /// Gauss-Newton as first written, with full outer products: the reference for the bits.
    fn reference_refine(points: &[[f64; 2]], start: CircleFit) -> [f64; 3] {
        let [mut a, mut b] = start.centre;
        let mut r = start.radius;
        for _ in 0..50 {
            let mut jtj = Matrix3::<f64>::zeros();
            let mut jtr = Vector3::<f64>::zeros();
            for p in points {
                let (dx, dy) = (p[0] - a, p[1] - b);
                let d = distance(dx, dy);
                if d <= f64::EPSILON {
                    continue;
                }
                let row = Vector3::new(-dx / d, -dy / d, -1.0);
                jtj += row * row.transpose();
                jtr += row * (d - r);
            }
            let Some(step) = jtj.lu().solve(&(-jtr)) else {
                return [f64::NAN; 3];
            };
            a += step[0];
            b += step[1];
            r += step[2];
            if step.norm() <= 1e-12 * r.abs().max(1.0) {
                break;
            }
        }
        [a, b, r]
    }

    proptest! {
        #[test]
        fn geometric_refinement_has_the_reference_bits(
            r in 5.0f64..200.0, n in 8usize..500, arc in 1.0f64..6.3, seed in any::<u64>()
        ) {
            let points = noisy_circle(3.5, -7.25, r, n, 0.3, arc, seed);
            let start = fit_pratt(&points).map_err(|e| TestCaseError::fail(e.to_string()))?;
            let fit = refine_geometric(&points, start)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            let bits = |v: [f64; 3]| v.map(f64::to_bits);
            prop_assert_eq!(
                bits([fit.centre[0], fit.centre[1], fit.radius]),
                bits(reference_refine(&points, start))
            );
        }
    }

    proptest! {
        #[test]
        fn the_fit_over_the_angle_ignores_how_densely_the_points_lie(
            r in 5.0f64..200.0, amp in 0.0f64..0.05, lobes in 2u32..4, phase in 0.0f64..6.3,
            density in 0.0f64..0.25, skew in 0.0f64..0.15,
            hidden in prop_oneof![Just(0.0f64), 0.01f64..1.5], seed in any::<u64>()
        ) {
            // A lobed profile about (3, -2), its points denser on some arcs (as rays spread
            // evenly in a tilted image lie on the end-face plane: a second and a first harmonic
            // of density, up to 40 % together: a 35-degree tilt gives about 22 %) and either no
            // arc without points or one of 0.01-1.5 rad. Beyond that, gaps pass the fit's cap
            // of twice the median and the whole revolution's centre moves by more than a
            // thousandth of the lobes (0.001 mm at 50 % on a 5 mm bore); a gap about one point
            // spacing wide, 0.005-0.01 rad, is neither a whole revolution nor a hidden arc.
            let mut rng = SimRng::new(seed);
            let n = 720;
            let start = rng.range(0.0, std::f64::consts::TAU);
            let mut points = Vec::new();
            let mut t = 0.0f64;
            while t < std::f64::consts::TAU {
                let profile = r * (1.0 + amp * (f64::from(lobes) * (t - phase)).cos());
                if (t - start).rem_euclid(std::f64::consts::TAU) > hidden {
                    points.push([3.0 + profile * t.cos(), -2.0 + profile * t.sin()]);
                }
                let rho = 1.0 + density * (2.0 * t).cos() + skew * (t + 1.0).cos();
                t += std::f64::consts::TAU / n as f64 / rho;
            }
            let fit = fit_geometric_over_angle(&points)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            // Over the whole revolution the reference circle of a lobed profile is centred on
            // its centre; with an arc hidden, the lobes move it by less than their height.
            let tol = if hidden > 0.01 { amp * r + 1e-9 * r } else { 1e-3 * amp * r + 1e-9 * r };
            prop_assert!((fit.centre[0] - 3.0).hypot(fit.centre[1] + 2.0) <= tol,
                "centre {:?} tol {}", fit.centre, tol);
            prop_assert!((fit.radius - r).abs() <= tol + 1e-3 * amp * r);
        }
    }

    #[test]
    fn the_unweighted_fit_follows_the_denser_arcs() {
        // Three lobes, points twice as dense about 0 and pi as about +-pi/2: the plain fit's
        // centre moves by a share of the lobes' height; the fit over the angle's does not.
        let (r, amp) = (100.0, 1.0);
        let mut points = Vec::new();
        let mut t = 0.0f64;
        while t < std::f64::consts::TAU {
            let profile = r + amp * (3.0 * t).cos();
            points.push([profile * t.cos(), profile * t.sin()]);
            t += std::f64::consts::TAU / 720.0 / (1.0 + 0.3 * (2.0 * t).cos());
        }
        let offset = |fit: CircleFit| fit.centre[0].hypot(fit.centre[1]);
        let plain = fit_geometric(&points).unwrap_or_else(|e| panic!("{e}"));
        let even = fit_geometric_over_angle(&points).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            offset(plain) > 0.1 * amp,
            "plain centre off by {}",
            offset(plain)
        );
        assert!(
            offset(even) < 0.01 * amp,
            "centre over the angle off by {}",
            offset(even)
        );
    }

    #[test]
    fn too_few_or_collinear_points_are_errors() {
        assert!(fit_kasa(&[[0.0, 0.0], [1.0, 1.0]]).is_err());
        assert!(fit_geometric(&[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]).is_err());
    }

    #[test]
    fn raw_roundness_of_a_square_is_the_diagonal_excess() {
        let square = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 1.0]];
        assert!((raw_roundness(&square, [0.0, 0.0]) - (2f64.sqrt() - 1.0)).abs() < 1e-12);
    }
}
