//! A bottle pose judged by its whole outline: the bottle's mesh projected through the calibrated
//! camera, cell by cell against the frame's pixels that are not the belt's.
//!
//! A box cannot tell a standing bottle seen obliquely from one lying along the view: from a
//! camera 35 degrees off the vertical, the box of a standing bottle is matched within a pixel or
//! two by a bottle lying with its cap away from the camera, its middle 60-90 mm off. The outline
//! tells them apart: under perspective a standing bottle's image widens towards its top (nearer
//! the camera), a lying one's narrows towards its far end, and the two outlines overlap by about
//! 0.8 of their union where the true pose's overlaps the pixels by 0.9 or more. The detector's box
//! is also off by 5-20 px on a bottle seen at a slant (its edge rounded, the cap's end cut, a part
//! beside it taken in), which the outline's fit to the pixels undoes.
//!
//! - A pose's **agreement** is the intersection over union of its outline and the pixels unlike
//!   the belt's, over a grid of cells around the detection. Cells outside the frame, cells a
//!   part may fill (its box and the tube's side below it, [`BottleFitter::part_column`]), and
//!   cells that show what lies beyond the belt's edges (the rails, the frame, the floor: unlike
//!   the belt whether or not a bottle stands there, [`BottleFitter::sees_belt`]) count for
//!   nothing. The cap is dark, read as belt or not: cells only the cap covers count for nothing
//!   either.
//! - A pose is **refined** by a pattern search over its place (and its yaw when lying) to the
//!   highest agreement.

use nalgebra::{Isometry3, Point3};

use super::bottle_evidence::Evidence;
use super::bottle_fit::{BottleFitter, BottlePose};
use super::measured_tube::MeasuredTube;
use crate::render::material::Material;
use crate::render::mesh::Mesh;

/// Cells along the longer side of the region a pose is judged over.
const CELLS_ALONG: f64 = 64.0;
/// The region is the detection's box grown by this share of its larger side on every side.
const REGION_GROWTH_SHARE: f64 = 0.15;
/// The refinement's first steps (place, m; yaw, rad) and how many times they are halved.
const REFINE_STEP_M: f64 = 0.008;
const REFINE_STEP_RAD: f64 = 0.06;
const REFINE_HALVINGS: usize = 4;

/// The bottle's mesh as the outline is drawn from it: each point once, and its triangles (point
/// indices), the cap's flagged.
#[derive(Debug, Clone)]
pub struct Outline {
    points: Vec<Point3<f64>>,
    triangles: Vec<([u32; 3], bool)>,
}

impl Outline {
    /// The outline of `mesh` (its triangles; those of [`Material::BOTTLE_CAP`] are the cap's).
    pub fn of_mesh(mesh: &Mesh) -> Self {
        let mut points: Vec<Point3<f64>> = Vec::new();
        let mut index_of = std::collections::HashMap::new();
        let mut triangles = Vec::with_capacity(mesh.vertices.len() / 3);
        for t in mesh.vertices.chunks_exact(3) {
            let mut tri = [0u32; 3];
            for (slot, v) in tri.iter_mut().zip(t) {
                let key = v.position.coords.map(f64::to_bits);
                let key = (key.x, key.y, key.z);
                *slot = *index_of.entry(key).or_insert_with(|| {
                    points.push(v.position);
                    (points.len() - 1) as u32
                });
            }
            triangles.push((tri, t[0].material == Material::BOTTLE_CAP));
        }
        Self { points, triangles }
    }
}

/// What the frame shows over a grid of cells (calibration pixels): per cell 0 when it counts for
/// nothing, 1 the belt, 2 not the belt.
#[derive(Debug, Clone)]
pub struct Cells {
    origin: [f64; 2],
    step: f64,
    cols: usize,
    rows: usize,
    seen: Vec<u8>,
}

