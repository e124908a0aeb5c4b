//! What the camera cannot see is not drawn: objects outside the view frustum, and objects hidden
//! behind convex occluders (the belt and its rails hide the floor, the pedestal and the bin
//! stands from a camera above the belt).
//!
//! Both tests are conservative: an object is dropped only when no sample of any pixel could see
//! it, so culling never changes an image. A software rasteriser pays for every covered sample of
//! a hidden surface (the depth test runs per sample), which is why this matters at all.

use nalgebra::{Isometry3, Point3, Vector3};

use super::exposure::Exposure;
use super::mesh::MeshVertex;
use super::pipeline::{FAR_M, NEAR_M};
use crate::camera::CameraCalibration;

/// Meshes with at most this many triangles are checked for being closed and convex, so they can
/// hide what lies behind them.
const MAX_OCCLUDER_TRIANGLES: usize = 64;
/// A footprint grows by this much, pixels, before it is tested against the occluders.
const MARGIN_PX: f64 = 1.0;
/// An occluder's outline shrinks by this much, pixels (far more than the device's
/// single-precision vertex rounding moves an edge).
const SHRINK_PX: f64 = 0.01;
/// Pieces of a footprint smaller than this, square pixels, are rounding noise along an
/// occluder's edge, not a gap.
const NEGLIGIBLE_AREA_PX2: f64 = 1e-9;

/// A mesh's extent in its own frame.
#[derive(Debug, Clone)]
pub(super) struct Bounds {
    /// Corners of the axis-aligned bounding box.
    corners: [Point3<f64>; 8],
    /// Centre of the bounding sphere.
    centre: Point3<f64>,
    /// Radius of the bounding sphere, m.
    radius: f64,
    /// The vertices, when the mesh is closed and convex (it hides what lies behind its outline).
    occluder: Option<Vec<Point3<f64>>>,
}

impl Bounds {
    /// The bounds of a triangle list.
    pub(super) fn of(vertices: &[MeshVertex]) -> Self {
        let first = vertices.first().map_or(Point3::origin(), |v| v.position);
        let (mut low, mut high) = (first, first);
        for v in vertices {
            low = low.inf(&v.position);
            high = high.sup(&v.position);
        }
        let centre = nalgebra::center(&low, &high);
        let radius = vertices
            .iter()
            .map(|v| (v.position - centre).norm())
            .fold(0.0, f64::max);
        let corners = std::array::from_fn(|k| {
            Point3::new(
                if k & 1 == 0 { low.x } else { high.x },
                if k & 2 == 0 { low.y } else { high.y },
                if k & 4 == 0 { low.z } else { high.z },
            )
        });
        let positions: Vec<Point3<f64>> = vertices.iter().map(|v| v.position).collect();
        let occluder = (is_closed(&positions) && is_convex(&positions)).then_some(positions);
        Self {
            corners,
            centre,
            radius,
            occluder,
        }
    }
}

/// Whether a triangle list of at most [`MAX_OCCLUDER_TRIANGLES`] is closed: every directed edge
/// is matched by the same edge the other way round in another triangle.
fn is_closed(positions: &[Point3<f64>]) -> bool {
    let triangles = positions.len() / 3;
    if !(4..=MAX_OCCLUDER_TRIANGLES).contains(&triangles) || !positions.len().is_multiple_of(3) {
        return false;
    }
    let edges: Vec<(Point3<f64>, Point3<f64>)> = positions
        .chunks_exact(3)
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .collect();
    edges.iter().all(|(a, b)| {
        edges.iter().filter(|(c, d)| c == b && d == a).count() == 1
            && edges.iter().filter(|(c, d)| c == a && d == b).count() == 1
    })
}

/// Whether no vertex lies in front of any triangle's plane (outward, counter-clockwise faces).
fn is_convex(positions: &[Point3<f64>]) -> bool {
    let scale = positions
        .iter()
        .map(|p| p.coords.amax())
        .fold(0.0, f64::max)
        .max(1e-9);
    positions.chunks_exact(3).all(|t| {
        let normal = (t[1] - t[0]).cross(&(t[2] - t[0]));
        let tolerance = 1e-9 * scale * normal.norm();
        positions
            .iter()
            .all(|p| normal.dot(&(p - t[0])) <= tolerance)
    })
}

