//! Which of the detector's bottle boxes are whole bottles, and where, by the image itself.
//!
//! A box fit ([`BottleFitter::fit`]) assumes the box holds one whole bottle. A detector that
//! has seen few lying bottles from a tilted camera also draws boxes around part of one (a
//! fragment, beside or inside the whole bottle's box), and the frame's border cuts the boxes of
//! bottles at the view's edge; the best pose for such a box is often a standing bottle 200 mm
//! tall that is not there. The pixels settle it: a bottle is bright plastic on a dark belt, so
//! every point of a true pose's body projects onto pixels that are not the belt's.
//!
//! - A pose's **support** is the share of points inside its body (off the dark cap) that project
//!   onto pixels unlike the belt's; points outside the frame count for nothing either way. A
//!   pose the image contradicts (support under [`MIN_SUPPORT`]) is dropped.
//! - A box whose fit no pose explains (none supported, a residual large for its size, or a side
//!   on the frame's border) is searched by the pixels instead: over standing and lying at any
//!   yaw, and over places on the belt around the box, the pose that best covers the box's bright
//!   pixels with a supported body.
//! - Two sightings whose bodies would pass through each other (their axes nearer than a
//!   bottle's radius) are one bottle: the better explained one stays.

use image::RgbImage;
use nalgebra::{Isometry3, Point3};

use super::bottle_fit::{BottleFitter, BottlePose, CUT_SHARE};
use super::bottle_outline::Cells;
use super::camera_percept::BottleSighting;
use super::measured_tube::{BeltScene, MeasuredTube};
use super::silhouette::{CutBox, box_residual_px};
use crate::detect::Detection;

/// A box whose best pose's outline agrees with the pixels by at least this (intersection over
/// union, [`BottleFitter::agreement`]) is explained by it.
const MIN_AGREEMENT: f64 = 0.45;
/// Share of a pose's body points that must fall on pixels unlike the belt's.
pub const MIN_SUPPORT: f64 = 0.7;
/// A pixel whose mean colour over 3 x 3 differs from the belt's by more than this (RGB
/// distance, 8-bit levels) is not the belt.
const FOREGROUND_LEVEL: f64 = 40.0;
/// A box fit whose residual exceeds this share of the box's diagonal does not explain the box.
const RESIDUAL_SHARE: f64 = 0.06;
/// Fewest body points that must fall inside the frame for the support to be read.
const MIN_POINTS_IN_FRAME: usize = 16;
/// The pixel search: lying yaws over a half turn (a lying body's support and cover barely
/// depend on which end is the cap), places on a square grid around the box's centre on the
/// belt (steps, step m), then a finer pass around the best.
const SEARCH_YAWS: usize = 36;
const SEARCH_STEPS: i32 = 5;
const SEARCH_STEP_M: f64 = 0.025;
const REFINE_STEPS: i32 = 3;
/// Samples of the box's pixels per side for the cover.
const COVER_GRID: usize = 24;

/// The frame as the fit reads it: pixels (calibration pixels `scale` image pixels each) and
/// the belt's colour.
pub struct Evidence<'a> {
    image: &'a RgbImage,
    scale: f64,
    belt: [f64; 3],
    /// The frame's size in calibration pixels.
    frame_px: (f64, f64),
    /// Per image pixel, once read: 1 belt, 2 not the belt (0 not read yet).
    read: Vec<std::cell::Cell<u8>>,
}

