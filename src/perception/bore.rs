//! The bore detector: every dark bore inside a bright rim, measured to sub-pixel accuracy.
//!
//! Pipeline: filter (3x3 median) -> threshold (adaptive mean, asking pixels to be brighter than
//! their block) -> border following -> for each hole border (a dark region fully enclosed by
//! bright pixels), and then for each hole border of a second segmentation (a share of the local
//! maximum, [`crate::perception::max_threshold`]) away from the bores already found: coarse Kasa
//! circle -> rays from the coarse centre, sub-pixel edges
//! ([`crate::perception::subpixel`]) -> acceptance tests -> geometric circle fit with one round of
//! outlier rejection -> filtered roundness ([`crate::perception::roundness`]).
//!
//! Acceptance tests, each on the rays' own intensity profiles (so they are local and immune to
//! illumination gradients and vignetting):
//! 1. Size: the coarse radius lies in `[min_radius_px, max_radius_px]` and the hole border is
//!    roughly circular (coarse RMS residual under a fifth of the radius).
//! 2. Edges: at least `min_valid_share` of the rays show a dark-to-bright edge near the border.
//! 3. Ring contrast: the bore is dark relative to its rim: median over rays of
//!    `(rim - bore) / rim >= min_contrast_ratio` and `rim - bore >= min_contrast_levels`. Oil
//!    stains only darken metal by a factor (transmission 0.55-0.8), so a stain on a rim fails.
//! 4. The rim is the flat face of a machined annulus ([`crate::perception::rim`]): on at least
//!    `min_flat_share` of the rays walked out from the edge, no level rises far above the rim's
//!    level next to the edge before the rim ends (at any wall: no catalogue ratio is assumed;
//!    the walk stops at `max_outer_ratio` times the radius), and where the rim ends inside the
//!    image its median width is at least `min_ring_width_px`; and the rim's level next to the
//!    edge is much the same all round, about a light gradient and where no oil darkens it
//!    (spread at most `max_rim_spread` of the contrast). A
//!    standing bottle's dark cap sits in a translucent body that brightens towards its limb, a
//!    lying one's between its body and the belt: they fail this test.
//! 5. Circularity: filtered roundness at most `max_roundness_ratio` times the radius. A lying
//!    bottle's capsule (and any dark band in it) is elongated and fails.
//!
//! The wall's width from the rim walk bounds how far the edge refinement reads onto the rim, so
//! walls down to a few pixels are measured. Bores cut by the image border are never fitted as
//! if whole: [`BoreDetector::detect_report`] lists them with the reason they were skipped.

use crate::perception::border_cut::cut_bore;
pub use crate::perception::border_cut::{BoreReport, SkipReason, SkippedBore};
pub use crate::perception::bore_params::BoreDetectorParams;
use crate::perception::circle_fit::{fit_geometric, fit_kasa, raw_roundness};
use crate::perception::contours::{BorderKind, Contour, binned_radii, find_contours};
use crate::perception::error::PerceptionError;
use crate::perception::integer_edges::{canny_points, integer_fit};
use crate::perception::rim::{RimParams, scan_rim};
use crate::perception::robust_series::fit_series_robust;
use crate::perception::roundness::{filtered_roundness_bridged, median_of};
use crate::perception::segment::{second_segmentation, segment};
use crate::perception::subpixel::{EdgePoint, RayDir, RaySteps, refine_ray_in_steps};
use image::GrayImage;
use std::f64::consts::TAU;

/// Which edge points the circle is fitted to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum EdgeMode {
    /// Sub-pixel edges on rays, roundness on the filtered profile (the default).
    SubPixel,
    /// The paper's classic way: integer hole-border pixels, eq. 11 on the raw points.
    IntegerContour,
    /// The paper's classic way with Canny: integer Canny edge pixels of the binary image.
    Canny,
}

impl EdgeMode {
    /// Short name for tables.
    pub fn name(&self) -> &'static str {
        match self {
            Self::SubPixel => "subpixel",
            Self::IntegerContour => "integer-contour",
            Self::Canny => "canny-integer",
        }
    }
}

