//! Where a bottle stands (or lies) on the belt, from the box a detector drew around it: the
//! bottle's mesh is projected through the calibrated camera in candidate poses and slid over the
//! belt until its box matches the detection.

use image::RgbImage;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use super::bottle_outline::Outline;
use super::bottle_unboxed::BeltBand;
use super::silhouette::{CutBox, Silhouette, box_residual_px};
use crate::camera::CameraCalibration;
use crate::render::mesh::Mesh;
use crate::scenario::BottleSection;

/// How high what runs along the belt's edges (its rails) may stand above its top, m.
const EDGE_HEIGHT_M: f64 = 0.03;
/// Yaw steps of the lying-bottle search over a full turn.
const LYING_YAW_STEPS: usize = 180;
/// A hypothesis within this box residual of the best one is kept as well, pixels.
const AMBIGUITY_PX: f64 = 2.0;
/// A box side within this share of the frame's width (height) of its border is cut by it.
pub(super) const CUT_SHARE: f64 = 0.01;
/// A box side within this share of the frame's width (height) of its border touches it: the
/// bottle runs on out of the frame.
const TOUCH_SHARE: f64 = 0.003;

/// A lying pose whose axis the image supports less than this share of the best lying pose's
/// is taken for that one's mirror image in the box, and dropped.
const MIRROR_SUPPORT_SHARE: f64 = 0.5;
/// The best lying pose's axis must stand out from the belt around the box by this much (mean
/// RGB distance, 8-bit levels) for the image to decide between mirrored poses.
const MIN_AXIS_CONTRAST: f64 = 16.0;
/// Points sampled along a pose's axis, and the ring around the box the belt is read from,
/// pixels (inside, outside).
const AXIS_SAMPLES: usize = 24;
const RING_PX: (f64, f64) = (3.0, 9.0);

/// One pose of the bottle that explains its detected box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BottlePose {
    /// The bottle's pose (origin at its base centre, its axis along local z).
    pub world_from_bottle: Isometry3<f64>,
    /// Lying on its side.
    pub lying: bool,
    /// RMS distance between the box this pose projects to and the detected box, pixels.
    pub residual_px: f64,
}

/// Facets around the bottle of the outline and the box a pose is judged by: a box or an outline
/// is projected thousands of times per frame (about a tenth of a camera trial's instructions
/// with the renderer's 64), and the 32-gon's corners are every other one of the rendered
/// 64-gon's, within 0.4 % of its radius (0.12 mm on the default bottle) of its sides: a tenth
/// of a cell of the outline's grid or less.
const OUTLINE_SEGMENTS: usize = 32;

/// Fits bottle poses to detected boxes for one calibrated camera and one bottle model.
#[derive(Debug, Clone)]
pub struct BottleFitter {
    pub(super) calibration: CameraCalibration,
    pub(super) radius_m: f64,
    pub(super) height_m: f64,
    /// The vertices of the bottle's mesh in its own frame.
    silhouette: Silhouette,
    /// Points inside the bottle's body, off its cap, in its own frame (the image's support of
    /// a pose is read at their projections).
    pub(super) body_points: Vec<Point3<f64>>,
    /// The mesh a pose's outline is drawn from ([`Self::agreement`]).
    pub(super) outline: Outline,
    /// The tallest part the cell handles, m: a part's box and the tube's side below it, down to
    /// the belt, are the part's pixels, not a bottle's ([`Self::part_column`]).
    pub(super) part_height_m: f64,
    /// The belt the bottles stand on: pixels that show what lies beyond its edges are not read
    /// against the belt's colour ([`Self::sees_belt`]).
    pub(super) belt: Option<BeltBand>,
    /// The frame the boxes come from, px: a box its border cuts also gets a standing
    /// hypothesis placed by its whole sides (`None`: none).
    pub(super) frame_px: Option<(f64, f64)>,
}

impl BottleFitter {
    /// A fitter for `bottle` seen by `calibration`.
    pub fn new(calibration: CameraCalibration, bottle: &BottleSection) -> Self {
        // The mesh repeats vertices per face; the silhouette keeps each point once.
        let mesh = Mesh::bottle(bottle.radius_m, bottle.height_m);
        let points: Vec<Point3<f64>> = mesh.vertices.iter().map(|v| v.position).collect();
        let coarse = Mesh::bottle_lathe(bottle.radius_m, bottle.height_m, OUTLINE_SEGMENTS);
        Self {
            calibration,
            radius_m: bottle.radius_m,
            height_m: bottle.height_m,
            silhouette: Silhouette::of_hull_points(coarse.vertices.iter().map(|v| v.position)),
            body_points: body_points(&points, bottle.height_m),
            outline: Outline::of_mesh(&coarse),
            part_height_m: 0.0,
            belt: None,
            frame_px: None,
        }
    }

