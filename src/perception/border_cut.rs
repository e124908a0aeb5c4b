//! Bores cut by the image border: recognised and skipped with a reason, never fitted as if
//! whole.
//!
//! Before border following the binary image gets a bright frame, so the dark region of a bore
//! that the border cuts becomes a hole whose border runs partly along the frame. Such a hole is a
//! cut bore when the rest of its border is a circular arc, dark inside and bright outside; the
//! belt beside a rim also touches the frame, but is bright inside its arc and dark outside.

use crate::perception::bore::{Bore, BoreDetectorParams};
use crate::perception::circle_fit::{distance, fit_kasa};
use crate::perception::contours::Contour;
use crate::perception::subpixel::sample_bilinear;
use image::GrayImage;
use std::f64::consts::TAU;

/// Why a dark region that looks like a bore was not measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SkipReason {
    /// The image border cuts the bore: fitting the visible arc as a whole circle would report a
    /// centre, radius and roundness nobody measured.
    CutByImageBorder,
}

impl SkipReason {
    /// A sentence for reports.
    pub fn describe(&self) -> &'static str {
        match self {
            Self::CutByImageBorder => "cut by the image border: partial bore, not measured",
        }
    }
}

/// A bore seen but not measured: where it roughly is and why it was skipped.
#[derive(Debug, Clone, PartialEq)]
pub struct SkippedBore {
    /// Centre of the circle through the visible arc (may lie outside the image).
    pub centre_px: [f64; 2],
    /// Radius of that circle.
    pub radius_px: f64,
    /// Share of that circle's circumference inside the image.
    pub visible_share: f64,
    /// Why it was skipped.
    pub reason: SkipReason,
}

/// Everything [`crate::perception::bore::BoreDetector::detect_report`] found in one image.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BoreReport {
    /// Measured bores, sorted by `y` then `x`.
    pub bores: Vec<Bore>,
    /// Bores seen but not measured, sorted by `y` then `x`.
    pub skipped: Vec<SkippedBore>,
}

/// Sets the outermost rows and columns of a binary image bright.
pub(crate) fn brighten_frame(binary: &mut GrayImage) {
    let w = binary.width() as usize;
    let raw: &mut [u8] = binary;
    let rows = raw.len() / w.max(1);
    for (y, row) in raw.chunks_exact_mut(w).enumerate() {
        if y == 0 || y + 1 == rows {
            row.fill(255);
        } else {
            row[0] = 255;
            row[w - 1] = 255;
        }
    }
}

/// A hole that runs along the image border: a bore cut by it when the rest of its border is
/// a circular arc with a dark inside and a bright outside.
pub(crate) fn cut_bore(
    p: &BoreDetectorParams,
    filtered: &GrayImage,
    contour: &Contour,
    on_frame: impl Fn(&[i32; 2]) -> bool,
) -> Option<SkippedBore> {
    let arc: Vec<[f64; 2]> = contour
        .points_px
        .iter()
        .filter(|q| !on_frame(q))
        .map(|q| [f64::from(q[0]), f64::from(q[1])])
        .collect();
    if (arc.len() as f64) < 0.25 * TAU * p.min_radius_px {
        return None;
    }
    let circle = fit_kasa(&arc).ok()?;
    if circle.radius < p.min_radius_px - 1.0
        || circle.radius > p.max_radius_px + 1.0
        || circle.rms_residual > 0.05 * circle.radius + 0.5
    {
        return None;
    }
    // Dark just inside the arc's middle, bright just outside: a bore, not the belt beside
    // a rim.
    let middle = arc[arc.len() / 2];
    let (dx, dy) = (middle[0] - circle.centre[0], middle[1] - circle.centre[1]);
    let d = distance(dx, dy).max(1e-9);
    let at = |f: f64| {
        let t = circle.radius * f / d;
        sample_bilinear(
            filtered,
            circle.centre[0] + t * dx,
            circle.centre[1] + t * dy,
        )
    };
    let (inside, outside) = (at(0.85), at(1.15));
    if outside - inside < p.min_contrast_levels || outside - inside < p.min_contrast_ratio * outside
    {
        return None;
    }
    let (wf, hf) = (f64::from(filtered.width()), f64::from(filtered.height()));
    let visible = (0..360)
        .filter(|&i| {
            let (s, c) = (TAU * f64::from(i) / 360.0).sin_cos();
            let (x, y) = (
                circle.centre[0] + circle.radius * c,
                circle.centre[1] + circle.radius * s,
            );
            x >= 0.0 && y >= 0.0 && x <= wf - 1.0 && y <= hf - 1.0
        })
        .count();
    Some(SkippedBore {
        centre_px: circle.centre,
        radius_px: circle.radius,
        visible_share: visible as f64 / 360.0,
        reason: SkipReason::CutByImageBorder,
    })
}