impl Cells {
    /// The cells over `box_px` grown by [`REGION_GROWTH_SHARE`], read in `e`; cells inside any
    /// of `excluded` (calibration pixels), and cells where `belt` (given a cell's centre) says
    /// the belt does not show, count for nothing.
    pub fn read(
        box_px: &[f64; 4],
        e: &Evidence<'_>,
        excluded: &[[f64; 4]],
        belt: impl Fn(f64, f64) -> bool,
    ) -> Self {
        let [x0, y0, x1, y1] = *box_px;
        let g = REGION_GROWTH_SHARE * (x1 - x0).max(y1 - y0);
        let (w, h) = e.frame_px();
        let region = [
            (x0 - g).max(0.0),
            (y0 - g).max(0.0),
            (x1 + g).min(w),
            (y1 + g).min(h),
        ];
        let step = ((region[2] - region[0]).max(region[3] - region[1]) / CELLS_ALONG).max(1.0);
        let cols = ((region[2] - region[0]) / step).ceil().max(1.0) as usize;
        let rows = ((region[3] - region[1]) / step).ceil().max(1.0) as usize;
        let origin = [region[0], region[1]];
        let mut seen = vec![0u8; cols * rows];
        for j in 0..rows {
            for i in 0..cols {
                let (u, v) = (
                    origin[0] + (i as f64 + 0.5) * step,
                    origin[1] + (j as f64 + 0.5) * step,
                );
                if excluded
                    .iter()
                    .any(|b| (b[0]..=b[2]).contains(&u) && (b[1]..=b[3]).contains(&v))
                    || !belt(u, v)
                {
                    continue;
                }
                seen[j * cols + i] = match e.foreground(u, v) {
                    Some(true) => 2,
                    Some(false) => 1,
                    None => 0,
                };
            }
        }
        Self {
            origin,
            step,
            cols,
            rows,
            seen,
        }
    }

    /// How many cells show something other than the belt.
    pub fn foreground(&self) -> usize {
        self.seen.iter().filter(|&&s| s == 2).count()
    }
}

impl BottleFitter {
    /// The agreement (intersection over union, over the cells that count) of the outline of the
    /// bottle at `world_from_bottle` with `cells`' pixels unlike the belt; `None` when a point of
    /// it is behind the camera or no cell counts.
    pub fn agreement(&self, world_from_bottle: &Isometry3<f64>, cells: &Cells) -> Option<f64> {
        let c = &self.calibration;
        let camera_from_bottle = c.world_from_camera.inverse() * world_from_bottle;
        let mut uv = Vec::with_capacity(self.outline.points.len());
        for p in &self.outline.points {
            let q = camera_from_bottle * p;
            if q.z <= 0.0 {
                return None;
            }
            uv.push([
                (c.fx_px * q.x / q.z + c.cx_px - cells.origin[0]) / cells.step - 0.5,
                (c.fy_px * q.y / q.z + c.cy_px - cells.origin[1]) / cells.step - 0.5,
            ]);
        }
        // Per cell: 1 the body covers it, 2 only the cap does.
        let mut cover = vec![0u8; cells.seen.len()];
        for &(tri, cap) in &self.outline.triangles {
            let [a, b, d] = tri.map(|k| uv[k as usize]);
            fill_triangle(&a, &b, &d, cells.cols, cells.rows, |k| {
                if !cap {
                    cover[k] = 1;
                } else if cover[k] == 0 {
                    cover[k] = 2;
                }
            });
        }
        let (mut both, mut either) = (0usize, 0usize);
        for (&s, &o) in cells.seen.iter().zip(&cover) {
            if s == 0 || o == 2 {
                continue;
            }
            let (fg, body) = (s == 2, o == 1);
            both += usize::from(fg && body);
            either += usize::from(fg || body);
        }
        (either > 0).then(|| both as f64 / either as f64)
    }