    /// The fitter with its boxes from a `width_px` x `height_px` frame: a box the frame's
    /// border cuts also gets a standing hypothesis placed by the sides the border leaves whole.
    pub fn with_frame(mut self, width_px: u32, height_px: u32) -> Self {
        self.frame_px = Some((f64::from(width_px), f64::from(height_px)));
        self
    }

    /// The fitter with the bottles on `belt` (without, every pixel is read against the belt's
    /// colour).
    pub fn with_belt(mut self, belt: BeltBand) -> Self {
        self.belt = Some(belt);
        self
    }

    /// Whether calibration pixel `(u, v)` shows the belt whose top is at `belt_top_z_m` when no
    /// bottle or part stands there: its ray meets the belt's top, and the height of the rails
    /// along its edges (30 mm), between the edges. Beyond them lie the rails, the
    /// frame and the floor, unlike the belt whether or not a bottle is there.
    pub fn sees_belt(&self, u: f64, v: f64, belt_top_z_m: f64) -> bool {
        let Some(band) = self.belt else {
            return true;
        };
        [belt_top_z_m, belt_top_z_m + EDGE_HEIGHT_M]
            .iter()
            .all(|&z| {
                self.calibration
                    .pixel_to_height(u, v, z)
                    .is_ok_and(|p| (p.y - band.centre_y_m).abs() <= band.half_width_m)
            })
    }

    /// The fitter with parts up to `height_m` tall beside the bottles (without, a part's pixels
    /// are taken to be its box's alone).
    pub fn with_part_height(mut self, height_m: f64) -> Self {
        self.part_height_m = height_m.max(0.0);
        self
    }

