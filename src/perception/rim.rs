//! The rim around a bore candidate, read on rays walked outwards from the bore edge: its level,
//! its width and whether it is the flat face of a machined annulus.
//!
//! A tube's end face is a machined annulus of one reflectance from the bore edge out to its outer
//! edge, whatever the wall: ratios of the rim's outer diameter to the bore's from 1.15 to 3 and
//! more. Beyond it lies a belt (dark or mid-grey), a touching neighbour, a stain or the image
//! border. So the rim is not asked to close within any ratio. What it must be is flat: along a
//! ray, from just outside the edge to where the level falls to `bore + end_share (rim - bore)`
//! (its end), no sample may rise more than `max_rise_share` of the contrast above the rim's
//! level next to the edge. A standing bottle's dark cap sits in a translucent body whose level
//! climbs from the cap to its limb (and the cap's contrast is lower than a bore's): it fails.
//! The test is on shares of the local contrast, so smooth illumination and vignetting pass.
//!
//! The same walk measures the wall's width, which sets how far the edge refinement may reach
//! onto the rim ([`crate::perception::subpixel::RayParams::within_wall`]).

use crate::perception::ray_samples::sample_points;
use crate::perception::roundness::median_of;
use crate::perception::subpixel::sample_bilinear;
use image::GrayImage;
use std::f64::consts::TAU;

/// Parameters of [`scan_rim`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RimParams {
    /// Rays walked.
    pub rays: usize,
    /// Where the walk starts, pixels outside the bore edge.
    pub start_px: f64,
    /// Longest walk, as a ratio of the outer to the bore radius (past the widest rim measured).
    pub max_outer_ratio: f64,
    /// The rim ends where the level falls below `bore + end_share (rim - bore)`.
    pub end_share: f64,
    /// Largest rise above the rim's level next to the edge, as a share of the contrast, for a
    /// ray to count as flat.
    pub max_rise_share: f64,
}

impl Default for RimParams {
    fn default() -> Self {
        Self {
            rays: 32,
            start_px: 1.5,
            max_outer_ratio: 3.3,
            end_share: 0.6,
            max_rise_share: 0.3,
        }
    }
}

/// Steps of the rim walk sampled together.
const WALK_CHUNK: usize = 8;

/// What the walk found.
#[derive(Debug, Clone, PartialEq)]
pub struct RimScan {
    /// Median level down the bore, half way to its edge.
    pub bore_level: f64,
    /// Median level of the rim next to the edge.
    pub rim_level: f64,
    /// Spread of the rim's level next to the edge around the bore, about a linear light
    /// gradient and over its brighter half (see `spread_under_light`), as a share of the
    /// contrast: small for one machined face under smooth light, oiled or not, large for a dark
    /// disc between a bottle's body and the belt.
    pub rim_spread: f64,
    /// Share of the walked rays whose rim stayed flat.
    pub flat_share: f64,
    /// Median width of the rim over the rays where it ended inside the image (`None` when it
    /// ended on none: cut by the border or covering the frame).
    pub wall_px: Option<f64>,
    /// Median distance from the centre to where the rim ends, over the same rays, with the
    /// end interpolated between the walk's samples: the outer edge's radius.
    pub outer_radius_px: Option<f64>,
    /// The rim's outer edge on every ray where it ended inside the image: where the level falls
    /// half way from the rim's, a few pixels inside, to the belt's (or whatever lies beyond), a
    /// few pixels outside; image pixels. On a tilted camera part of these lie where the tube's
    /// side wall shows beyond the end face, not on the face's edge: the reader of the outer
    /// diameter keeps those it can trust ([`crate::perception::identify`]).
    pub outer_points_px: Vec<[f64; 2]>,
}