    /// `pose_at(x, y, yaw)` refined from `(x, y, yaw)` to the highest agreement with `cells` by a
    /// pattern search (the yaw held when `turn` is false): the place, the yaw and the agreement.
    pub(super) fn refine(
        &self,
        start: (f64, f64, f64),
        turn: bool,
        cells: &Cells,
        pose_at: impl Fn(f64, f64, f64) -> Isometry3<f64>,
    ) -> Option<((f64, f64, f64), f64)> {
        // A step back to a place already judged (the move before, undone) is not judged
        // again: the same place, to the bit, has the same agreement.
        let mut judged: Vec<([u64; 3], Option<f64>)> = Vec::new();
        let mut score = |s: (f64, f64, f64)| {
            let key = [s.0.to_bits(), s.1.to_bits(), s.2.to_bits()];
            if let Some((_, a)) = judged.iter().find(|(k, _)| *k == key) {
                return *a;
            }
            let a = self.agreement(&pose_at(s.0, s.1, s.2), cells);
            judged.push((key, a));
            a
        };
        let mut best = (start, score(start)?);
        let (mut step, mut turn_step) = (REFINE_STEP_M, REFINE_STEP_RAD);
        for _ in 0..=REFINE_HALVINGS {
            loop {
                let (x, y, yaw) = best.0;
                let mut moves = vec![
                    (x + step, y, yaw),
                    (x - step, y, yaw),
                    (x, y + step, yaw),
                    (x, y - step, yaw),
                ];
                if turn {
                    moves.push((x, y, yaw + turn_step));
                    moves.push((x, y, yaw - turn_step));
                }
                let mut improved = false;
                for m in moves {
                    if let Some(a) = score(m)
                        && a > best.1
                    {
                        best = (m, a);
                        improved = true;
                    }
                }
                if !improved {
                    break;
                }
            }
            step /= 2.0;
            turn_step /= 2.0;
        }
        Some(best)
    }
}

/// A triangle's bounding box this many cells wide or less is searched row by row without
/// solving where its edges cross each row.
const NARROW_CELLS: i64 = 4;

/// Calls `mark` with the index of every cell of a `cols` x `rows` grid whose centre lies in the
/// triangle `a`, `b`, `c` (cell coordinates: cell `(i, j)`'s centre is at `(i, j)`), by the
/// test of a centre against each edge, `((q - p) x (centre - p)) * sign(area) >= 0`.
///
/// Along a row each edge's test, in floating point as exactly, passes on a prefix or a suffix
/// of the cells (its value is monotone in the cell's x: every operation rounds monotonically),
/// so the cells that pass all three are one run. Each row's run is found by testing from either
/// end of the span between the edges' crossings of the row, widened by a cell each way against
/// rounding; the cells are exactly those of a test of every cell in the triangle's bounding box
/// (mostly outside a long, thin triangle's), at the cost of its outline.
fn fill_triangle(
    a: &[f64; 2],
    b: &[f64; 2],
    c: &[f64; 2],
    cols: usize,
    rows: usize,
    mut mark: impl FnMut(usize),
) {
    let i0 = ceil_i(a[0].min(b[0]).min(c[0])).max(0);
    let i1 = floor_i(a[0].max(b[0]).max(c[0])).min(cols as i64 - 1);
    let j0 = ceil_i(a[1].min(b[1]).min(c[1])).max(0);
    let j1 = floor_i(a[1].max(b[1]).max(c[1])).min(rows as i64 - 1);
    if i0 > i1 || j0 > j1 {
        return;
    }
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if area == 0.0 {
        return;
    }
    let sign = area.signum();
    // Per edge p -> q: p, q - p, its run per unit of rise (where it crosses a row: not finite
    // for an edge along a row), and whether the triangle lies left of that crossing (the
    // crossing an upper bound) or right.
    let edges = [(a, b), (b, c), (c, a)].map(|(p, q)| {
        let (run, rise) = (q[0] - p[0], q[1] - p[1]);
        (*p, run, rise, run / rise, rise * sign > 0.0)
    });
    // A narrow box's rows are searched whole; a wide one's narrowed first.
    let narrow = i1 - i0 <= NARROW_CELLS;
    for j in j0..=j1 {
        let y = j as f64;
        // Per edge, the part of its test that is the row's.
        let along = edges.map(|(p, run, _, _, _)| run * (y - p[1]));
        let passes = |i: i64| {
            let x = i as f64;
            edges
                .iter()
                .zip(&along)
                .all(|((p, _, rise, _, _), t)| (t - rise * (x - p[0])) * sign >= 0.0)
        };
        let (mut lo, mut hi) = (i0, i1);
        if !narrow {
            for (p, _, _, run_per_rise, upper) in edges {
                let x = p[0] + run_per_rise * (y - p[1]);
                if !x.is_finite() {
                    continue;
                }
                if upper {
                    hi = hi.min(floor_i(x).saturating_add(1));
                } else {
                    lo = lo.max(ceil_i(x).saturating_sub(1));
                }
            }
        }
        let Some(first) = (lo..=hi).find(|&i| passes(i)) else {
            continue;
        };
        let last = (first..=hi).rev().find(|&i| passes(i)).unwrap_or(first);
        let row = j as usize * cols;
        for i in first..=last {
            mark(row + i as usize);
        }
    }
}