/// A measured bore, pixels (x right, y down, pixel centres at integers).
#[derive(Debug, Clone, PartialEq)]
pub struct Bore {
    /// Fitted centre `[x, y]`.
    pub centre_px: [f64; 2],
    /// Fitted radius.
    pub radius_px: f64,
    /// `Rmax - Rmin` about the fitted centre.
    pub roundness_px: f64,
    /// One-sigma uncertainty of each centre coordinate.
    pub centre_sigma_px: f64,
    /// One-sigma uncertainty of the radius.
    pub radius_sigma_px: f64,
    /// One-sigma uncertainty of the roundness.
    pub roundness_sigma_px: f64,
    /// Measured edge points the fit used.
    pub edge_points_px: Vec<[f64; 2]>,
    /// Points of the robust low-order outline standing in for the rays whose edge was rejected
    /// (hidden or displaced by a stain or dirt): the roundness profile bridges those arcs with
    /// them. Empty when every ray gave a clean edge.
    pub bridge_points_px: Vec<[f64; 2]>,
    /// Share of the rays whose measured edge the fit used.
    pub coverage: f64,
    /// Median `(rim - bore) / rim` over the rays.
    pub contrast_ratio: f64,
    /// Median ratio of the rim's outer radius to the bore radius over the rays where the rim
    /// ends inside the image; NaN where it ends on none.
    pub outer_ratio: f64,
    /// The rim's outer edge where it was found (image pixels), some of them on the tube's side
    /// wall under a tilted camera ([`crate::perception::rim::RimScan::outer_points_px`]).
    pub outer_edge_points_px: Vec<[f64; 2]>,
}

impl Bore {
    /// The same bore in another image's pixels, `p' = scale p + (dx_px, dy_px)` (a bore found in
    /// an area of interest read at a finer pitch, moved into the frame): positions map, lengths
    /// and their uncertainties scale.
    pub fn mapped(mut self, scale: f64, dx_px: f64, dy_px: f64) -> Self {
        let map = |p: [f64; 2]| [scale * p[0] + dx_px, scale * p[1] + dy_px];
        self.centre_px = map(self.centre_px);
        for p in self
            .edge_points_px
            .iter_mut()
            .chain(self.bridge_points_px.iter_mut())
            .chain(self.outer_edge_points_px.iter_mut())
        {
            *p = map(*p);
        }
        self.radius_px *= scale;
        self.roundness_px *= scale;
        self.centre_sigma_px *= scale;
        self.radius_sigma_px *= scale;
        self.roundness_sigma_px *= scale;
        self
    }
}

/// What became of one hole border.
enum Candidate {
    Measured(Bore),
    Skipped(SkippedBore),
    Rejected,
}

/// Smallest image side the detector accepts.
pub const MIN_IMAGE_SIDE_PX: u32 = 16;

/// Finds and measures bores. Holds only its parameters.
#[derive(Debug, Clone, Default)]
pub struct BoreDetector {
    /// Parameters.
    pub params: BoreDetectorParams,
}

impl BoreDetector {
    /// A detector with `params`.
    pub fn new(params: BoreDetectorParams) -> Self {
        Self { params }
    }

    /// Every whole bore in `image`, sorted by `y` then `x`; an empty list when there is none.
    pub fn detect(&self, image: &GrayImage) -> Result<Vec<Bore>, PerceptionError> {
        Ok(self.detect_report(image)?.bores)
    }

    /// Every whole bore in `image`, and the bores cut by its border with the reason they were
    /// not measured.
    pub fn detect_report(&self, image: &GrayImage) -> Result<BoreReport, PerceptionError> {
        if image.width() < MIN_IMAGE_SIDE_PX || image.height() < MIN_IMAGE_SIDE_PX {
            return Err(PerceptionError::ImageTooSmall {
                width_px: image.width(),
                height_px: image.height(),
                min_side_px: MIN_IMAGE_SIDE_PX,
            });
        }
        let (filtered, binary) = segment(&self.params, image);
        let contours = find_contours(&binary);
        let mut report = self.report_contours(&filtered, &binary, &contours);
        if let Some(second) = second_segmentation(&self.params, &filtered) {
            let contours = find_contours(&second);
            self.add_unseen(&filtered, &second, &contours, &mut report);
        }
        Ok(report)
    }

