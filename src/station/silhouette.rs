//! A rigid body's outline as the calibrated camera sees it: its points projected to the box
//! they span, and a body slid over a plane until its box is centred where a detection's is (or,
//! for a detection the frame's border cuts, until its clipped box meets the detection's whole
//! sides). The bottle fit and the lying-part fit share it.

use nalgebra::{Isometry3, Point3};

use crate::camera::CameraCalibration;

/// Fixed-point iterations that move a hypothesis until its box centre meets the detection.
const FIT_ITERATIONS: usize = 12;
/// A hypothesis whose last move was shorter than this has converged, m.
const CONVERGED_M: f64 = 1e-6;

/// The points of a body's outline in its own frame, each once, as columns of x, y and z: the
/// box is their projection's extent, taken in vector lanes.
#[derive(Debug, Clone)]
pub struct Silhouette {
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
}

impl Silhouette {
    /// The outline of `points` (repeats dropped).
    pub fn of_points(points: impl IntoIterator<Item = Point3<f64>>) -> Self {
        let mut points: Vec<Point3<f64>> = points.into_iter().collect();
        points.sort_by(|a, b| {
            (a.x, a.y, a.z)
                .partial_cmp(&(b.x, b.y, b.z))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        points.dedup();
        Self {
            xs: points.iter().map(|p| p.x).collect(),
            ys: points.iter().map(|p| p.y).collect(),
            zs: points.iter().map(|p| p.z).collect(),
        }
    }

    /// The outline of `points` without those deep inside their convex hull (at least
    /// a micrometre inside every face): a projection's box, and the nearest depth, are
    /// extremes of functions that are linear, or linear over a positive depth, in the point, so
    /// they lie on the hull's vertices, and a point that deep inside projects measurably inside
    /// them (a micrometre is a few thousandths of a pixel at a metre), never onto the box. The box
    /// is the same to the bit; a body of revolution keeps its outer rings only. All points are
    /// kept when the hull cannot be made (flat or degenerate bodies).
    pub fn of_hull_points(points: impl IntoIterator<Item = Point3<f64>>) -> Self {
        let all = Self::of_points(points);
        let points: Vec<Point3<f64>> = (0..all.xs.len())
            .map(|k| Point3::new(all.xs[k], all.ys[k], all.zs[k]))
            .collect();
        let Some(faces) = hull_faces(&points) else {
            return all;
        };
        let kept = points.into_iter().filter(|p| {
            !faces
                .iter()
                .all(|(normal, offset)| normal.dot(&p.coords) - offset < -HULL_INSIDE_M)
        });
        Self::of_points(kept)
    }

    /// How many points the outline has.
    pub fn len(&self) -> usize {
        self.xs.len()
    }

    /// Whether the outline has no points.
    pub fn is_empty(&self) -> bool {
        self.xs.is_empty()
    }

    /// The box (`[x0, y0, x1, y1]`, pixels) the body at `world_from_body` projects to through
    /// `camera`, or `None` when a point of it is not in front of the camera.
    ///
    /// A fit projects the outline a few thousand times per detection, so the body-to-camera
    /// transform is composed once and applied as a matrix to every point.
    pub fn projected_box(
        &self,
        camera: &CameraCalibration,
        world_from_body: &Isometry3<f64>,
    ) -> Option<[f64; 4]> {
        let camera_from_body = camera.world_from_camera.inverse() * world_from_body;
        let m = camera_from_body.rotation.to_rotation_matrix().into_inner();
        let t = camera_from_body.translation.vector;
        let (fx, fy, cx, cy) = (camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px);
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut nearest_z = f64::INFINITY;
        for ((&x, &y), &z) in self.xs.iter().zip(&self.ys).zip(&self.zs) {
            let cz = m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)] * z + t.z;
            let cx_m = m[(0, 0)] * x + m[(0, 1)] * y + m[(0, 2)] * z + t.x;
            let cy_m = m[(1, 0)] * x + m[(1, 1)] * y + m[(1, 2)] * z + t.y;
            let u = fx * cx_m / cz + cx;
            let v = fy * cy_m / cz + cy;
            nearest_z = if cz < nearest_z { cz } else { nearest_z };
            b[0] = if u < b[0] { u } else { b[0] };
            b[1] = if v < b[1] { v } else { b[1] };
            b[2] = if u > b[2] { u } else { b[2] };
            b[3] = if v > b[3] { v } else { b[3] };
        }
        (nearest_z > 0.0).then_some(b)
    }