    /// Where in the image a part whose end face the detector boxed at `box_px` may show: the box
    /// and the tube's side below it down to the belt at `belt_top_z_m` (the end face taken at
    /// the tallest part's height), as one box.
    pub fn part_column(&self, box_px: &[f64; 4], belt_top_z_m: f64) -> [f64; 4] {
        let [x0, y0, x1, y1] = *box_px;
        let mut column = *box_px;
        let top_z = belt_top_z_m + self.part_height_m;
        for (u, v) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
            let Ok(top) = self.calibration.pixel_to_height(u, v, top_z) else {
                continue;
            };
            let Some([du, dv]) = self
                .calibration
                .project(&Point3::new(top.x, top.y, belt_top_z_m))
            else {
                continue;
            };
            column = [
                column[0].min(du),
                column[1].min(dv),
                column[2].max(du),
                column[3].max(dv),
            ];
        }
        column
    }

    /// The box (`[x0, y0, x1, y1]`, pixels) the bottle at `world_from_bottle` projects to, or
    /// `None` when a point of it is not in front of the camera.
    pub fn projected_box(&self, world_from_bottle: &Isometry3<f64>) -> Option<[f64; 4]> {
        self.silhouette
            .projected_box(&self.calibration, world_from_bottle)
    }

    /// The pose of a bottle standing (`lying` false) or lying at `yaw_rad` with its middle over
    /// `(x, y)` on a belt whose top is at `belt_top_z_m`.
    pub(super) fn pose_at(
        &self,
        lying: bool,
        yaw_rad: f64,
        x: f64,
        y: f64,
        belt_top_z_m: f64,
    ) -> Isometry3<f64> {
        if lying {
            Isometry3::from_parts(
                Translation3::new(x, y, belt_top_z_m + self.radius_m),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad)
                    * UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
            ) * Isometry3::translation(0.0, 0.0, -self.height_m / 2.0)
        } else {
            Isometry3::translation(x, y, belt_top_z_m)
        }
    }

    /// Poses (standing, or lying at any yaw) that explain `box_px`: each hypothesis is slid over
    /// the belt until its projected box is centred on the detection, then scored by the RMS
    /// difference of the four sides. The best pose and every distinct pose within
    /// `AMBIGUITY_PX` (2 px) of it are returned, best first: a lying bottle seen from above can look
    /// the same at mirrored yaws, and the planner must keep clear of each.
    pub fn fit(&self, box_px: &[f64; 4], belt_top_z_m: f64) -> Vec<BottlePose> {
        self.fit_among(self.fit_candidates(box_px, belt_top_z_m))
    }

    /// Of `poses` from [`Self::fit_candidates`] (best box first), the best and every distinct
    /// pose within `AMBIGUITY_PX` of it: what [`Self::fit`] returns.
    pub(super) fn fit_among(&self, poses: Vec<BottlePose>) -> Vec<BottlePose> {
        let best = poses.first().map_or(0.0, |p| p.residual_px);
        let mut kept: Vec<BottlePose> = Vec::new();
        for pose in poses {
            if pose.residual_px > best + AMBIGUITY_PX {
                break;
            }
            if !kept.iter().any(|k| self.same_cylinder(k, &pose)) {
                kept.push(pose);
            }
        }
        kept
    }

    /// Every hypothesis of [`Self::fit`] (standing, and lying at each of its yaws) slid over the
    /// belt until its box is centred on `box_px`'s, best box first.
    pub(super) fn fit_candidates(&self, box_px: &[f64; 4], belt_top_z_m: f64) -> Vec<BottlePose> {
        let centre = [(box_px[0] + box_px[2]) / 2.0, (box_px[1] + box_px[3]) / 2.0];
        let mut hypotheses = vec![(false, 0.0)];
        hypotheses.extend(lying_yaws().map(|yaw| (true, yaw)));
        let mut poses: Vec<BottlePose> = Vec::new();
        for (lying, yaw) in hypotheses {
            let mid_z = self.mid_z(lying, belt_top_z_m);
            let pose_at = |x, y| self.pose_at(lying, yaw, x, y, belt_top_z_m);
            let Some(([x, y], b)) =
                self.silhouette
                    .slide_to_centre(&self.calibration, centre, mid_z, pose_at)
            else {
                continue;
            };
            let residual_px = box_residual_px(&b, box_px);
            poses.push(BottlePose {
                world_from_bottle: self.pose_at(lying, yaw, x, y, belt_top_z_m),
                lying,
                residual_px,
            });
        }
        // A box the frame's border cuts: centred on the cut box, a standing bottle lands tens of
        // millimetres in from the border, so it is also placed by the sides the border leaves
        // whole, its box clipped to the frame.
        let cut = self
            .frame_px
            .and_then(|frame| CutBox::of(box_px, frame, CUT_SHARE));
        if let Some(cut) = cut {
            poses.extend(self.by_cut_sides(&cut, box_px, (false, 0.0), belt_top_z_m));
        }
        poses.sort_by(|a, b| a.residual_px.total_cmp(&b.residual_px));
        poses
    }

    /// Lying hypotheses at each yaw placed by the sides of `box_px` that the frame's border
    /// leaves whole (as [`Self::fit_candidates`] places a standing one), best box first; none
    /// when the box does not reach the border. Centred on the cut box, a lying bottle whose end
    /// the border cuts off lands where its box cannot match the detection's.
    pub(super) fn cut_lying_candidates(
        &self,
        box_px: &[f64; 4],
        belt_top_z_m: f64,
    ) -> Vec<BottlePose> {
        let Some(cut) = self
            .frame_px
            .and_then(|frame| CutBox::of(box_px, frame, TOUCH_SHARE))
        else {
            return Vec::new();
        };
        let mut poses: Vec<BottlePose> = lying_yaws()
            .filter_map(|yaw| self.by_cut_sides(&cut, box_px, (true, yaw), belt_top_z_m))
            .collect();
        poses.sort_by(|a, b| a.residual_px.total_cmp(&b.residual_px));
        poses
    }

    /// The world z of the middle of a standing (`lying` false) or lying bottle
    /// on a belt whose top is at `belt_top_z_m`.
    pub(super) fn mid_z(&self, lying: bool, belt_top_z_m: f64) -> f64 {
        belt_top_z_m
            + if lying {
                self.radius_m
            } else {
                self.height_m / 2.0
            }
    }

    /// The hypothesis `(lying, yaw)` slid over the belt until the sides of `cut` (the detection
    /// `box_px`, cut by the frame's border) that the border leaves whole match its box, with
    /// its residual to `box_px`; `None` when it leaves the camera's view.
    fn by_cut_sides(
        &self,
        cut: &CutBox,
        box_px: &[f64; 4],
        (lying, yaw): (bool, f64),
        belt_top_z_m: f64,
    ) -> Option<BottlePose> {
        let pose_at = |x, y| self.pose_at(lying, yaw, x, y, belt_top_z_m);
        let mid_z = self.mid_z(lying, belt_top_z_m);
        let ([x, y], b) =
            self.silhouette
                .slide_to_cut_box(&self.calibration, cut, mid_z, pose_at)?;
        Some(BottlePose {
            world_from_bottle: pose_at(x, y),
            lying,
            residual_px: box_residual_px(&b, box_px),
        })
    }

    /// `poses` (a [`Self::fit`] to `box_px`) less the lying ones the image contradicts. A box
    /// cannot tell a bottle lying along one of its diagonals from one along the other; the
    /// pixels can: along the true pose's axis they are the bottle's, along its mirror's mostly
    /// the belt's. Each lying pose's axis is sampled in `image` (whose pixels are `scale`
    /// calibration pixels each) and compared with the belt read on a ring around the box;
    /// poses whose axis differs from the belt less than half as much as the best one's are
    /// dropped. When even the best axis hardly stands out (a bottle the belt's colour), or the
    /// ring cannot be read, every pose is kept.
    pub fn keep_supported(
        &self,
        poses: Vec<BottlePose>,
        box_px: &[f64; 4],
        image: &RgbImage,
        scale: f64,
    ) -> Vec<BottlePose> {
        if poses.iter().filter(|p| p.lying).count() < 2 {
            return poses;
        }
        let (w, h) = (f64::from(image.width()), f64::from(image.height()));
        let pixel = |u: f64, v: f64| {
            let (x, y) = (u * scale, v * scale);
            (x >= 0.0 && y >= 0.0 && x < w && y < h).then(|| {
                let p = image.get_pixel(x as u32, y as u32).0;
                [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]
            })
        };
        let Some(belt) = ring_median(box_px, pixel) else {
            return poses;
        };
        let distance = |c: [f64; 3]| {
            ((c[0] - belt[0]).powi(2) + (c[1] - belt[1]).powi(2) + (c[2] - belt[2]).powi(2)).sqrt()
        };
        let support = |pose: &BottlePose| {
            let at = |t: f64| {
                self.calibration
                    .project(&(pose.world_from_bottle * Point3::new(0.0, 0.0, t * self.height_m)))
            };
            let (Some(a), Some(b)) = (at(0.1), at(0.9)) else {
                return 0.0;
            };
            let samples: Vec<f64> = (0..AXIS_SAMPLES)
                .filter_map(|k| {
                    let t = k as f64 / (AXIS_SAMPLES - 1) as f64;
                    pixel(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])).map(distance)
                })
                .collect();
            if samples.is_empty() {
                0.0
            } else {
                samples.iter().sum::<f64>() / samples.len() as f64
            }
        };
        let scored: Vec<(BottlePose, f64)> = poses
            .into_iter()
            .map(|p| {
                let s = if p.lying { support(&p) } else { 0.0 };
                (p, s)
            })
            .collect();
        let best = scored
            .iter()
            .filter(|(p, _)| p.lying)
            .map(|(_, s)| *s)
            .fold(0.0, f64::max);
        scored
            .into_iter()
            .filter(|(p, s)| {
                best < MIN_AXIS_CONTRAST || !p.lying || *s >= MIRROR_SUPPORT_SHARE * best
            })
            .map(|(p, _)| p)
            .collect()
    }

    /// Whether two poses occupy nearly the same bounding cylinder (the planner's view of a
    /// bottle, the same whichever end is the base): axes within 10 degrees, middles within 1 cm.
    pub(super) fn same_cylinder(&self, a: &BottlePose, b: &BottlePose) -> bool {
        let axis = |p: &BottlePose| p.world_from_bottle.rotation * Vector3::z();
        let middle =
            |p: &BottlePose| p.world_from_bottle * Point3::new(0.0, 0.0, self.height_m / 2.0);
        a.lying == b.lying
            && axis(a).dot(&axis(b)).abs() > 10f64.to_radians().cos()
            && (middle(a) - middle(b)).norm() < 0.01
    }
}