    /// Adds to `report` the bores (and cut bores) of the hole borders in `contours` (of another
    /// segmentation of `filtered`) that lie away from those it holds; those it holds stay as
    /// they are.
    fn add_unseen(
        &self,
        filtered: &GrayImage,
        binary: &GrayImage,
        contours: &[Contour],
        report: &mut BoreReport,
    ) {
        let canny = match self.params.edge_mode {
            EdgeMode::Canny => Some(crate::perception::edges::canny(binary, 50.0, 150.0)),
            _ => None,
        };
        let min_points = (0.5 * TAU * self.params.min_radius_px) as usize;
        let apart = |a: [f64; 2], ra: f64, b: [f64; 2], rb: f64| {
            (a[0] - b[0]).hypot(a[1] - b[1]) >= 0.5 * ra.min(rb)
        };
        let mut added = false;
        for contour in contours.iter().filter(|c| c.kind == BorderKind::Hole) {
            if contour.points_px.len() < min_points {
                continue;
            }
            // The border's centroid and mean distance from it: enough to tell a place apart.
            let n = contour.points_px.len() as f64;
            let [sx, sy] = contour.points_px.iter().fold([0.0, 0.0], |[x, y], q| {
                [x + f64::from(q[0]), y + f64::from(q[1])]
            });
            let centre = [sx / n, sy / n];
            let radius = contour
                .points_px
                .iter()
                .map(|q| (f64::from(q[0]) - centre[0]).hypot(f64::from(q[1]) - centre[1]))
                .sum::<f64>()
                / n;
            let unseen = |c: [f64; 2], r: f64| {
                report
                    .bores
                    .iter()
                    .all(|b| apart(b.centre_px, b.radius_px, c, r))
                    && report
                        .skipped
                        .iter()
                        .all(|s| apart(s.centre_px, s.radius_px, c, r))
            };
            if !unseen(centre, radius) {
                // A bore measured far out of round may be one run together with oil on its rim:
                // this hole, measured on its own, replaces it if it is much rounder.
                let suspect = report.bores.iter().position(|b| {
                    !apart(b.centre_px, b.radius_px, centre, radius)
                        && b.roundness_px > self.params.recheck_roundness_ratio * b.radius_px
                });
                if let Some(i) = suspect
                    && let Candidate::Measured(bore) =
                        self.measure_candidate(filtered, canny.as_ref(), contour)
                    && bore.roundness_px < 0.5 * report.bores[i].roundness_px
                {
                    report.bores[i] = bore;
                    added = true;
                }
                continue;
            }
            match self.measure_candidate(filtered, canny.as_ref(), contour) {
                Candidate::Measured(bore) if unseen(bore.centre_px, bore.radius_px) => {
                    report.bores.push(bore);
                    added = true;
                }
                Candidate::Skipped(skip) if unseen(skip.centre_px, skip.radius_px) => {
                    report.skipped.push(skip);
                    added = true;
                }
                _ => {}
            }
        }
        if added {
            report
                .bores
                .sort_by(|a, b| by_position(&a.centre_px, &b.centre_px));
            report
                .skipped
                .sort_by(|a, b| by_position(&a.centre_px, &b.centre_px));
        }
    }

    /// The stages after border following: candidates, edges, tests, fits.
    pub fn measure_contours(
        &self,
        filtered: &GrayImage,
        binary: &GrayImage,
        contours: &[Contour],
    ) -> Vec<Bore> {
        self.report_contours(filtered, binary, contours).bores
    }

    /// [`Self::measure_contours`] with the skipped bores.
    pub fn report_contours(
        &self,
        filtered: &GrayImage,
        binary: &GrayImage,
        contours: &[Contour],
    ) -> BoreReport {
        let canny = match self.params.edge_mode {
            EdgeMode::Canny => Some(crate::perception::edges::canny(binary, 50.0, 150.0)),
            _ => None,
        };
        let mut bores = Vec::new();
        let mut skipped = Vec::new();
        for contour in contours.iter().filter(|c| c.kind == BorderKind::Hole) {
            match self.measure_candidate(filtered, canny.as_ref(), contour) {
                Candidate::Measured(bore) => bores.push(bore),
                Candidate::Skipped(skip) => skipped.push(skip),
                Candidate::Rejected => {}
            }
        }
        // Keep one bore per place (the one with more edge points).
        bores.sort_by_key(|b| std::cmp::Reverse(b.edge_points_px.len()));
        let mut kept: Vec<Bore> = Vec::with_capacity(bores.len());
        for bore in bores {
            let duplicate = kept.iter().any(|k| {
                let d =
                    (k.centre_px[0] - bore.centre_px[0]).hypot(k.centre_px[1] - bore.centre_px[1]);
                d < 0.5 * k.radius_px.min(bore.radius_px)
            });
            if !duplicate {
                kept.push(bore);
            }
        }
        kept.sort_by(|a, b| by_position(&a.centre_px, &b.centre_px));
        skipped.sort_by(|a, b| by_position(&a.centre_px, &b.centre_px));
        BoreReport {
            bores: kept,
            skipped,
        }
    }

    fn measure_candidate(
        &self,
        filtered: &GrayImage,
        canny: Option<&GrayImage>,
        contour: &Contour,
    ) -> Candidate {
        let (w, h) = (filtered.width() as i32, filtered.height() as i32);
        let on_frame = |q: &[i32; 2]| q[0] <= 0 || q[1] <= 0 || q[0] >= w - 1 || q[1] >= h - 1;
        if contour.points_px.iter().any(on_frame) {
            return cut_bore(&self.params, filtered, contour, on_frame)
                .map_or(Candidate::Rejected, Candidate::Skipped);
        }
        self.measure_whole(filtered, canny, contour)
            .map_or(Candidate::Rejected, Candidate::Measured)
    }