    /// Slides the body over the horizontal plane (`pose_at(x, y)` places it with its middle
    /// over `(x, y)`; `mid_z` is the height of that middle) until its box is centred on
    /// `centre_px`: the place reached and the box there, or `None` when the body leaves the
    /// camera's view.
    pub fn slide_to_centre(
        &self,
        camera: &CameraCalibration,
        centre_px: [f64; 2],
        mid_z: f64,
        pose_at: impl Fn(f64, f64) -> Isometry3<f64>,
    ) -> Option<([f64; 2], [f64; 4])> {
        let centre = |b: &[f64; 4]| [(b[0] + b[2]) / 2.0, (b[1] + b[3]) / 2.0];
        self.slide(camera, [centre_px; 2], mid_z, pose_at, |b| *b, centre)
    }

    /// Slides the body from over `start_px` until the point `anchor` picks of its box (as
    /// `seen` turns it into what the detector would box) lies over `want_px`, each move measured
    /// on the plane through the body's middle: the place reached and the seen box there.
    fn slide(
        &self,
        camera: &CameraCalibration,
        [start_px, want_px]: [[f64; 2]; 2],
        mid_z: f64,
        pose_at: impl Fn(f64, f64) -> Isometry3<f64>,
        seen: impl Fn(&[f64; 4]) -> [f64; 4],
        anchor: impl Fn(&[f64; 4]) -> [f64; 2],
    ) -> Option<([f64; 2], [f64; 4])> {
        let on_mid_plane = |p: [f64; 2]| camera.pixel_to_height(p[0], p[1], mid_z);
        let start = on_mid_plane(start_px).ok()?;
        let want = on_mid_plane(want_px);
        let (mut x, mut y) = (start.x, start.y);
        let mut fitted = None;
        for _ in 0..FIT_ITERATIONS {
            let Some(b) = self.projected_box(camera, &pose_at(x, y)) else {
                break;
            };
            let b = seen(&b);
            fitted = Some(b);
            let (Ok(at), Ok(want)) = (on_mid_plane(anchor(&b)), &want) else {
                break;
            };
            let (dx, dy) = (want.x - at.x, want.y - at.y);
            x += dx;
            y += dy;
            if dx.hypot(dy) < CONVERGED_M {
                break;
            }
        }
        fitted.map(|b| ([x, y], b))
    }
}

/// See [`Silhouette::of_hull_points`], m.
const HULL_INSIDE_M: f64 = 1e-6;

/// The planes (unit outward normal, offset along it) of the faces of `points`' convex hull, each
/// through three of the points themselves (the hull is found in single precision, the planes are
/// taken in double); `None` when the hull cannot be made or has a face without area.
fn hull_faces(points: &[Point3<f64>]) -> Option<Vec<(nalgebra::Vector3<f64>, f64)>> {
    use rapier3d::prelude::Vector;
    let single: Vec<Vector> = points
        .iter()
        .map(|p| Vector::new(p.x as f32, p.y as f32, p.z as f32))
        .collect();
    let (vertices, faces) = rapier3d::parry::transformation::try_convex_hull(&single).ok()?;
    // The hull's vertices are input points: back to the double-precision ones.
    let original = |v: &Vector| {
        single
            .iter()
            .position(|s| s.to_array().map(f32::to_bits) == v.to_array().map(f32::to_bits))
            .map(|k| points[k])
    };
    let corners: Vec<Point3<f64>> = vertices.iter().map(original).collect::<Option<_>>()?;
    let centroid = corners
        .iter()
        .fold(nalgebra::Vector3::zeros(), |s, p| s + p.coords)
        / corners.len().max(1) as f64;
    faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|k| corners.get(k as usize).copied());
            let (a, b, c) = (a?, b?, c?);
            let normal = (b - a).cross(&(c - a));
            let length = normal.norm();
            if length.is_nan() || length <= 1e-12 {
                return None;
            }
            let mut normal = normal / length;
            if normal.dot(&(centroid - a.coords)) > 0.0 {
                normal = -normal;
            }
            Some((normal, normal.dot(&a.coords)))
        })
        .collect()
}

/// A detection box cut by the frame's border: which of its sides lie on the border, and the
/// frame it was cut by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutBox {
    /// The box, `x0, y0, x1, y1`, px.
    pub box_px: [f64; 4],
    /// Per side (left, top, right, bottom), whether the border cuts it.
    pub cut: [bool; 4],
    /// The frame's width and height, px.
    pub frame_px: (f64, f64),
}

impl CutBox {
    /// `box_px` in a `frame_px` frame, its sides within `share` of the frame's width (height)
    /// of the border cut; `None` when no side is.
    pub fn of(box_px: &[f64; 4], frame_px: (f64, f64), share: f64) -> Option<Self> {
        let (w, h) = frame_px;
        let (mx, my) = (share * w, share * h);
        let cut = [
            box_px[0] <= mx,
            box_px[1] <= my,
            box_px[2] >= w - mx,
            box_px[3] >= h - my,
        ];
        cut.contains(&true).then_some(Self {
            box_px: *box_px,
            cut,
            frame_px,
        })
    }

