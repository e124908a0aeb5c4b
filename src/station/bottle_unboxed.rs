//! Bottles the detector drew no box around, found in the pixels.
//!
//! The detector misses bottles: a lying one pressed against the part, or every bottle of a
//! crowded look (traced in `clutter`: the arm's descent touched a lying bottle the percept did
//! not hold, its planned clearance 20 mm). A bottle is bright plastic on a dark belt, so what
//! the look has not explained is still in the frame: bright pixels on the belt outside every
//! part's box and every kept bottle's outline. Each patch of them large enough to be a bottle is
//! searched by the pixels as an unexplained box is (`BottleFitter::search`), and the pose found
//! is kept when its body covers most of the patch: a new bottle, or, where it passes through a
//! bottle already seen (a box fitted elsewhere than the bottle lies), one more pose of that one.

use super::bottle_evidence::{Evidence, segment_distance};
use super::bottle_fit::{BottleFitter, BottlePose};
use super::camera_percept::BottleSighting;
use super::measured_tube::MeasuredTube;

/// Grid points across the frame's width the scan reads (the grid is square).
const SCAN_COLUMNS: f64 = 160.0;
/// How far past a part's box its own pixels (its side, its edge's blur) may reach, as a share
/// of the box's larger side.
const PART_GROWTH_SHARE: f64 = 0.15;
/// How far past a kept bottle's projected outline its own pixels may reach, pixels.
const OUTLINE_GROWTH_PX: f64 = 6.0;
/// Smallest patch searched, as a share of the grid points a lying bottle's outline covers there.
const MIN_PATCH_SHARE: f64 = 0.2;
/// Share of a patch's points the found body must cover.
const MIN_PATCH_COVER: f64 = 0.6;
/// How far inside the belt's edges a point must lie, m (the belt's own border and rails).
const BELT_EDGE_MARGIN_M: f64 = 0.01;

/// Where the bottles may lie: the belt, along the world's x, between two y.
#[derive(Debug, Clone, Copy)]
pub struct BeltBand {
    /// y of the belt's middle, m.
    pub centre_y_m: f64,
    /// Half the belt's width, m.
    pub half_width_m: f64,
}

impl BeltBand {
    /// The band of the scenario's belt.
    pub fn of(conveyor: &crate::scenario::ConveyorSection) -> Self {
        Self {
            centre_y_m: conveyor.belt_center_m[1],
            half_width_m: conveyor.width_m / 2.0,
        }
    }
}

impl BottleFitter {
    /// Adds to `seen` the bottles in `e`'s frame that no box holds: patches of bright pixels on
    /// the belt's `band` outside `part_boxes` (grown) and outside the outline of every pose of
    /// `seen`, each searched by the pixels. A pose found through a bottle of `seen` is another
    /// pose of it; any other is a new sighting (its `detection` is `usize::MAX`: no detection
    /// holds it).
    pub(super) fn unboxed(
        &self,
        seen: &mut Vec<BottleSighting>,
        part_boxes: &[[f64; 4]],
        band: BeltBand,
        belt_top_z_m: f64,
        tubes: &[MeasuredTube],
        e: &Evidence<'_>,
    ) {
        let (w, h) = e.frame_px();
        let step = (w / SCAN_COLUMNS).max(1.0);
        let (cols, rows) = ((w / step) as usize, (h / step) as usize);
        let outlines: Vec<([f64; 2], [f64; 2], f64)> = seen
            .iter()
            .flat_map(|s| s.poses.iter())
            .filter_map(|p| self.capsule(&p.world_from_bottle))
            .collect();
        let grown: Vec<[f64; 4]> = part_boxes
            .iter()
            .map(|b| {
                let g = PART_GROWTH_SHARE * (b[2] - b[0]).max(b[3] - b[1]);
                [b[0] - g, b[1] - g, b[2] + g, b[3] + g]
            })
            .collect();
        let lying_mid_z = belt_top_z_m + self.radius_m;
        let on_belt = |u: f64, v: f64| {
            self.calibration
                .pixel_to_height(u, v, lying_mid_z)
                .is_ok_and(|p| {
                    (p.y - band.centre_y_m).abs() <= band.half_width_m - BELT_EDGE_MARGIN_M
                })
        };
        let unexplained = |u: f64, v: f64| {
            e.foreground(u, v) == Some(true)
                && !grown
                    .iter()
                    .any(|b| (b[0]..=b[2]).contains(&u) && (b[1]..=b[3]).contains(&v))
                && !outlines
                    .iter()
                    .any(|(a, b, r)| segment_distance(&[u, v], a, b) <= r + OUTLINE_GROWTH_PX)
                && on_belt(u, v)
        };
        let at = |i: usize, j: usize| ((i as f64 + 0.5) * step, (j as f64 + 0.5) * step);
        let mut mask = vec![false; cols * rows];
        for j in 0..rows {
            for i in 0..cols {
                let (u, v) = at(i, j);
                mask[j * cols + i] = unexplained(u, v);
            }
        }
        for patch in patches(&mut mask, cols, rows) {
            let points: Vec<[f64; 2]> = patch
                .iter()
                .map(|&k| {
                    let (u, v) = at(k % cols, k / cols);
                    [u, v]
                })
                .collect();
            let n = points.len() as f64;
            let centre = points
                .iter()
                .fold([0.0, 0.0], |c, p| [c[0] + p[0] / n, c[1] + p[1] / n]);
            // The grid points a lying bottle's outline covers about here.
            let Some(expected) = self.lying_points_near(centre, belt_top_z_m, step) else {
                continue;
            };
            if n < MIN_PATCH_SHARE * expected {
                continue;
            }
            let box_px = points.iter().fold(
                [
                    f64::INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NEG_INFINITY,
                ],
                |b, p| {
                    [
                        b[0].min(p[0] - step),
                        b[1].min(p[1] - step),
                        b[2].max(p[0] + step),
                        b[3].max(p[1] + step),
                    ]
                },
            );
            let Some(pose) = self.search(&box_px, belt_top_z_m, tubes, e) else {
                continue;
            };
            if !self.covers(&pose, &points, MIN_PATCH_COVER) {
                continue;
            }
            // A body through a bottle already seen is that bottle, seen elsewhere than its box
            // put it: one more pose of it, which the planner keeps clear of too.
            let clash = seen
                .iter_mut()
                .find(|s| s.poses.iter().any(|q| self.interpenetrate(&pose, q)));
            match clash {
                Some(sighting) => sighting.poses.push(pose),
                None => seen.push(BottleSighting {
                    detection: usize::MAX,
                    poses: vec![pose],
                }),
            }
        }
    }