/// The largest integer not above `x` (saturating far outside `i64`'s range), without a call to
/// the C library's `floor` (the build's baseline x86-64 has no rounding instruction).
fn floor_i(x: f64) -> i64 {
    let t = x as i64;
    if t as f64 > x { t.saturating_sub(1) } else { t }
}

/// The smallest integer not below `x` (saturating as [`floor_i`]).
fn ceil_i(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) < x {
        t.saturating_add(1)
    } else {
        t
    }
}

/// Lying hypotheses refined besides the standing one: the best by agreement at distinct yaws.
const LYING_REFINED: usize = 2;
/// Lying hypotheses whose axes lie within this angle of each other (either way along) are one.
const DISTINCT_YAW_RAD: f64 = 0.3;
/// Refined poses whose agreement lies within this of the best one's are all kept: the pixels
/// cannot tell them apart.
const AMBIGUITY_AGREEMENT: f64 = 0.02;

impl BottleFitter {
    /// The place under the bottle's middle and its yaw (0 standing) of a pose of [`Self::pose_at`].
    fn place_of(&self, pose: &BottlePose) -> (f64, f64, f64) {
        let w = &pose.world_from_bottle;
        let middle = w * Point3::new(0.0, 0.0, self.height_m / 2.0);
        let axis = w.rotation * nalgebra::Vector3::z();
        let yaw = if pose.lying {
            axis.y.atan2(axis.x)
        } else {
            0.0
        };
        (middle.x, middle.y, yaw)
    }

    /// `pose` refined to the highest agreement with `cells`, its box residual to `box_px` read
    /// again; with its agreement.
    fn refined(
        &self,
        pose: &BottlePose,
        box_px: &[f64; 4],
        belt_top_z_m: f64,
        cells: &Cells,
    ) -> Option<(BottlePose, f64)> {
        let lying = pose.lying;
        let pose_at = |x, y, yaw| self.pose_at(lying, yaw, x, y, belt_top_z_m);
        let ((x, y, yaw), agreement) = self.refine(self.place_of(pose), lying, cells, pose_at)?;
        let world_from_bottle = self.pose_at(lying, yaw, x, y, belt_top_z_m);
        let residual_px = self
            .projected_box(&world_from_bottle)
            .map_or(f64::INFINITY, |b| {
                super::silhouette::box_residual_px(&b, box_px)
            });
        Some((
            BottlePose {
                world_from_bottle,
                lying,
                residual_px,
            },
            agreement,
        ))
    }