impl<'a> Evidence<'a> {
    /// The evidence of `image` (`scale` image pixels per calibration pixel, a `frame_px` large
    /// frame), the belt's colour read around `boxes` (every detection's box, calibration
    /// pixels) outside all of them; `None` when too little of the belt shows.
    pub fn new(
        image: &'a RgbImage,
        scale: f64,
        frame_px: (u32, u32),
        boxes: &[[f64; 4]],
    ) -> Option<Self> {
        let mut e = Self {
            image,
            scale,
            belt: [0.0; 3],
            frame_px: (f64::from(frame_px.0), f64::from(frame_px.1)),
            read: vec![std::cell::Cell::new(0); (image.width() * image.height()) as usize],
        };
        let inside_any = |u: f64, v: f64| {
            boxes
                .iter()
                .any(|b| (b[0]..=b[2]).contains(&u) && (b[1]..=b[3]).contains(&v))
        };
        let mut ring = Vec::new();
        for b in boxes {
            for d in [4.0, 10.0] {
                for k in 0..=32 {
                    let t = f64::from(k) / 32.0;
                    let (u, v) = (
                        b[0] - d + t * (b[2] - b[0] + 2.0 * d),
                        b[1] - d + t * (b[3] - b[1] + 2.0 * d),
                    );
                    for (x, y) in [(u, b[1] - d), (u, b[3] + d), (b[0] - d, v), (b[2] + d, v)] {
                        if !inside_any(x, y)
                            && let Some(c) = e.colour(x, y)
                        {
                            ring.push(c);
                        }
                    }
                }
            }
        }
        if ring.len() < 16 {
            return None;
        }
        for c in 0..3 {
            let mut channel: Vec<f64> = ring.iter().map(|p| p[c]).collect();
            channel.sort_by(f64::total_cmp);
            e.belt[c] = channel[channel.len() / 2];
        }
        Some(e)
    }

    /// The mean colour over 3 x 3 image pixels at calibration pixel `(u, v)`, or `None` outside
    /// the image.
    fn colour(&self, u: f64, v: f64) -> Option<[f64; 3]> {
        let (w, h) = (self.image.width() as i64, self.image.height() as i64);
        let (x, y) = (
            (u * self.scale).floor() as i64,
            (v * self.scale).floor() as i64,
        );
        if x < 0 || y < 0 || x >= w || y >= h {
            return None;
        }
        let mut sum = [0.0; 3];
        let mut n = 0.0;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (px, py) = ((x + dx).clamp(0, w - 1), (y + dy).clamp(0, h - 1));
                let p = self.image.get_pixel(px as u32, py as u32).0;
                for c in 0..3 {
                    sum[c] += f64::from(p[c]);
                }
                n += 1.0;
            }
        }
        Some(sum.map(|s| s / n))
    }

    /// The frame's size in calibration pixels.
    pub(super) fn frame_px(&self) -> (f64, f64) {
        self.frame_px
    }

    /// Whether calibration pixel `(u, v)` is not the belt; `None` outside the frame.
    pub(super) fn foreground(&self, u: f64, v: f64) -> Option<bool> {
        let (x, y) = ((u * self.scale).floor(), (v * self.scale).floor());
        let (w, h) = (
            f64::from(self.image.width()),
            f64::from(self.image.height()),
        );
        if x < 0.0 || y < 0.0 || x >= w || y >= h {
            return None;
        }
        let slot = &self.read[(y * w + x) as usize];
        if slot.get() == 0 {
            let c = self.colour(u, v)?;
            let d = ((c[0] - self.belt[0]).powi(2)
                + (c[1] - self.belt[1]).powi(2)
                + (c[2] - self.belt[2]).powi(2))
            .sqrt();
            slot.set(if d > FOREGROUND_LEVEL { 2 } else { 1 });
        }
        Some(slot.get() == 2)
    }

    /// `box_px` as much of it as lies in the frame.
    fn clip(&self, box_px: [f64; 4]) -> [f64; 4] {
        let (w, h) = self.frame_px;
        [
            box_px[0].clamp(0.0, w),
            box_px[1].clamp(0.0, h),
            box_px[2].clamp(0.0, w),
            box_px[3].clamp(0.0, h),
        ]
    }
}

/// How well one pose is borne out by the pixels.
#[derive(Debug, Clone, Copy)]
struct Score {
    support: f64,
    cover: f64,
}

impl BottleFitter {
    /// The share of the body points of the bottle at `world_from_bottle` that project onto
    /// pixels unlike the belt's, or `None` when too few project into the frame.
    pub fn support(&self, world_from_bottle: &Isometry3<f64>, e: &Evidence<'_>) -> Option<f64> {
        let (mut on, mut seen) = (0usize, 0usize);
        for p in &self.body_points {
            let Some([u, v]) = self.calibration.project(&(world_from_bottle * p)) else {
                continue;
            };
            if let Some(fg) = e.foreground(u, v) {
                seen += 1;
                on += usize::from(fg);
            }
        }
        (seen >= MIN_POINTS_IN_FRAME).then(|| on as f64 / seen as f64)
    }