    /// The grid points (`step` pixels apart) a lying bottle's outline covers with its middle
    /// under pixel `centre`.
    fn lying_points_near(&self, centre: [f64; 2], belt_top_z_m: f64, step: f64) -> Option<f64> {
        let mid = self
            .calibration
            .pixel_to_height(centre[0], centre[1], belt_top_z_m + self.radius_m)
            .ok()?;
        let pose = self.pose_at(true, 0.0, mid.x, mid.y, belt_top_z_m);
        let (a, b, r) = self.capsule(&pose)?;
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        Some((2.0 * r * length + std::f64::consts::PI * r * r) / (step * step))
    }

    /// Whether `pose`'s projected outline holds at least `share` of `points`.
    fn covers(&self, pose: &BottlePose, points: &[[f64; 2]], share: f64) -> bool {
        let Some((a, b, r)) = self.capsule(&pose.world_from_bottle) else {
            return false;
        };
        let inside = points
            .iter()
            .filter(|p| segment_distance(p, &a, &b) <= r)
            .count();
        inside as f64 >= share * points.len() as f64
    }
}

/// The 4-connected patches of set cells of a `cols` x `rows` grid (row-major), each as its cell
/// indices; the mask is cleared on the way.
fn patches(mask: &mut [bool], cols: usize, rows: usize) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    for start in 0..mask.len() {
        if !mask[start] {
            continue;
        }
        mask[start] = false;
        let mut patch = vec![start];
        let mut next = 0;
        while next < patch.len() {
            let k = patch[next];
            next += 1;
            let (i, j) = (k % cols, k / cols);
            let mut neighbours = Vec::with_capacity(4);
            if i > 0 {
                neighbours.push(k - 1);
            }
            if i + 1 < cols {
                neighbours.push(k + 1);
            }
            if j > 0 {
                neighbours.push(k - cols);
            }
            if j + 1 < rows {
                neighbours.push(k + cols);
            }
            for n in neighbours {
                if mask[n] {
                    mask[n] = false;
                    patch.push(n);
                }
            }
        }
        out.push(patch);
    }
    out
}

#[cfg(test)]
mod tests {
    use image::{Rgb, RgbImage};
    use nalgebra::{Isometry3, Point3, Vector3};

    use super::{BeltBand, patches};
    use crate::detect::Detection;
    use crate::rng::SimRng;
    use crate::station::BeltScene;
    use crate::station::bottle_evidence::{bottle_sightings, segment_distance};
    use crate::station::bottle_fit::BottleFitter;
    use crate::station::bottle_fit::tests::{BELT_TOP_Z, fitter};

    /// A 640 x 480 frame (half the calibration's pixels) of a dark belt with a bright part box
    /// and, when `bottle` is given, that bottle's outline filled bright.
    fn frame(f: &BottleFitter, bottle: Option<&Isometry3<f64>>, part: [f64; 4]) -> RgbImage {
        let capsule = bottle.and_then(|p| f.capsule(p));
        RgbImage::from_fn(640, 480, |x, y| {
            let (u, v) = (f64::from(x) * 2.0 + 1.0, f64::from(y) * 2.0 + 1.0);
            let in_part = (part[0]..=part[2]).contains(&u) && (part[1]..=part[3]).contains(&v);
            let in_bottle = capsule.is_some_and(|(a, b, r)| segment_distance(&[u, v], &a, &b) <= r);
            if in_part || in_bottle {
                Rgb([200, 200, 190])
            } else {
                Rgb([40, 40, 45])
            }
        })
    }