    fn measure_whole(
        &self,
        filtered: &GrayImage,
        canny: Option<&GrayImage>,
        contour: &Contour,
    ) -> Option<Bore> {
        let p = &self.params;
        let min_points = (0.5 * TAU * p.min_radius_px) as usize;
        let max_points = (4.0 * TAU * p.max_radius_px) as usize;
        if contour.points_px.len() < min_points || contour.points_px.len() > max_points {
            return None;
        }
        let border: Vec<[f64; 2]> = contour
            .points_px
            .iter()
            .map(|q| [f64::from(q[0]), f64::from(q[1])])
            .collect();
        let coarse = fit_kasa(&border).ok()?;
        // The hole border lies on the bright side, about half a pixel outside the edge.
        if coarse.radius < p.min_radius_px - 1.0
            || coarse.radius > p.max_radius_px + 1.0
            // A stain or noise joined to the bore bulges its hole border; the robust outline below
            // sees through bulges, so only clearly non-circular holes stop here.
            || coarse.rms_residual > 0.3 * coarse.radius
        {
            return None;
        }
        let [fewest, most] = p.ray_range;
        let ray_count = ((TAU * coarse.radius / p.ray_spacing_px).round() as usize)
            .clamp(fewest, most.max(fewest));
        let coarse_radii = binned_radii(&border, coarse.centre, ray_count, coarse.radius);
        let rays: Vec<RayDir> = (0..ray_count)
            .map(|i| RayDir::new(TAU * i as f64 / ray_count as f64))
            .collect();
        // Where the threshold cut a stain or dirt out of the rim, the hole border bulges around
        // it; a robust low-order outline of the border ignores such bulges.
        let stride = ray_count.div_ceil(MAX_SERIES_POINTS);
        let outline = fit_series_robust(
            &rays
                .iter()
                .step_by(stride)
                .map(|r| r.unit)
                .collect::<Vec<_>>(),
            &coarse_radii
                .iter()
                .step_by(stride)
                .copied()
                .collect::<Vec<_>>(),
            OUTLINE_ORDER,
            0.5,
        )?;

        let rim = scan_rim(
            filtered,
            coarse.centre,
            |unit| outline.radius_along(unit),
            &RimParams {
                max_outer_ratio: p.max_outer_ratio,
                ..RimParams::default()
            },
        )?;
        if rim.flat_share < p.min_flat_share
            || rim.rim_spread > p.max_rim_spread
            || rim.wall_px.is_some_and(|wall| wall < p.min_ring_width_px)
        {
            return None;
        }
        let ray_params = match rim.wall_px {
            Some(wall) => p.rays.within_wall(wall),
            None => p.rays,
        };
        let mut scratch = Vec::new();
        let steps = RaySteps::new(&ray_params);
        let edges: Vec<EdgePoint> = rays
            .iter()
            .filter_map(|&ray| {
                let rho = outline.radius_along(ray.unit);
                refine_ray_in_steps(filtered, coarse.centre, ray, rho, &steps, &mut scratch)
            })
            .collect();
        if (edges.len() as f64) < p.min_valid_share * ray_count as f64 {
            return None;
        }
        let mut ratios: Vec<f64> = edges
            .iter()
            .map(|e| e.contrast() / e.outer_level.max(1.0))
            .collect();
        let contrast_ratio = median_of(&mut ratios);
        let mut contrasts: Vec<f64> = edges.iter().map(EdgePoint::contrast).collect();
        if contrast_ratio < p.min_contrast_ratio
            || median_of(&mut contrasts) < p.min_contrast_levels
        {
            return None;
        }

        let mut bridges = Vec::new();
        let mut coverage = 1.0;
        let (points, fit, profile) = match p.edge_mode {
            EdgeMode::SubPixel => {
                let arcs = self.clean_edges(coarse.centre, &rays, &edges)?;
                bridges = arcs.bridges;
                coverage = arcs.points.len() as f64 / ray_count as f64;
                let fit = fit_geometric(&arcs.points).ok()?;
                let profile =
                    filtered_roundness_bridged(&arcs.points, &bridges, fit.centre, p.max_upr)
                        .ok()?;
                (arcs.points, fit, profile)
            }
            EdgeMode::IntegerContour => integer_fit(border, p.max_upr)?,
            EdgeMode::Canny => {
                let edge_map = canny?;
                let points = canny_points(edge_map, coarse.centre, &coarse_radii);
                integer_fit(points, p.max_upr)?
            }
        };
        if profile.roundness > p.max_roundness_ratio * fit.radius
            || fit.radius < p.min_radius_px
            || fit.radius > p.max_radius_px
        {
            return None;
        }
        let roundness_px = match p.edge_mode {
            EdgeMode::SubPixel => profile.roundness,
            EdgeMode::IntegerContour | EdgeMode::Canny => raw_roundness(&points, fit.centre),
        };
        let n = points.len() as f64;
        let sigma = profile.noise_sigma();
        Some(Bore {
            centre_px: fit.centre,
            radius_px: fit.radius,
            roundness_px,
            centre_sigma_px: sigma * (2.0 / n).sqrt(),
            radius_sigma_px: sigma / n.sqrt(),
            roundness_sigma_px: profile.roundness_sigma(),
            edge_points_px: points,
            bridge_points_px: bridges,
            coverage,
            contrast_ratio,
            // The outer edge's radius over the fitted bore's, not the coarse outline's (which
            // sits a pixel or so off the edge: 5 % of an 8 mm bore).
            outer_ratio: rim
                .outer_radius_px
                .map_or(f64::NAN, |outer| outer / fit.radius),
            outer_edge_points_px: rim.outer_points_px,
        })
    }