/// Walks `params.rays` rays from `centre`, each from `radius_at(unit)` (the coarse bore edge in
/// that direction) outwards. `None` when the candidate is too close to the image to sample.
pub fn scan_rim(
    filtered: &GrayImage,
    centre: [f64; 2],
    radius_at: impl Fn([f64; 2]) -> f64,
    params: &RimParams,
) -> Option<RimScan> {
    let (w, h) = (f64::from(filtered.width()), f64::from(filtered.height()));
    let inside = |x: f64, y: f64| x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0;
    let units: Vec<[f64; 2]> = (0..params.rays)
        .map(|i| {
            let (s, c) = (TAU * (i as f64 + 0.5) / params.rays as f64).sin_cos();
            [c, s]
        })
        .collect();
    let mut bore_levels = Vec::with_capacity(units.len());
    let mut rim_levels = Vec::with_capacity(units.len());
    let mut rim_units = Vec::with_capacity(units.len());
    for &[c, s] in &units {
        let r = radius_at([c, s]);
        let (bx, by) = (centre[0] + 0.5 * r * c, centre[1] + 0.5 * r * s);
        if inside(bx, by) {
            bore_levels.push(sample_bilinear(filtered, bx, by));
        }
        // The brightest of the first samples past the edge: on a wall of two pixels only those
        // reach the rim's level.
        let rim = (0..4)
            .map(|k| r + params.start_px + 0.5 * f64::from(k))
            .filter(|&t| inside(centre[0] + t * c, centre[1] + t * s))
            .map(|t| sample_bilinear(filtered, centre[0] + t * c, centre[1] + t * s))
            .fold(f64::NEG_INFINITY, f64::max);
        if rim.is_finite() {
            rim_levels.push(rim);
            rim_units.push([c, s]);
        }
    }
    if bore_levels.len() < units.len() / 2 || rim_levels.len() < units.len() / 2 {
        return None;
    }
    let bore_level = median_of(&mut bore_levels);
    let rim_level = median_of(&mut rim_levels.clone());
    let contrast = rim_level - bore_level;
    let rim_spread = spread_under_light(&rim_units, &rim_levels, contrast);
    let end_level = bore_level + params.end_share * contrast;
    let mut flat = 0usize;
    let mut walked = 0usize;
    let mut walls = Vec::with_capacity(units.len());
    let mut outer_radii = Vec::with_capacity(units.len());
    let mut outer_points = Vec::with_capacity(units.len());
    for &[c, s] in &units {
        let r = radius_at([c, s]);
        let limit = params.max_outer_ratio * r + 2.0;
        let mut t = r + params.start_px;
        let mut near = f64::NEG_INFINITY;
        let mut highest = f64::NEG_INFINITY;
        let mut ended = None;
        let mut previous = f64::NAN;
        // The walk's positions a chunk at a time (to its limit or the image border), sampled
        // together, then read in order: a chunk reads at most a few samples past the end.
        let [mut xs, mut ys, mut ts, mut levels] = [[0.0; WALK_CHUNK]; 4];
        'walk: loop {
            let mut n = 0;
            let mut stopped = false;
            while n < WALK_CHUNK {
                let within = t <= limit;
                let (x, y) = (centre[0] + t * c, centre[1] + t * s);
                if !within || !inside(x, y) {
                    stopped = true;
                    break;
                }
                (xs[n], ys[n], ts[n]) = (x, y, t);
                n += 1;
                t += 1.0;
            }
            sample_points(filtered, &xs[..n], &ys[..n], &mut levels[..n]);
            for (&level, &t) in levels.iter().zip(&ts).take(n) {
                if level < end_level {
                    ended = Some(t);
                    // Where the level crossed the end level between the last two samples.
                    let crossing = if previous > level {
                        t - ((end_level - level) / (previous - level)).clamp(0.0, 1.0)
                    } else {
                        t
                    };
                    outer_radii.push(crossing);
                    let inner = (crossing - OUTER_FLANK_PX).max(r + params.start_px);
                    let t_edge = half_level_crossing(filtered, centre, [c, s], inner, crossing)
                        .unwrap_or(crossing);
                    outer_points.push([centre[0] + t_edge * c, centre[1] + t_edge * s]);
                    break 'walk;
                }
                previous = level;
                if t < r + params.start_px + 2.0 {
                    near = near.max(level);
                }
                highest = highest.max(level);
            }
            if stopped {
                break;
            }
        }
        if !near.is_finite() {
            continue;
        }
        walked += 1;
        if highest - near <= params.max_rise_share * contrast {
            flat += 1;
        }
        if let Some(end) = ended {
            walls.push(end - r);
        }
    }
    if walked == 0 {
        return None;
    }
    let median = |v: &mut Vec<f64>| (!v.is_empty()).then(|| median_of(v));
    Some(RimScan {
        bore_level,
        rim_level,
        rim_spread,
        flat_share: flat as f64 / walked as f64,
        wall_px: median(&mut walls),
        outer_radius_px: median(&mut outer_radii),
        outer_points_px: outer_points,
    })
}

/// How far either side of the walk's end the outer edge's levels are read, px.
const OUTER_FLANK_PX: f64 = 3.0;
/// Step of the outer edge's search, px.
const OUTER_STEP_PX: f64 = 0.25;

/// Where the level along the ray from `centre` along `unit` first falls below half way between
/// its values at `inner` (on the rim) and `OUTER_FLANK_PX` past `end` (beyond the rim), linearly
/// interpolated between samples; `None` when the outside lies off the image or the two levels
/// hardly differ.
fn half_level_crossing(
    image: &GrayImage,
    centre: [f64; 2],
    unit: [f64; 2],
    inner: f64,
    end: f64,
) -> Option<f64> {
    let (w, h) = (f64::from(image.width()), f64::from(image.height()));
    let at = |t: f64| {
        let (x, y) = (centre[0] + t * unit[0], centre[1] + t * unit[1]);
        (x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0).then(|| sample_bilinear(image, x, y))
    };
    let outer = end + OUTER_FLANK_PX;
    let (rim, beyond) = (at(inner)?, at(outer)?);
    if rim - beyond < 8.0 {
        return None;
    }
    let half = 0.5 * (rim + beyond);
    let mut previous = (inner, rim);
    let mut t = inner + OUTER_STEP_PX;
    while t <= outer {
        let level = at(t)?;
        if level < half {
            let (t0, l0) = previous;
            let share = ((l0 - half) / (l0 - level)).clamp(0.0, 1.0);
            return Some(t0 + share * (t - t0));
        }
        previous = (t, level);
        t += OUTER_STEP_PX;
    }
    None
}