    /// The bottle's projected outline as its axis' two ends and half its width, pixels.
    pub(super) fn capsule(
        &self,
        world_from_bottle: &Isometry3<f64>,
    ) -> Option<([f64; 2], [f64; 2], f64)> {
        let c = &self.calibration;
        let a = c.project(&(world_from_bottle * Point3::new(0.0, 0.0, 0.0)))?;
        let b = c.project(&(world_from_bottle * Point3::new(0.0, 0.0, self.height_m)))?;
        let middle = world_from_bottle * Point3::new(0.0, 0.0, self.height_m / 2.0);
        let depth = (c.world_from_camera.inverse() * middle).z;
        (depth > 0.0).then(|| (a, b, self.radius_m * c.fx_px / depth))
    }

    /// Support and cover (the share of `bright`, the box's pixels unlike the belt, inside the
    /// pose's outline) of the bottle at `pose`.
    fn score(&self, pose: &Isometry3<f64>, bright: &[[f64; 2]], e: &Evidence<'_>) -> Option<Score> {
        let support = self.support(pose, e)?;
        if support < MIN_SUPPORT {
            // Not a candidate: its cover is not needed.
            return Some(Score {
                support,
                cover: 0.0,
            });
        }
        let (a, b, r) = self.capsule(pose)?;
        let inside = bright
            .iter()
            .filter(|p| segment_distance(p, &a, &b) <= r)
            .count();
        let cover = if bright.is_empty() {
            0.0
        } else {
            inside as f64 / bright.len() as f64
        };
        Some(Score { support, cover })
    }

    /// The pose over standing and lying at any yaw, on places around `box_px`'s centre on the
    /// belt, whose supported body best covers the box's bright pixels; `None` when no pose is
    /// supported.
    pub(super) fn search(
        &self,
        box_px: &[f64; 4],
        belt_top_z_m: f64,
        tubes: &[MeasuredTube],
        e: &Evidence<'_>,
    ) -> Option<BottlePose> {
        let bright = bright_pixels(box_px, e);
        if bright.len() < COVER_GRID {
            return None;
        }
        let [x0, y0, x1, y1] = *box_px;
        let centre = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
        let value = |s: Score| {
            if s.support >= MIN_SUPPORT {
                s.support * s.cover
            } else {
                0.0
            }
        };
        let eval = |lying: bool, yaw: f64, x: f64, y: f64| {
            let pose = self.pose_at(lying, yaw, x, y, belt_top_z_m);
            if tubes
                .iter()
                .any(|t| self.passes_through(&pose, t, belt_top_z_m))
            {
                return 0.0;
            }
            self.score(&pose, &bright, e).map_or(0.0, value)
        };
        let mut best: Option<(f64, bool, f64, f64, f64)> = None;
        let keep = |best: &mut Option<(f64, bool, f64, f64, f64)>,
                    c: (f64, bool, f64, f64, f64)| {
            if c.0 > 0.0 && best.is_none_or(|b| c.0 > b.0) {
                *best = Some(c);
            }
        };
        let hypotheses: Vec<(bool, f64)> = std::iter::once((false, 0.0))
            .chain(
                (0..SEARCH_YAWS)
                    .map(|k| (true, std::f64::consts::PI * k as f64 / SEARCH_YAWS as f64)),
            )
            .collect();
        for &(lying, yaw) in &hypotheses {
            let mid_z = self.mid_z(lying, belt_top_z_m);
            let Ok(at) = self
                .calibration
                .pixel_to_height(centre[0], centre[1], mid_z)
            else {
                continue;
            };
            for i in -SEARCH_STEPS..=SEARCH_STEPS {
                for j in -SEARCH_STEPS..=SEARCH_STEPS {
                    let (x, y) = (
                        at.x + f64::from(i) * SEARCH_STEP_M,
                        at.y + f64::from(j) * SEARCH_STEP_M,
                    );
                    keep(&mut best, (eval(lying, yaw, x, y), lying, yaw, x, y));
                }
            }
        }
        let (_, lying, yaw, x, y) = best?;
        let step = SEARCH_STEP_M / f64::from(REFINE_STEPS);
        let yaw_step = std::f64::consts::PI / SEARCH_YAWS as f64 / 2.0;
        for k in -1..=1 {
            for i in -REFINE_STEPS..=REFINE_STEPS {
                for j in -REFINE_STEPS..=REFINE_STEPS {
                    let yaw = if lying {
                        yaw + f64::from(k) * yaw_step
                    } else {
                        0.0
                    };
                    let (x, y) = (x + f64::from(i) * step, y + f64::from(j) * step);
                    keep(&mut best, (eval(lying, yaw, x, y), lying, yaw, x, y));
                }
            }
        }
        let (_, lying, yaw, x, y) = best?;
        let world_from_bottle = self.pose_at(lying, yaw, x, y, belt_top_z_m);
        let residual_px = self
            .projected_box(&world_from_bottle)
            .map_or(f64::INFINITY, |b| {
                super::silhouette::box_residual_px(&b, box_px)
            });
        Some(BottlePose {
            world_from_bottle,
            lying,
            residual_px,
        })
    }