    /// A lying bottle the detector drew no box around, drawn over place and yaw beside a boxed
    /// part: the scan finds it where it lies. Painted the belt's colour, nothing is found; boxed
    /// and fitted, it is not found twice.
    #[test]
    fn a_bottle_without_a_box_is_found_in_the_pixels() {
        let f = fitter();
        let band = BeltBand {
            centre_y_m: -0.45,
            half_width_m: 0.16,
        };
        let part_box = [600.0, 440.0, 680.0, 520.0];
        let part = Detection {
            class_id: 0,
            class_name: "tube".into(),
            score: 0.9,
            box_px: part_box.map(|c| c as f32),
        };
        let mut rng = SimRng::new(2511);
        let mut drawn = 0;
        while drawn < 8 {
            let yaw = rng.range(0.0, std::f64::consts::PI);
            let (x, y) = (rng.range(-0.1, 0.2), rng.range(-0.53, -0.37));
            let truth = f.pose_at(true, yaw, x, y, BELT_TOP_Z);
            let Some((a, b, r)) = f.capsule(&truth) else {
                continue;
            };
            // Clear of the part's box and wholly in the frame.
            let centre = [640.0, 480.0];
            let (ends_in, near_part) = (
                [a, b]
                    .iter()
                    .all(|p| (40.0..1240.0).contains(&p[0]) && (40.0..920.0).contains(&p[1])),
                segment_distance(&centre, &a, &b) < r + 80.0,
            );
            if !ends_in || near_part {
                continue;
            }
            drawn += 1;
            let detections = vec![part.clone()];
            let image = frame(&f, Some(&truth), part_box);
            let (seen, _) = bottle_sightings(
                &f,
                &[],
                &detections,
                &image,
                (1280, 960),
                &BeltScene {
                    top_z_m: BELT_TOP_Z,
                    band: Some(band),
                    tubes: &[],
                },
            );
            assert_eq!(seen.len(), 1, "draw {drawn}: {} sightings", seen.len());
            let pose = &seen[0].poses[0];
            let middle = |p: &Isometry3<f64>| p * Point3::new(0.0, 0.0, f.height_m / 2.0);
            let off_m = (middle(&pose.world_from_bottle) - middle(&truth)).norm();
            let axis = |p: &Isometry3<f64>| p.rotation * Vector3::z();
            let off_deg = axis(&pose.world_from_bottle)
                .dot(&axis(&truth))
                .abs()
                .min(1.0)
                .acos()
                .to_degrees();
            assert!(
                pose.lying && off_m < 0.025 && off_deg < 10.0,
                "draw {drawn}: found {off_m:.3} m and {off_deg:.1} deg off (lying {})",
                pose.lying
            );
            // Without the bottle, nothing.
            let bare = frame(&f, None, part_box);
            let (none, _) = bottle_sightings(
                &f,
                &[],
                &detections,
                &bare,
                (1280, 960),
                &BeltScene {
                    top_z_m: BELT_TOP_Z,
                    band: Some(band),
                    tubes: &[],
                },
            );
            assert!(none.is_empty(), "draw {drawn}: a bottle in an empty belt");
            // Boxed, it is one sighting.
            let Some(box_px) = f.projected_box(&truth) else {
                panic!("draw {drawn}: out of view");
            };
            let bottle = Detection {
                class_id: 1,
                class_name: "bottle".into(),
                score: 0.9,
                box_px: box_px.map(|c| c as f32),
            };
            let both = vec![part.clone(), bottle];
            let (once, _) = bottle_sightings(
                &f,
                &[(1, box_px)],
                &both,
                &image,
                (1280, 960),
                &BeltScene {
                    top_z_m: BELT_TOP_Z,
                    band: Some(band),
                    tubes: &[],
                },
            );
            assert_eq!(
                once.len(),
                1,
                "draw {drawn}: a boxed bottle seen {} times",
                once.len()
            );
        }
    }

    #[test]
    fn patches_are_the_connected_cells() {
        // An L of 4 cells and two lone cells: a diagonal neighbour is not connected.
        let (cols, rows) = (5, 4);
        let mut mask = vec![false; cols * rows];
        for k in [0, 1, 5, 10, 13] {
            mask[k] = true;
        }
        mask[19] = true;
        let mut found = patches(&mut mask, cols, rows);
        for p in &mut found {
            p.sort_unstable();
        }
        assert_eq!(found, vec![vec![0, 1, 5, 10], vec![13], vec![19]]);
        assert!(mask.iter().all(|m| !m));
    }
}
