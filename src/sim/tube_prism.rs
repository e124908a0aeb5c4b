//! A tube's collider as rapier sees it: the convex prism `items::tube_shape` builds (two rings
//! of `sides` corners about the y axis and a square at each end), whose support point is found
//! among the few corners near the direction instead of by scanning all of them.
//!
//! Parry's convex polyhedron finds a support point by testing every corner (72 on a tube), and
//! GJK asks for one at each of its steps, for every pair a tube touches: 6 % of a camera trial's
//! samples and 19 % of a tracked stream's. The corners of a ring are a regular polygon, so the
//! corner furthest along a direction lies at the direction's angle about the axis, within a
//! corner's step; only the corners two steps either side of that angle on each ring, and the
//! squares' eight, can be the furthest. They are tested as the full scan tests them (the same
//! dot product, the largest kept, of equals the one the scan meets first), so the point is the
//! scan's to the bit; a direction within a thousandth of the axis, where the rings' corners tie,
//! is scanned whole. Everything else is the polyhedron's own.

use rapier3d::parry::bounding_volume::{Aabb, BoundingSphere};
use rapier3d::parry::mass_properties::MassProperties;
use rapier3d::parry::query::{PointProjection, PointQuery, Ray, RayCast, RayIntersection};
use rapier3d::parry::shape::{
    ConvexPolyhedron, FeatureId, PolygonalFeature, PolygonalFeatureMap, Shape, ShapeType,
    SubShapeId, SupportMap, TypedShape,
};
use rapier3d::prelude::{Pose, Real, Vector};

/// A direction whose part across the axis is under this share of its length is scanned whole.
const AXIAL_SHARE: f32 = 1e-3;
/// Corners tested either side of the direction's nearest one on each ring.
const WINDOW: usize = 2;

/// The prism and where its corners lie (see the module docs).
#[derive(Debug, Clone)]
pub(super) struct TubePrism {
    hull: ConvexPolyhedron,
    /// Per ring (y < 0, y > 0), the index among the hull's points of its corner `k`.
    rings: [Vec<u32>; 2],
    /// The indices of the other points (the end squares).
    others: Vec<u32>,
}

impl TubePrism {
    /// `hull` (the prism `items::tube_shape` builds) with its ring corners found: those at
    /// `radius` from the axis, at the angles of a regular `sides`-gon. The hull back when its
    /// points are not such a prism's (each ring's corners each once, the rest few).
    pub(super) fn new(
        hull: ConvexPolyhedron,
        radius: f32,
        sides: usize,
    ) -> Result<Self, Box<ConvexPolyhedron>> {
        let mut rings = [vec![u32::MAX; sides], vec![u32::MAX; sides]];
        let mut others = Vec::new();
        let step = std::f32::consts::TAU / sides as f32;
        for (index, p) in hull.points().iter().enumerate() {
            let across = p.x.hypot(p.z);
            if (across - radius).abs() > 1e-5 * radius.max(1e-3) {
                others.push(index as u32);
                continue;
            }
            let k = (p.z.atan2(p.x) / step).round().rem_euclid(sides as f32) as usize % sides;
            let slot = &mut rings[usize::from(p.y > 0.0)][k];
            if *slot != u32::MAX {
                return Err(Box::new(hull));
            }
            *slot = index as u32;
        }
        let complete = rings.iter().flatten().all(|&i| i != u32::MAX);
        if complete && others.len() <= 16 {
            Ok(Self {
                hull,
                rings,
                others,
            })
        } else {
            Err(Box::new(hull))
        }
    }

    /// The polyhedron.
    #[cfg(test)]
    fn hull(&self) -> &ConvexPolyhedron {
        &self.hull
    }
}

/// A monotone stand-in for the angle of `(x, y)` about the origin, in [0, 4) for a turn: the
/// "diamond angle", within 4 degrees of the true angle's quarter turns, without a call to
/// `atan2`.
fn diamond_angle(y: f32, x: f32) -> f32 {
    if y >= 0.0 {
        if x >= 0.0 {
            y / (x + y)
        } else {
            1.0 - x / (-x + y)
        }
    } else if x < 0.0 {
        2.0 - y / (-x - y)
    } else {
        3.0 + x / (x - y)
    }
}

impl SupportMap for TubePrism {
    fn local_support_point(&self, dir: Vector) -> Vector {
        let points = self.hull.points();
        let across2 = dir.x * dir.x + dir.z * dir.z;
        let all2 = across2 + dir.y * dir.y;
        if !dir.is_finite() || across2 <= AXIAL_SHARE * AXIAL_SHARE * all2 {
            return scan(points, dir);
        }
        let sides = self.rings[0].len();
        // The diamond angle is within 4 degrees of the true one: a corner either way of the
        // nearest, so the window of two either way holds the furthest corner and its ties.
        let turn = diamond_angle(dir.z, dir.x) / 4.0;
        let nearest = (turn * sides as f32).round() as isize;
        // The largest dot product, the first (lowest index) of equals: what the scan keeps.
        let mut best = (f32::NEG_INFINITY, u32::MAX);
        let mut consider = |i: u32| {
            let dot = points[i as usize].dot(dir);
            if dot > best.0 || (dot == best.0 && i < best.1) {
                best = (dot, i);
            }
        };
        for ring in &self.rings {
            for offset in -(WINDOW as isize)..=WINDOW as isize {
                consider(ring[(nearest + offset).rem_euclid(sides as isize) as usize]);
            }
        }
        for &i in &self.others {
            consider(i);
        }
        points[best.1 as usize]
    }
}