/// Spread of the rim's `levels` on rays along `units` about a first harmonic `a + b cos + c
/// sin` (a linear light gradient across the rim), the brighter half only (90th minus 50th
/// percentile of the residuals), as a share of `contrast`.
///
/// Oil only darkens, and may lie on a third of the rim and more: the harmonic is fitted to the
/// rays that stay within a tenth of the contrast below it, three times over.
fn spread_under_light(units: &[[f64; 2]], levels: &[f64], contrast: f64) -> f64 {
    let contrast = contrast.max(1.0);
    let mut kept = vec![true; levels.len()];
    let mut residuals = levels.to_vec();
    for _ in 0..3 {
        let Some(fit) = fit_first_harmonic(units, levels, &kept) else {
            break;
        };
        for ((r, &level), &[c, s]) in residuals.iter_mut().zip(levels).zip(units) {
            *r = level - (fit[0] + fit[1] * c + fit[2] * s);
        }
        for (k, &r) in kept.iter_mut().zip(&residuals) {
            *k = r >= -0.1 * contrast;
        }
    }
    residuals.sort_by(f64::total_cmp);
    let percentile = |q: f64| residuals[((residuals.len() - 1) as f64 * q).round() as usize];
    (percentile(0.9) - percentile(0.5)) / contrast
}

/// Least-squares `[a, b, c]` of `level = a + b cos + c sin` over the `kept` rays; `None` when
/// fewer than 8 are kept or they do not pin the harmonic down.
fn fit_first_harmonic(units: &[[f64; 2]], levels: &[f64], kept: &[bool]) -> Option<[f64; 3]> {
    let mut normal = nalgebra::Matrix3::<f64>::zeros();
    let mut rhs = nalgebra::Vector3::<f64>::zeros();
    let mut n = 0;
    for ((&[c, s], &level), _) in units.iter().zip(levels).zip(kept).filter(|(_, k)| **k) {
        let row = nalgebra::Vector3::new(1.0, c, s);
        normal += row * row.transpose();
        rhs += row * level;
        n += 1;
    }
    if n < 8 {
        return None;
    }
    let solution = normal.cholesky()?.solve(&rhs);
    Some([solution[0], solution[1], solution[2]])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::synthetic::{BoreShape, Bottle, Illumination, Noise, Scene, Tube};

    fn scene(tubes: Vec<Tube>, bottles: Vec<Bottle>, belt_level: f64) -> GrayImage {
        Scene {
            width_px: 320,
            height_px: 240,
            belt_level,
            tubes,
            bottles,
            stains: vec![],
            rim_stains: vec![],
            illumination: Illumination {
                gradient_x: 0.3,
                gradient_y: -0.2,
                vignetting: 0.2,
            },
            noise: Noise::NONE,
            noise_seed: 0,
        }
        .render()
    }

    fn tube(r: f64, ratio: f64) -> Tube {
        Tube {
            centre_px: [160.0, 120.0],
            bore: BoreShape::Circle { radius_px: r },
            outer_radius_px: ratio * r,
            rim_level: 190.0,
            bore_level: 20.0,
        }
    }

    #[test]
    fn thick_and_thin_walls_on_dark_and_grey_belts_are_flat_and_measured() {
        for (r, ratio) in [(12.0, 1.3), (20.0, 3.0), (30.0, 1.15), (35.0, 2.5)] {
            for belt in [40.0, 110.0] {
                let image = scene(vec![tube(r, ratio)], vec![], belt);
                let Some(scan) = scan_rim(&image, [160.0, 120.0], |_| r, &RimParams::default())
                else {
                    panic!("no scan");
                };
                assert!(scan.flat_share > 0.95, "r {r} ratio {ratio}: {scan:?}");
                assert!(scan.rim_spread < 0.2, "r {r} ratio {ratio}: {scan:?}");
                let Some(wall) = scan.wall_px else {
                    panic!("r {r} ratio {ratio} belt {belt}: the rim never ended: {scan:?}");
                };
                let true_wall = (ratio - 1.0) * r;
                assert!((wall - true_wall).abs() < 2.0, "wall {wall} vs {true_wall}");
            }
        }
    }

    #[test]
    fn a_dark_cap_in_a_bottle_body_is_not_a_flat_rim() {
        for cap_level in [30.0, 40.0, 50.0, 60.0] {
            let bottle = Bottle::Standing {
                centre_px: [160.0, 120.0],
                body_radius_px: 70.0,
                cap_radius_px: 22.0,
                cap_level,
            };
            let image = scene(vec![], vec![bottle], 45.0);
            let Some(scan) = scan_rim(&image, [160.0, 120.0], |_| 22.0, &RimParams::default())
            else {
                panic!("no scan");
            };
            assert!(scan.flat_share < 0.5, "cap {cap_level}: {scan:?}");
        }
    }
}