    /// The bottles of one frame: each detector box `boxes[k]` (its detection index and box,
    /// calibration pixels) fitted on the `belt` clear of its measured tubes, its poses checked
    /// against the pixels of `e` (a box no pose explains searched by the pixels), and sightings
    /// of one bottle merged. Returns the
    /// sightings and, per box, the index of the sighting that holds it.
    pub fn sightings(
        &self,
        boxes: &[(usize, [f64; 4])],
        belt: &BeltScene<'_>,
        e: &Evidence<'_>,
        excluded: &[[f64; 4]],
    ) -> (Vec<BottleSighting>, Vec<usize>) {
        let belt_top_z_m = belt.top_z_m;
        // Each box's poses, and whether its fit explained it.
        let mut fitted: Vec<(usize, Vec<BottlePose>, bool)> = Vec::new();
        for (k, (_, box_px)) in boxes.iter().enumerate() {
            let diagonal = (box_px[2] - box_px[0]).hypot(box_px[3] - box_px[1]);
            // The hypotheses whose boxes explain the detection (compared clipped to the frame, as
            // below); the outline chooses among them. A box none explains (a fragment of a
            // bottle, two bottles in one box) is searched by the pixels as before.
            // A pose through a measured tube is impossible.
            let candidates = self.clear_of_tubes(
                self.fit_candidates(box_px, belt_top_z_m),
                belt.tubes,
                belt_top_z_m,
            );
            let explains = |p: &BottlePose| {
                self.projected_box(&p.world_from_bottle).is_some_and(|b| {
                    box_residual_px(&e.clip(b), box_px) <= RESIDUAL_SHARE * diagonal
                })
            };
            let mut explaining: Vec<BottlePose> =
                candidates.iter().copied().filter(explains).collect();
            // A box the border cuts that no lying hypothesis explains: a lying bottle running
            // out of the frame is placed by the box's whole sides, and the outline judges it
            // beside the standing ones.
            if !explaining.iter().any(|p| p.lying) {
                let cut_lying = self.clear_of_tubes(
                    self.cut_lying_candidates(box_px, belt_top_z_m),
                    belt.tubes,
                    belt_top_z_m,
                );
                explaining.extend(cut_lying.into_iter().filter(explains));
            }
            // A box the border cuts that no standing hypothesis explains by its box: the border
            // may hide a standing bottle's upper body (from a camera looking down, a standing
            // bottle near the border reaches out of the frame), so the outline also judges its
            // best standing hypothesis (candidates are sorted best box first). A lying reading of
            // a standing bottle leaves 130 mm of its height unguarded.
            let cut = self
                .frame_px
                .is_some_and(|frame| CutBox::of(box_px, frame, CUT_SHARE).is_some());
            let hidden = if cut && !explaining.iter().any(|p| !p.lying) {
                candidates.iter().find(|p| !p.lying)
            } else {
                None
            };
            if !explaining.is_empty() {
                let cells = Cells::read(box_px, e, excluded, |u, v| {
                    self.sees_belt(u, v, belt_top_z_m)
                });
                if let Some((poses, agreement)) = self.by_outline(
                    &explaining,
                    hidden,
                    box_px,
                    belt_top_z_m,
                    belt.tubes,
                    &cells,
                ) && agreement >= MIN_AGREEMENT
                {
                    fitted.push((k, poses, true));
                    continue;
                }
            }
            let poses = self.fit_among(candidates);
            let poses = self.keep_supported(poses, box_px, e.image, e.scale);
            let supports: Vec<Option<f64>> = poses
                .iter()
                .map(|p| self.support(&p.world_from_bottle, e))
                .collect();
            let supported: Vec<BottlePose> = poses
                .iter()
                .zip(&supports)
                .filter(|(_, s)| s.is_none_or(|s| s >= MIN_SUPPORT))
                .map(|(p, _)| *p)
                .collect();
            // A box cut by the frame's border shows only the part of the bottle in the frame:
            // its poses are compared with it clipped to the frame.
            let explained = supported.iter().any(|p| {
                self.projected_box(&p.world_from_bottle).is_some_and(|b| {
                    box_residual_px(&e.clip(b), box_px) <= RESIDUAL_SHARE * diagonal
                })
            });
            let poses = if explained {
                supported
            } else {
                match self.search(box_px, belt_top_z_m, belt.tubes, e) {
                    Some(found) => vec![found],
                    None if !supported.is_empty() => supported,
                    None => poses,
                }
            };
            fitted.push((k, poses, explained));
        }
        self.merge_sightings(boxes, &fitted)
    }
}