/// The point of `points` furthest along `dir`, the first of equals: parry's scan of a point
/// cloud.
fn scan(points: &[Vector], dir: Vector) -> Vector {
    let (mut best, mut best_dot) = (0, points[0].dot(dir));
    for (i, p) in points.iter().enumerate().skip(1) {
        let dot = p.dot(dir);
        if dot > best_dot {
            (best, best_dot) = (i, dot);
        }
    }
    points[best]
}

impl PolygonalFeatureMap for TubePrism {
    fn local_support_feature(&self, dir: Vector, out_feature: &mut PolygonalFeature) {
        self.hull.local_support_feature(dir, out_feature);
    }
}

impl RayCast for TubePrism {
    fn cast_local_ray_and_get_normal(
        &self,
        ray: &Ray,
        max_time_of_impact: Real,
        solid: bool,
    ) -> Option<RayIntersection> {
        self.hull
            .cast_local_ray_and_get_normal(ray, max_time_of_impact, solid)
    }
}

impl PointQuery for TubePrism {
    fn project_local_point(&self, point: Vector, solid: bool) -> PointProjection {
        self.hull.project_local_point(point, solid)
    }

    fn project_local_point_and_get_feature(&self, point: Vector) -> (PointProjection, FeatureId) {
        self.hull.project_local_point_and_get_feature(point)
    }
}

impl Shape for TubePrism {
    fn compute_local_aabb(&self) -> Aabb {
        self.hull.compute_local_aabb()
    }

    fn compute_local_bounding_sphere(&self) -> BoundingSphere {
        self.hull.compute_local_bounding_sphere()
    }

    fn compute_aabb(&self, position: &Pose) -> Aabb {
        self.hull.compute_aabb(position)
    }

    fn clone_dyn(&self) -> Box<dyn Shape> {
        Box::new(self.clone())
    }

    fn scale_dyn(&self, scale: Vector, num_subdivisions: u32) -> Option<Box<dyn Shape>> {
        self.hull.scale_dyn(scale, num_subdivisions)
    }

    fn mass_properties(&self, density: Real) -> MassProperties {
        self.hull.mass_properties(density)
    }

    fn is_convex(&self) -> bool {
        true
    }

    fn shape_type(&self) -> ShapeType {
        ShapeType::Custom
    }

    fn as_typed_shape(&self) -> TypedShape<'_> {
        TypedShape::Custom(self)
    }

    fn ccd_thickness(&self) -> Real {
        self.hull.ccd_thickness()
    }

    fn ccd_angular_thickness(&self) -> Real {
        self.hull.ccd_angular_thickness()
    }

    fn as_support_map(&self) -> Option<&dyn SupportMap> {
        Some(self as &dyn SupportMap)
    }

    fn as_polygonal_feature_map(&self) -> Option<(&dyn PolygonalFeatureMap, Real)> {
        Some((self as &dyn PolygonalFeatureMap, 0.0))
    }

    fn feature_normal_at_point(
        &self,
        subshape: SubShapeId,
        feature: FeatureId,
        point: Vector,
    ) -> Option<Vector> {
        self.hull.feature_normal_at_point(subshape, feature, point)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;

    /// The support point is the full scan's to the bit over directions of every kind: random,
    /// near the axis, across it, and exactly on corners' and edges' bisectors.
    #[test]
    fn the_support_point_is_the_scans() {
        let mut rng = SimRng::new(26);
        for (radius, height) in [(0.017f64, 0.06f64), (0.045, 0.12), (0.004, 0.03)] {
            let shape = super::super::items::tube_shape(radius, height);
            let Some(prism) = shape.as_shape::<TubePrism>() else {
                panic!("not a tube prism");
            };
            let points = prism.hull().points();
            let full = |d: Vector| scan(points, d);
            let mut directions = Vec::new();
            for _ in 0..20000 {
                let d = Vector::new(
                    rng.range(-1.0, 1.0) as f32,
                    rng.range(-1.0, 1.0) as f32,
                    rng.range(-1.0, 1.0) as f32,
                );
                directions.push(d);
                // Nearly along the axis, and nearly across it.
                directions.push(Vector::new(d.x * 1e-3, d.y, d.z * 1e-3));
                directions.push(Vector::new(d.x * 2e-3, d.y, d.z * 2e-3));
                directions.push(Vector::new(d.x, d.y * 1e-4, d.z));
            }
            for k in 0..128 {
                let a = std::f32::consts::TAU * k as f32 / 128.0;
                for y in [-1.0f32, -0.3, 0.0, 0.3, 1.0] {
                    directions.push(Vector::new(a.cos(), y, a.sin()));
                }
            }
            directions.push(Vector::new(0.0, 1.0, 0.0));
            directions.push(Vector::new(0.0, -1.0, 0.0));
            for d in directions {
                let (fast, slow) = (prism.local_support_point(d), full(d));
                assert_eq!(
                    fast.to_array().map(f32::to_bits),
                    slow.to_array().map(f32::to_bits),
                    "radius {radius}, direction {d:?}"
                );
            }
        }
    }
}