    /// `b` clipped to the frame.
    pub fn clip(&self, b: &[f64; 4]) -> [f64; 4] {
        let (w, h) = self.frame_px;
        [
            b[0].clamp(0.0, w),
            b[1].clamp(0.0, h),
            b[2].clamp(0.0, w),
            b[3].clamp(0.0, h),
        ]
    }

    /// The point of `b` that a fit matches with the same point of the detection: per axis, the
    /// middle when neither side or both are cut, else the side the border leaves whole.
    fn anchor(&self, b: &[f64; 4]) -> [f64; 2] {
        let along = |low: usize, high: usize| match (self.cut[low], self.cut[high]) {
            (false, true) => b[low],
            (true, false) => b[high],
            _ => (b[low] + b[high]) / 2.0,
        };
        [along(0, 2), along(1, 3)]
    }
}

impl Silhouette {
    /// As [`Self::slide_to_centre`] for a detection cut by the frame: the body's box, clipped to
    /// the frame, is matched to the detection on the sides the border leaves whole (on an axis
    /// cut at one side only, by the other side; otherwise by the middle). Returns the place and
    /// the clipped box there.
    pub fn slide_to_cut_box(
        &self,
        camera: &CameraCalibration,
        detection: &CutBox,
        mid_z: f64,
        pose_at: impl Fn(f64, f64) -> Isometry3<f64>,
    ) -> Option<([f64; 2], [f64; 4])> {
        let d = &detection.box_px;
        let start_px = [(d[0] + d[2]) / 2.0, (d[1] + d[3]) / 2.0];
        let ends = [start_px, detection.anchor(d)];
        let clip = |b: &[f64; 4]| detection.clip(b);
        self.slide(camera, ends, mid_z, pose_at, clip, |b| detection.anchor(b))
    }
}

/// The RMS difference of two boxes' four sides, pixels.
pub fn box_residual_px(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    ((0..4).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>() / 4.0).sqrt()
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    use super::*;
    use crate::render::mesh::Mesh;
    use crate::rng::SimRng;

    /// The bottle's outline without its inner rings boxes every pose, seen from cameras over the
    /// whole envelope, to the bit as the whole outline does.
    #[test]
    fn the_hulls_points_box_a_body_as_all_its_points_do() {
        let mut rng = SimRng::new(61);
        let mut seen = 0;
        for (radius, height) in [(0.033, 0.2), (0.02, 0.3), (0.05, 0.12)] {
            let mesh = Mesh::bottle(radius, height);
            let points = || mesh.vertices.iter().map(|v| v.position);
            let (all, hull) = (
                Silhouette::of_points(points()),
                Silhouette::of_hull_points(points()),
            );
            assert!(
                hull.len() < all.len() * 9 / 10,
                "{} of {} points kept",
                hull.len(),
                all.len()
            );
            for _ in 0..400 {
                // A camera 0.35-1.2 m away, up to 40 degrees off the vertical, any roll, looking
                // at a point near the body.
                let tilt = rng.range(0.0, 40f64.to_radians());
                let heading = rng.range(0.0, std::f64::consts::TAU);
                let distance = rng.range(0.35, 1.2);
                let target = Point3::new(rng.range(-0.1, 0.1), rng.range(-0.1, 0.1), 0.0);
                let eye = target
                    + distance
                        * Vector3::new(
                            tilt.sin() * heading.cos(),
                            tilt.sin() * heading.sin(),
                            tilt.cos(),
                        );
                let look = UnitQuaternion::face_towards(&(target - eye), &Vector3::y())
                    * UnitQuaternion::from_euler_angles(0.0, 0.0, rng.range(0.0, 6.3));
                let camera = CameraCalibration {
                    fx_px: 1500.0,
                    fy_px: 1500.0,
                    cx_px: 640.0,
                    cy_px: 480.0,
                    world_from_camera: Isometry3::from_parts(Translation3::from(eye.coords), look),
                    end_face_height_m: 0.0,
                };
                let lying = rng.range(0.0, 1.0) < 0.5;
                let tip = if lying {
                    std::f64::consts::FRAC_PI_2
                } else {
                    0.0
                };
                let body = Isometry3::from_parts(
                    Translation3::new(rng.range(-0.1, 0.1), rng.range(-0.1, 0.1), 0.0),
                    UnitQuaternion::from_euler_angles(0.0, tip, rng.range(0.0, 6.3)),
                );
                let (a, b) = (
                    all.projected_box(&camera, &body),
                    hull.projected_box(&camera, &body),
                );
                seen += usize::from(a.is_some());
                assert_eq!(
                    a.map(|b| b.map(f64::to_bits)),
                    b.map(|b| b.map(f64::to_bits)),
                    "camera {eye:?}, body {body:?}"
                );
            }
        }
        // Nearly every body is in front of its camera: the boxes were compared, not two Nones.
        assert!(seen > 1100, "{seen} of 1200 boxes");
    }
}