/// The camera's view for culling: pinhole intrinsics, image size and frustum.
pub(super) struct View {
    camera: CameraCalibration,
    /// The image, pixel-centre coordinates: `[x0, y0, x1, y1]`.
    image: [f64; 4],
    /// Inward unit normals of the frustum's side planes (through the camera centre along the
    /// image's outer pixel edges).
    sides: [Vector3<f64>; 4],
    near_m: f64,
    far_m: f64,
}

impl View {
    /// The view a render through `exposure` culls with: its camera and image, between the
    /// pipeline's near and far planes.
    pub(super) fn of_exposure(exposure: &Exposure) -> Self {
        Self::new(
            &exposure.camera,
            exposure.width_px,
            exposure.height_px,
            NEAR_M,
            FAR_M,
        )
    }

    /// The view of `camera` over a `width_px` x `height_px` image between two depths.
    pub(super) fn new(
        camera: &CameraCalibration,
        width_px: u32,
        height_px: u32,
        near_m: f64,
        far_m: f64,
    ) -> Self {
        // Pixel centres at integers: the image spans [-0.5, size - 0.5].
        let image = [
            -0.5,
            -0.5,
            f64::from(width_px) - 0.5,
            f64::from(height_px) - 0.5,
        ];
        let left = (image[0] - camera.cx_px) / camera.fx_px;
        let right = (image[2] - camera.cx_px) / camera.fx_px;
        let top = (image[1] - camera.cy_px) / camera.fy_px;
        let bottom = (image[3] - camera.cy_px) / camera.fy_px;
        Self {
            camera: *camera,
            image,
            sides: [
                Vector3::new(1.0, 0.0, -left).normalize(),
                Vector3::new(-1.0, 0.0, right).normalize(),
                Vector3::new(0.0, 1.0, -top).normalize(),
                Vector3::new(0.0, -1.0, bottom).normalize(),
            ],
            near_m,
            far_m,
        }
    }

    /// Pixel of a camera-frame point in front of the camera.
    fn project(&self, p: &Point3<f64>) -> [f64; 2] {
        let c = &self.camera;
        [c.fx_px * p.x / p.z + c.cx_px, c.fy_px * p.y / p.z + c.cy_px]
    }

    /// Whether a sphere (centre in the camera frame) reaches into the frustum.
    fn sees_sphere(&self, centre: &Point3<f64>, radius: f64) -> bool {
        centre.z + radius >= self.near_m
            && centre.z - radius <= self.far_m
            && self.sides.iter().all(|n| n.dot(&centre.coords) >= -radius)
    }

    /// The objects (indices into `bounds` and `camera_from_object`, taken in `order`) that the
    /// camera may see, in that order.
    pub(super) fn visible(
        &self,
        bounds: &[Bounds],
        camera_from_object: &[Isometry3<f64>],
        order: &[usize],
    ) -> Vec<usize> {
        let in_frustum: Vec<usize> = order
            .iter()
            .copied()
            .filter(|&i| {
                self.sees_sphere(
                    &(camera_from_object[i] * bounds[i].centre),
                    bounds[i].radius,
                )
            })
            .collect();
        // Occluders in view: their outline in the image and their farthest depth.
        let occluders: Vec<(usize, Vec<[f64; 2]>, f64)> = in_frustum
            .iter()
            .filter_map(|&i| {
                let points: Vec<Point3<f64>> = bounds[i]
                    .occluder
                    .as_ref()?
                    .iter()
                    .map(|p| camera_from_object[i] * p)
                    .collect();
                // Clipped by the near or far plane, it would not cover its outline.
                if points.iter().any(|p| p.z < self.near_m || p.z > self.far_m) {
                    return None;
                }
                let far = points.iter().map(|p| p.z).fold(f64::MIN, f64::max);
                let outline = convex_hull(points.iter().map(|p| self.project(p)).collect());
                Some((i, outline, far))
            })
            .collect();
        in_frustum
            .into_iter()
            .filter(|&i| {
                let corners = bounds[i].corners.map(|p| camera_from_object[i] * p);
                if corners.iter().any(|p| p.z < self.near_m) {
                    return true;
                }
                let near = corners.iter().map(|p| p.z).fold(f64::MAX, f64::min);
                let (mut low, mut high) = ([f64::MAX; 2], [f64::MIN; 2]);
                for p in &corners {
                    let q = self.project(p);
                    for k in 0..2 {
                        low[k] = low[k].min(q[k] - MARGIN_PX);
                        high[k] = high[k].max(q[k] + MARGIN_PX);
                    }
                }
                let (x0, y0) = (low[0].max(self.image[0]), low[1].max(self.image[1]));
                let (x1, y1) = (high[0].min(self.image[2]), high[1].min(self.image[3]));
                if x0 >= x1 || y0 >= y1 {
                    // Wholly beside the image.
                    return false;
                }
                let footprint = vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
                let mut uncovered = vec![footprint];
                for (j, outline, far) in &occluders {
                    if *j == i || *far >= near {
                        continue;
                    }
                    uncovered = uncovered
                        .iter()
                        .flat_map(|piece| subtract(piece, outline))
                        .collect();
                    if uncovered.is_empty() {
                        return false;
                    }
                }
                true
            })
            .collect()
    }
}