/// Levels along the axis and points around it of [`BottleFitter::body_points`], the share of
/// the height they span (the dark cap above it left out), and the share of the body's local
/// radius they lie at.
const BODY_LEVELS: usize = 16;
const BODY_ANGLES: usize = 6;
const BODY_SPAN: (f64, f64) = (0.04, 0.88);
const BODY_DEPTH: f64 = 0.6;

/// The yaws of the lying hypotheses, [`LYING_YAW_STEPS`] over a full turn, rad.
fn lying_yaws() -> impl Iterator<Item = f64> {
    (0..LYING_YAW_STEPS).map(|k| std::f64::consts::TAU * k as f64 / LYING_YAW_STEPS as f64)
}

/// Points inside a lathed body of `height_m` whose surface points are `surface` (its own
/// frame, axis along z): at each level the body's radius there is the widest surface point
/// within half a level's spacing.
fn body_points(surface: &[Point3<f64>], height_m: f64) -> Vec<Point3<f64>> {
    let spacing = height_m * (BODY_SPAN.1 - BODY_SPAN.0) / (BODY_LEVELS - 1) as f64;
    let mut points = Vec::new();
    for level in 0..BODY_LEVELS {
        let z = height_m * BODY_SPAN.0 + spacing * level as f64;
        let radius = surface
            .iter()
            .filter(|p| (p.z - z).abs() <= spacing)
            .map(|p| p.x.hypot(p.y))
            .fold(0.0, f64::max);
        for k in 0..BODY_ANGLES {
            let a = std::f64::consts::TAU * k as f64 / BODY_ANGLES as f64;
            let r = BODY_DEPTH * radius;
            points.push(Point3::new(r * a.cos(), r * a.sin(), z));
        }
    }
    points
}

