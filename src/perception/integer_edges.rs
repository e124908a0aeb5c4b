//! The seed paper's classic way of fitting a bore, kept for `measure --compare`: integer edge
//! pixels (hole-border pixels, or Canny pixels near the coarse outline), a geometric circle and
//! eq. 11 on the raw points.

use crate::perception::circle_fit::{CircleFit, fit_geometric};
use crate::perception::roundness::{RoundnessProfile, filtered_roundness};
use image::GrayImage;
use std::f64::consts::TAU;

/// The classic fit on integer points: geometric circle, profile only for the noise estimate.
pub(crate) fn integer_fit(
    points: Vec<[f64; 2]>,
    max_upr: usize,
) -> Option<(Vec<[f64; 2]>, CircleFit, RoundnessProfile)> {
    let fit = fit_geometric(&points).ok()?;
    let profile = filtered_roundness(&points, fit.centre, max_upr).ok()?;
    Some((points, fit, profile))
}

/// Canny edge pixels within 2.5 px of the coarse outline.
pub(crate) fn canny_points(
    edge_map: &GrayImage,
    centre: [f64; 2],
    coarse_radii: &[f64],
) -> Vec<[f64; 2]> {
    let bins = coarse_radii.len();
    let r_max = coarse_radii.iter().copied().fold(0.0, f64::max) + 3.0;
    let (w, h) = (edge_map.width() as i64, edge_map.height() as i64);
    let x0 = ((centre[0] - r_max).floor() as i64).max(0);
    let x1 = ((centre[0] + r_max).ceil() as i64).min(w - 1);
    let y0 = ((centre[1] - r_max).floor() as i64).max(0);
    let y1 = ((centre[1] + r_max).ceil() as i64).min(h - 1);
    let mut points = Vec::new();
    for y in y0..=y1 {
        for x in x0..=x1 {
            if edge_map.as_raw()[(y * w + x) as usize] == 0 {
                continue;
            }
            let (dx, dy) = (x as f64 - centre[0], y as f64 - centre[1]);
            let bin = ((dy.atan2(dx).rem_euclid(TAU) / TAU * bins as f64).round() as usize) % bins;
            if (dx.hypot(dy) - coarse_radii[bin]).abs() <= 2.5 {
                points.push([x as f64, y as f64]);
            }
        }
    }
    points
}