    /// The edges a roundness measurement can trust, and bridge points for the arcs without one.
    ///
    /// An edge is dropped when the levels either side of it depart from lines by more than
    /// `max_flank_departure` of the contrast (a speck of dirt or a stain's curved rim lies
    /// against it), or when its radius about the ray origin lies more than `outlier_scales` robust scales
    /// from a robust low-order series fitted to the remaining edges. The rays left without an
    /// edge get a bridge point on that series. `None` when less than `min_clean_share` of the
    /// rays keep an edge.
    fn clean_edges(
        &self,
        origin: [f64; 2],
        rays: &[RayDir],
        edges: &[EdgePoint],
    ) -> Option<CleanArcs> {
        let p = &self.params;
        let flat: Vec<&EdgePoint> = edges
            .iter()
            .filter(|e| e.flank_departure() <= p.max_flank_departure)
            .collect();
        let stride = flat.len().div_ceil(MAX_SERIES_POINTS).max(1);
        let flat_units: Vec<[f64; 2]> = flat.iter().step_by(stride).map(|e| e.ray.unit).collect();
        let flat_radii: Vec<f64> = flat.iter().step_by(stride).map(|e| e.radius_px).collect();
        let series =
            fit_series_robust(&flat_units, &flat_radii, EDGE_ORDER, p.edge_scale_floor_px)?;
        let limit = p.outlier_scales * series.scale;
        let mut points = Vec::with_capacity(flat.len());
        let mut kept_angles = Vec::with_capacity(flat.len());
        for e in &flat {
            if (e.radius_px - series.radius_along(e.ray.unit)).abs() <= limit {
                points.push(e.point_px);
                kept_angles.push(e.ray.angle_rad);
            }
        }
        if (points.len() as f64) < p.min_clean_share * rays.len() as f64 {
            return None;
        }
        // Both lists are in ray order: walk them together.
        let mut bridges = Vec::new();
        let mut next = kept_angles.iter().peekable();
        for ray in rays {
            if next.next_if(|&&a| a == ray.angle_rad).is_none() {
                let [c, s] = ray.unit;
                let r = series.radius_along(ray.unit);
                bridges.push([origin[0] + r * c, origin[1] + r * s]);
            }
        }
        Some(CleanArcs { points, bridges })
    }
}

/// Orders points by `y`, then `x`.
fn by_position(a: &[f64; 2], b: &[f64; 2]) -> std::cmp::Ordering {
    a[1].total_cmp(&b[1]).then(a[0].total_cmp(&b[0]))
}

/// Order of the robust outline of a hole border: enough for an off-centre origin (1), ellipses
/// and lobes (2, 3) and their perspective images.
const OUTLINE_ORDER: usize = 3;

/// Order of the robust series the measured edges are checked against.
const EDGE_ORDER: usize = 4;

/// Most points a robust series is fitted to (every n-th of more): plenty for its few
/// coefficients, and the fit's cost grows with them.
const MAX_SERIES_POINTS: usize = 200;

/// Measured edge points and bridge points of [`BoreDetector::clean_edges`].
struct CleanArcs {
    points: Vec<[f64; 2]>,
    bridges: Vec<[f64; 2]>,
}