/// The points of a `COVER_GRID`-square grid over `box_px` whose pixels are not the belt.
fn bright_pixels(box_px: &[f64; 4], e: &Evidence<'_>) -> Vec<[f64; 2]> {
    let [x0, y0, x1, y1] = *box_px;
    let mut bright = Vec::new();
    for i in 0..COVER_GRID {
        for j in 0..COVER_GRID {
            let u = x0 + (x1 - x0) * (i as f64 + 0.5) / COVER_GRID as f64;
            let v = y0 + (y1 - y0) * (j as f64 + 0.5) / COVER_GRID as f64;
            if e.foreground(u, v) == Some(true) {
                bright.push([u, v]);
            }
        }
    }
    bright
}

/// Distance from `p` to the segment `a`-`b`, pixels.
pub(super) fn segment_distance(p: &[f64; 2], a: &[f64; 2], b: &[f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// The bottle sightings of a look: `boxes` (the bottle detections' indices in `detections` and
/// boxes, calibration pixels of a `frame_px` frame) fitted by `fitter` and checked against
/// `image`, on the `belt`: no pose passes through one of its measured tubes. With the belt's
/// band, the bottles no box holds are then looked for in the pixels (`BottleFitter::unboxed`)
/// and follow the boxes' sightings. When the image shows too little of the belt to be read, each
/// box is fitted alone.
pub fn bottle_sightings(
    fitter: &BottleFitter,
    boxes: &[(usize, [f64; 4])],
    detections: &[Detection],
    image: &RgbImage,
    frame_px: (u32, u32),
    belt: &BeltScene<'_>,
) -> (Vec<BottleSighting>, Vec<usize>) {
    let belt_top_z_m = belt.top_z_m;
    let scale = f64::from(image.width()) / f64::from(frame_px.0);
    let all: Vec<[f64; 4]> = detections.iter().map(|d| d.box_px.map(f64::from)).collect();
    match Evidence::new(image, scale, frame_px, &all) {
        Some(e) => {
            let parts: Vec<[f64; 4]> = all
                .iter()
                .enumerate()
                .filter(|(i, _)| !boxes.iter().any(|(k, _)| k == i))
                .map(|(_, b)| *b)
                .collect();
            let columns: Vec<[f64; 4]> = parts
                .iter()
                .map(|b| fitter.part_column(b, belt_top_z_m))
                .collect();
            let (mut sightings, holder) = fitter.sightings(boxes, belt, &e, &columns);
            if let Some(band) = belt.band {
                fitter.unboxed(&mut sightings, &parts, band, belt_top_z_m, belt.tubes, &e);
            }
            (sightings, holder)
        }
        None => {
            let sightings = boxes
                .iter()
                .map(|(detection, box_px)| BottleSighting {
                    detection: *detection,
                    poses: fitter.keep_supported(
                        fitter.fit_among(fitter.clear_of_tubes(
                            fitter.fit_candidates(box_px, belt_top_z_m),
                            belt.tubes,
                            belt_top_z_m,
                        )),
                        box_px,
                        image,
                        scale,
                    ),
                })
                .collect();
            (sightings, (0..boxes.len()).collect())
        }
    }
}

#[cfg(test)]
#[path = "cut_standing_tests.rs"]
mod cut_standing_tests;