/// Counter-clockwise (in image coordinates, y down: clockwise on screen) convex hull of points
/// (Andrew's monotone chain).
fn convex_hull(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let turn = |o: &[f64; 2], a: &[f64; 2], b: &[f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * points.len());
    for pass in [false, true] {
        let start = hull.len();
        let ordered: Box<dyn Iterator<Item = &[f64; 2]>> = if pass {
            Box::new(points.iter().rev())
        } else {
            Box::new(points.iter())
        };
        for p in ordered {
            while hull.len() >= start + 2
                && turn(&hull[hull.len() - 2], &hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(*p);
        }
        hull.pop();
    }
    hull
}

/// The part of convex polygon `piece` outside convex polygon `hole` (wound as [`convex_hull`]
/// winds) shrunk by [`SHRINK_PX`], as convex pieces.
fn subtract(piece: &[[f64; 2]], hole: &[[f64; 2]]) -> Vec<Vec<[f64; 2]>> {
    if hole.len() < 3 {
        return vec![piece.to_vec()];
    }
    let mut out = Vec::new();
    let mut rest = piece.to_vec();
    for (k, a) in hole.iter().enumerate() {
        let b = hole[(k + 1) % hole.len()];
        // Left of a -> b (positive cross product), by more than the shrink, is inside the hole.
        let shrink = SHRINK_PX * (b[0] - a[0]).hypot(b[1] - a[1]);
        let side =
            |p: &[f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) - shrink;
        let outside = clip(&rest, |p| -side(p));
        if area(&outside) > NEGLIGIBLE_AREA_PX2 {
            out.push(outside);
        }
        rest = clip(&rest, side);
        if area(&rest) <= NEGLIGIBLE_AREA_PX2 {
            return out;
        }
    }
    out
}

/// The part of a convex polygon where `f` (an affine function) is at least zero.
fn clip(polygon: &[[f64; 2]], f: impl Fn(&[f64; 2]) -> f64) -> Vec<[f64; 2]> {
    let mut out = Vec::with_capacity(polygon.len() + 1);
    for (k, a) in polygon.iter().enumerate() {
        let b = &polygon[(k + 1) % polygon.len()];
        let (fa, fb) = (f(a), f(b));
        if fa >= 0.0 {
            out.push(*a);
        }
        if (fa >= 0.0) != (fb >= 0.0) {
            let t = fa / (fa - fb);
            out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
        }
    }
    out
}

/// Absolute area of a polygon, square pixels.
fn area(polygon: &[[f64; 2]]) -> f64 {
    let twice: f64 = polygon
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let b = &polygon[(k + 1) % polygon.len()];
            a[0] * b[1] - a[1] * b[0]
        })
        .sum();
    twice.abs() / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::material::Material;
    use crate::render::mesh::Mesh;

    #[test]
    fn boxes_are_closed_convex_occluders_and_parts_are_not() {
        let cube = Mesh::cuboid(Vector3::new(0.1, 0.2, 0.3), Material::BELT);
        assert!(Bounds::of(&cube.vertices).occluder.is_some());
        let mut open = cube.clone();
        open.vertices.truncate(30);
        assert!(Bounds::of(&open.vertices).occluder.is_none());
        let bore = crate::cell::BoreForm::Ellipse {
            a_m: 0.0101,
            b_m: 0.0099,
            angle_rad: 0.0,
        };
        let tube = Mesh::axle_part(&bore, 0.017, 0.06);
        assert!(Bounds::of(&tube.vertices).occluder.is_none());
    }

    #[test]
    fn subtracting_covers_exactly_the_hole() {
        let square = |x0: f64, y0: f64, x1: f64, y1: f64| {
            convex_hull(vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        };
        let total = |pieces: &[Vec<[f64; 2]>]| pieces.iter().map(|p| area(p)).sum::<f64>();
        let piece = square(0.0, 0.0, 10.0, 10.0);
        // Two overlapping halves cover it; one half leaves the other (holes shrink by 0.01).
        let left = square(-1.0, -1.0, 6.0, 11.0);
        let right = square(5.0, -1.0, 11.0, 11.0);
        let rest = subtract(&piece, &left);
        assert!((total(&rest) - 40.1).abs() < 1e-9, "{rest:?}");
        let covered: Vec<_> = rest.iter().flat_map(|p| subtract(p, &right)).collect();
        assert!(covered.is_empty(), "{covered:?}");
        // Halves that only touch leave a sliver: not covered.
        let touching = square(6.0, -1.0, 11.0, 11.0);
        let sliver: Vec<_> = rest.iter().flat_map(|p| subtract(p, &touching)).collect();
        assert!((total(&sliver) - 0.2).abs() < 1e-9, "{sliver:?}");
        // A hole inside leaves a frame of four pieces.
        let rest = subtract(&piece, &square(2.0, 2.0, 8.0, 8.0));
        assert_eq!(rest.len(), 4);
        assert!((total(&rest) - (100.0 - 5.98 * 5.98)).abs() < 1e-9);
    }

    /// A camera 0.6 m above a belt-like box looking straight down: a floor box below is hidden
    /// while the belt fills the view, seen once the belt is too narrow, and an object beside the
    /// view is never drawn.
    #[test]
    fn a_box_filling_the_view_hides_what_lies_behind_it() {
        let eye = Point3::new(0.0, 0.0, 1.3);
        let Some(world_from_camera) =
            CameraCalibration::look_at(&eye, &Point3::new(0.0, 0.0, 0.7), &Vector3::x())
        else {
            panic!("camera");
        };
        let camera =
            CameraCalibration::from_fov(640, 480, 44f64.to_radians(), world_from_camera, 0.7);
        let view = View::new(&camera, 640, 480, 0.02, 20.0);
        let camera_from_world = world_from_camera.inverse();
        let boxed = |half: Vector3<f64>, centre: Vector3<f64>| {
            (
                Bounds::of(&Mesh::cuboid(half, Material::BELT).vertices),
                camera_from_world * Isometry3::translation(centre.x, centre.y, centre.z),
            )
        };
        let visible = |belt_half_width: f64| {
            let objects = [
                boxed(Vector3::new(3.0, 3.0, 0.05), Vector3::new(0.0, 0.0, -0.05)),
                boxed(
                    Vector3::new(0.8, belt_half_width, 0.025),
                    Vector3::new(0.0, 0.0, 0.675),
                ),
                boxed(Vector3::new(0.05, 0.05, 0.05), Vector3::new(1.5, 0.0, 0.75)),
            ];
            let (bounds, poses): (Vec<Bounds>, Vec<Isometry3<f64>>) = objects.into_iter().unzip();
            view.visible(&bounds, &poses, &[1, 0, 2])
        };
        assert_eq!(visible(0.3), vec![1]);
        assert_eq!(visible(0.15), vec![1, 0]);
    }
}