/// The median colour of the pixels on a ring `RING_PX` outside `box_px` (`pixel` reads one,
/// `None` outside the image), or `None` when too few lie in the image.
fn ring_median(
    box_px: &[f64; 4],
    pixel: impl Fn(f64, f64) -> Option<[f64; 3]>,
) -> Option<[f64; 3]> {
    let [x0, y0, x1, y1] = *box_px;
    let mut ring = Vec::new();
    let mut d = RING_PX.0;
    while d <= RING_PX.1 {
        let steps = 32;
        for k in 0..=steps {
            let t = f64::from(k) / f64::from(steps);
            let (u, v) = (
                x0 - d + t * (x1 - x0 + 2.0 * d),
                y0 - d + t * (y1 - y0 + 2.0 * d),
            );
            ring.extend(pixel(u, y0 - d));
            ring.extend(pixel(u, y1 + d));
            ring.extend(pixel(x0 - d, v));
            ring.extend(pixel(x1 + d, v));
        }
        d += 3.0;
    }
    if ring.len() < 16 {
        return None;
    }
    let mut median = [0.0; 3];
    for (c, m) in median.iter_mut().enumerate() {
        let mut channel: Vec<f64> = ring.iter().map(|p| p[c]).collect();
        channel.sort_by(f64::total_cmp);
        *m = channel[channel.len() / 2];
    }
    Some(median)
}

#[cfg(test)]
#[path = "cut_lying_tests.rs"]
mod cut_lying_tests;

#[cfg(test)]
pub(super) mod tests {
    use image::Rgb;
    use nalgebra::Vector3;

    use super::*;
    use crate::rng::SimRng;
    use crate::station::silhouette::CutBox;

    pub(in crate::station) const BELT_TOP_Z: f64 = 0.70;

    /// The default camera: 0.58 m above the station, 44 degrees across 1280 x 960 pixels.
    pub(in crate::station) fn fitter() -> BottleFitter {
        let station = Point3::new(0.05, -0.45, BELT_TOP_Z);
        let eye = station + Vector3::new(0.0, 0.0, 0.58);
        let pose = CameraCalibration::look_at(&eye, &station, &Vector3::x()).expect("pose");
        let calibration =
            CameraCalibration::from_fov(1280, 960, 44f64.to_radians(), pose, BELT_TOP_Z);
        let bottle = BottleSection {
            radius_m: 0.033,
            height_m: 0.2,
            ..BottleSection::default()
        };
        BottleFitter::new(calibration, &bottle)
    }