    /// The poses among `candidates` (a box fit's hypotheses whose boxes explain `box_px`) that
    /// the outline bears out, refined: each is judged by its agreement with `cells`; the best
    /// standing and the best lying at [`LYING_REFINED`] distinct yaws are refined; the best of
    /// those, and any other within [`AMBIGUITY_AGREEMENT`] of it, are returned best first, with
    /// the best agreement. `None` when no hypothesis can be judged, or every refined one passes
    /// through one of `tubes`. A `hidden` hypothesis (a standing bottle the frame's border may
    /// cut, whose box does not explain the detection's) is refined and judged beside them when
    /// any of them is left: it can outdo them, not stand in for them.
    pub(super) fn by_outline(
        &self,
        candidates: &[BottlePose],
        hidden: Option<&BottlePose>,
        box_px: &[f64; 4],
        belt_top_z_m: f64,
        tubes: &[MeasuredTube],
        cells: &Cells,
    ) -> Option<(Vec<BottlePose>, f64)> {
        let mut judged: Vec<(BottlePose, f64)> = candidates
            .iter()
            .filter_map(|p| Some((*p, self.agreement(&p.world_from_bottle, cells)?)))
            .collect();
        judged.sort_by(|a, b| b.1.total_cmp(&a.1));
        let mut starts: Vec<BottlePose> = Vec::new();
        if let Some((standing, _)) = judged.iter().find(|(p, _)| !p.lying) {
            starts.push(*standing);
        }
        let mut yaws: Vec<f64> = Vec::new();
        for (p, _) in judged.iter().filter(|(p, _)| p.lying) {
            if yaws.len() >= LYING_REFINED {
                break;
            }
            let yaw = self.place_of(p).2;
            let distinct = yaws.iter().all(|y| {
                let d = (yaw - y).rem_euclid(std::f64::consts::PI);
                d.min(std::f64::consts::PI - d) > DISTINCT_YAW_RAD
            });
            if distinct {
                yaws.push(yaw);
                starts.push(*p);
            }
        }
        let mut refined: Vec<(BottlePose, f64)> = starts
            .iter()
            .filter_map(|p| self.refined(p, box_px, belt_top_z_m, cells))
            // Refined through a measured tube: impossible.
            .filter(|(p, _)| {
                !tubes
                    .iter()
                    .any(|t| self.passes_through(&p.world_from_bottle, t, belt_top_z_m))
            })
            .collect();
        if !refined.is_empty()
            && let Some(hidden) = hidden.and_then(|p| self.refined(p, box_px, belt_top_z_m, cells))
            && !tubes
                .iter()
                .any(|t| self.passes_through(&hidden.0.world_from_bottle, t, belt_top_z_m))
        {
            refined.push(hidden);
        }
        refined.sort_by(|a, b| b.1.total_cmp(&a.1));
        let best = refined.first()?.1;
        let mut kept: Vec<BottlePose> = Vec::new();
        for (pose, agreement) in refined {
            if agreement < best - AMBIGUITY_AGREEMENT {
                break;
            }
            if !kept.iter().any(|k| self.same_cylinder(k, &pose)) {
                kept.push(pose);
            }
        }
        Some((kept, best))
    }
}

#[cfg(test)]
mod tests {
    use super::fill_triangle;
    use crate::rng::SimRng;

    /// The cells whose centres pass all three edge tests, found by testing every cell of the
    /// grid: what the row spans must give.
    fn every_cell(
        a: &[f64; 2],
        b: &[f64; 2],
        c: &[f64; 2],
        cols: usize,
        rows: usize,
    ) -> Vec<usize> {
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area == 0.0 {
            return Vec::new();
        }
        let edge = |p: &[f64; 2], q: &[f64; 2], x: f64, y: f64| {
            ((q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0])) * area.signum()
        };
        (0..rows * cols)
            .filter(|k| {
                let (x, y) = ((k % cols) as f64, (k / cols) as f64);
                edge(a, b, x, y) >= 0.0 && edge(b, c, x, y) >= 0.0 && edge(c, a, x, y) >= 0.0
            })
            .collect()
    }

    #[test]
    fn a_triangle_fills_exactly_the_cells_whose_centres_it_holds() {
        let mut rng = SimRng::new(29);
        let (cols, rows) = (64, 48);
        let mut filled_any = 0;
        for n in 0..6000 {
            // Triangles of every size and slant, some reaching past the grid: a third of them
            // small (a mesh's usual, within a few cells), a third long thin slivers; a quarter
            // with corners on cell centres, where the tests are ties.
            let on_centres = n % 4 == 0;
            let span = if n % 3 == 1 { 5.0 } else { 100.0 };
            let a = [rng.range(-20.0, 84.0), rng.range(-20.0, 68.0)];
            let near = |rng: &mut SimRng, reach: f64| {
                [
                    a[0] + rng.range(-reach, reach),
                    a[1] + rng.range(-reach, reach),
                ]
            };
            let b = if n % 3 == 0 {
                near(&mut rng, 0.5)
            } else {
                near(&mut rng, span)
            };
            let c = near(&mut rng, span);
            let [a, b, c] = [a, b, c].map(|p| if on_centres { p.map(f64::round) } else { p });
            let mut got = Vec::new();
            fill_triangle(&a, &b, &c, cols, rows, |k| got.push(k));
            let want = every_cell(&a, &b, &c, cols, rows);
            assert_eq!(got, want, "triangle {a:?} {b:?} {c:?}");
            filled_any += usize::from(!want.is_empty());
        }
        assert!(
            filled_any > 2000,
            "only {filled_any} triangles cover a cell"
        );
    }
}