    /// A 640 x 480 frame (half the calibration's pixels) of a belt of `belt` with the bottle
    /// at `pose` painted `paint` over its outline's points and the axis between them.
    fn frame(f: &BottleFitter, pose: &Isometry3<f64>, belt: u8, paint: u8) -> RgbImage {
        let mut image = RgbImage::from_pixel(640, 480, Rgb([belt, belt, belt]));
        for k in 0..=400 {
            let t = f64::from(k) / 400.0;
            for (dx, dy) in [(0.0, 0.0), (0.0, 1.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0)] {
                let local =
                    Point3::new(dx * f.radius_m * 0.9, dy * f.radius_m * 0.9, t * f.height_m);
                if let Some([u, v]) = f.calibration.project(&(pose * local)) {
                    let (x, y) = ((u / 2.0) as u32, (v / 2.0) as u32);
                    if x < 640 && y < 480 {
                        image.put_pixel(x, y, Rgb([paint, paint, paint]));
                    }
                }
            }
        }
        image
    }

    /// A lying bottle drawn over place and diagonal yaw: its box fits the pose and its mirror
    /// about equally; the pixels keep the true one and drop the mirror. A bottle painted the
    /// belt's colour decides nothing: both stay.
    #[test]
    fn the_image_tells_a_lying_bottle_from_its_mirror_in_the_box() {
        let f = fitter();
        let mut rng = SimRng::new(2503);
        for draw in 0..12 {
            let yaw = rng.range(0.3, 1.2) + if draw % 2 == 0 { 0.0 } else { 1.57 };
            let (x, y) = (rng.range(-0.05, 0.15), rng.range(-0.5, -0.4));
            let truth = f.pose_at(true, yaw, x, y, BELT_TOP_Z);
            let mirror = f.pose_at(true, -yaw, x, y, BELT_TOP_Z);
            let Some(box_px) = f.projected_box(&truth) else {
                panic!("draw {draw}: out of view");
            };
            let pose = |p: Isometry3<f64>| BottlePose {
                world_from_bottle: p,
                lying: true,
                residual_px: 0.0,
            };
            let poses = vec![pose(mirror), pose(truth)];
            let image = frame(&f, &truth, 90, 220);
            let kept = f.keep_supported(poses.clone(), &box_px, &image, 0.5);
            assert_eq!(kept.len(), 1, "draw {draw}");
            assert_eq!(kept[0].world_from_bottle, truth, "draw {draw}");
            let plain = frame(&f, &truth, 90, 92);
            assert_eq!(f.keep_supported(poses, &box_px, &plain, 0.5).len(), 2);
        }
    }

    /// A standing bottle at the view's edge, its box cut by the frame's border on one or two
    /// sides: placed by the box's whole sides, a standing hypothesis lands on it; centred on
    /// the cut box, the only one without the frame lands millimetres to tens of millimetres in
    /// from the border.
    #[test]
    fn a_box_the_border_cuts_gets_a_standing_hypothesis_by_its_whole_sides() {
        let whole = fitter();
        let framed = fitter().with_frame(1280, 960);
        let station = [0.05, -0.45];
        // Offsets from the station that put part of the bottle out of view (the view spans
        // about +-0.23 m across and +-0.17 m along the image's axes at the belt).
        let offsets = [
            [0.0, 0.20],
            [0.0, -0.21],
            [0.16, 0.0],
            [-0.15, 0.0],
            [0.15, 0.19],
            [-0.14, -0.2],
        ];
        for [dx, dy] in offsets {
            let truth = Isometry3::translation(station[0] + dx, station[1] + dy, BELT_TOP_Z);
            let Some(b) = whole.projected_box(&truth) else {
                panic!("({dx}, {dy}): out of view");
            };
            let Some(cut) = CutBox::of(&b, (1280.0, 960.0), 0.0) else {
                panic!("({dx}, {dy}): not cut by the border: {b:?}");
            };
            let detection = cut.clip(&b);
            // The nearest standing hypothesis to the truth, m.
            let nearest_m = |f: &BottleFitter| {
                let t = truth.translation.vector;
                f.fit_candidates(&detection, BELT_TOP_Z)
                    .iter()
                    .filter(|p| !p.lying)
                    .map(|p| {
                        let p = p.world_from_bottle.translation.vector;
                        (p.x - t.x).hypot(p.y - t.y)
                    })
                    .fold(f64::INFINITY, f64::min)
            };
            let (framed_m, whole_m) = (nearest_m(&framed), nearest_m(&whole));
            assert!(
                framed_m < 0.005,
                "({dx}, {dy}): {:.1} mm off by the whole sides",
                framed_m * 1e3
            );
            assert!(
                whole_m > 0.005,
                "({dx}, {dy}): only {:.1} mm off centred on the cut box",
                whole_m * 1e3
            );
        }
    }
}
