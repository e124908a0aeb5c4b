//! Triangle meshes of the cell's bodies in their own frames, with per-vertex materials.
//!
//! Every mesh is a plain triangle list (three vertices per triangle, outward normals, counter-
//! clockwise seen from outside). The axle part's mesh carries its true bore: the end face's inner
//! edge follows [`BoreForm::radius_at`] at [`BORE_SEGMENTS`] points.

use nalgebra::{Point3, Vector3};

use super::material::Material;
use crate::cell::BoreForm;

/// Segments around a bore (its edge error is below 0.1 um for a 44 mm bore).
pub const BORE_SEGMENTS: usize = 1024;
/// Segments around other round bodies.
pub const ROUND_SEGMENTS: usize = 64;

/// One vertex in a body's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshVertex {
    /// Position, m.
    pub position: Point3<f64>,
    /// Unit normal.
    pub normal: Vector3<f64>,
    /// Surface material.
    pub material: Material,
}

/// A triangle list in a body's frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Three vertices per triangle.
    pub vertices: Vec<MeshVertex>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.vertices.len() / 3
    }

    /// Appends another mesh.
    pub fn append(&mut self, other: &Mesh) {
        self.vertices.extend_from_slice(&other.vertices);
    }

    /// Adds a flat triangle (normal from its winding).
    fn flat_triangle(&mut self, corners: [Point3<f64>; 3], material: Material) {
        let normal = (corners[1] - corners[0])
            .cross(&(corners[2] - corners[0]))
            .try_normalize(1e-18)
            .unwrap_or_else(Vector3::z);
        for position in corners {
            self.vertices.push(MeshVertex {
                position,
                normal,
                material,
            });
        }
    }

    /// Adds a quad `a b c d` (counter-clockwise from outside) with per-corner normals.
    fn quad(&mut self, corners: [Point3<f64>; 4], normals: [Vector3<f64>; 4], material: Material) {
        for i in [0, 1, 2, 0, 2, 3] {
            self.vertices.push(MeshVertex {
                position: corners[i],
                normal: normals[i],
                material,
            });
        }
    }

    /// A box centred on the origin with half extents `half`.
    pub fn cuboid(half: Vector3<f64>, material: Material) -> Self {
        let mut mesh = Self::default();
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut normal = Vector3::zeros();
                normal[axis] = sign;
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let corner = |a: f64, b: f64| {
                    let mut p = Vector3::zeros();
                    p[axis] = sign * half[axis];
                    p[u] = a * half[u];
                    p[v] = b * half[v];
                    Point3::from(p)
                };
                let mut corners = [
                    corner(-1.0, -1.0),
                    corner(1.0, -1.0),
                    corner(1.0, 1.0),
                    corner(-1.0, 1.0),
                ];
                if sign < 0.0 {
                    corners.reverse();
                }
                mesh.quad(corners, [normal; 4], material);
            }
        }
        mesh
    }

    /// A solid of revolution about the z axis through profile points `(radius, z)` listed from
    /// bottom to top; a zero radius closes the solid there. Smooth normals around, flat along
    /// the profile.
    pub fn lathe(profile: &[(f64, f64, Material)], segments: usize) -> Self {
        let mut mesh = Self::default();
        for pair in profile.windows(2) {
            let ((r0, z0, _), (r1, z1, material)) = (pair[0], pair[1]);
            // The profile's outward normal in the (r, z) half-plane.
            let (dr, dz) = (r1 - r0, z1 - z0);
            let length = dr.hypot(dz);
            if length < 1e-12 {
                continue;
            }
            let (nr, nz) = (dz / length, -dr / length);
            for k in 0..segments {
                let (t0, t1) = (angle(k, segments), angle(k + 1, segments));
                let at = |r: f64, z: f64, t: f64| Point3::new(r * t.cos(), r * t.sin(), z);
                let normal = |t: f64| Vector3::new(nr * t.cos(), nr * t.sin(), nz);
                mesh.quad(
                    [
                        at(r0, z0, t0),
                        at(r0, z0, t1),
                        at(r1, z1, t1),
                        at(r1, z1, t0),
                    ],
                    [normal(t0), normal(t1), normal(t1), normal(t0)],
                    material,
                );
            }
        }
        mesh
    }

    /// A closed cylinder about the z axis, centred on the origin.
    pub fn cylinder_z(radius: f64, half_height: f64, material: Material) -> Self {
        Self::lathe(
            &[
                (0.0, -half_height, material),
                (radius, -half_height, material),
                (radius, half_height, material),
                (0.0, half_height, material),
            ],
            ROUND_SEGMENTS,
        )
    }

    /// An axle part: a tube standing on its bottom face, centred on the origin, whose bore
    /// follows `bore` exactly (its edge at [`BORE_SEGMENTS`] angles), with a machined end face on
    /// top, a turned outer wall and a dark bore wall.
    pub fn axle_part(bore: &BoreForm, outer_radius_m: f64, height_m: f64) -> Self {
        let mut mesh = Self::default();
        let n = BORE_SEGMENTS;
        let (top, bottom) = (height_m / 2.0, -height_m / 2.0);
        let inner = |k: usize| {
            let t = angle(k, n);
            let r = bore.radius_at(t);
            (Point3::new(r * t.cos(), r * t.sin(), 0.0), t)
        };
        for k in 0..n {
            let ((a, t0), (b, t1)) = (inner(k), inner(k + 1));
            let outer =
                |t: f64, z: f64| Point3::new(outer_radius_m * t.cos(), outer_radius_m * t.sin(), z);
            let lift = |p: Point3<f64>, z: f64| Point3::new(p.x, p.y, z);
            let up = Vector3::z();
            // End face: an annulus from the bore edge out to the outer radius.
            mesh.quad(
                [lift(a, top), outer(t0, top), outer(t1, top), lift(b, top)],
                [up; 4],
                Material::END_FACE,
            );
            // The underside stands on the belt at the belt's own depth; dark, so where the two
            // fight for the depth test (seen down the bore) it looks like the belt.
            mesh.quad(
                [
                    lift(a, bottom),
                    lift(b, bottom),
                    outer(t1, bottom),
                    outer(t0, bottom),
                ],
                [-up; 4],
                Material::BORE,
            );
            let radial = |t: f64| Vector3::new(t.cos(), t.sin(), 0.0);
            mesh.quad(
                [
                    outer(t0, bottom),
                    outer(t1, bottom),
                    outer(t1, top),
                    outer(t0, top),
                ],
                [radial(t0), radial(t1), radial(t1), radial(t0)],
                Material::PART_WALL,
            );
            // The bore wall faces the axis.
            mesh.flat_triangle(
                [lift(a, bottom), lift(a, top), lift(b, top)],
                Material::BORE,
            );
            mesh.flat_triangle(
                [lift(a, bottom), lift(b, top), lift(b, bottom)],
                Material::BORE,
            );
        }
        mesh
    }

    /// A plastic bottle standing on its base at the origin, its axis along z: a rounded body,
    /// a shoulder, a neck and a cap.
    pub fn bottle(radius_m: f64, height_m: f64) -> Self {
        let (r, h) = (radius_m, height_m);
        let body = Material::BOTTLE;
        let cap = Material::BOTTLE_CAP;
        let mut profile = vec![(0.0, 0.0, body), (0.8 * r, 0.0, body)];
        // A rounded heel, then the straight body up to the shoulder at 0.6 h.
        for i in 1..=4 {
            let a = std::f64::consts::FRAC_PI_2 * f64::from(i) / 4.0;
            profile.push((0.8 * r + 0.2 * r * a.sin(), 0.2 * r * (1.0 - a.cos()), body));
        }
        profile.push((r, 0.6 * h, body));
        // The shoulder curves in to the neck (0.42 r) at 0.85 h.
        for i in 1..=6 {
            let s = f64::from(i) / 6.0;
            let radius = 0.42 * r + 0.58 * r * (std::f64::consts::FRAC_PI_2 * s).cos();
            profile.push((radius, 0.6 * h + 0.25 * h * s, body));
        }
        profile.push((0.42 * r, 0.92 * h, body));
        profile.push((0.48 * r, 0.92 * h, cap));
        profile.push((0.48 * r, h, cap));
        profile.push((0.0, h, cap));
        Self::lathe(&profile, ROUND_SEGMENTS)
    }
}

/// Angle of segment boundary `k` of `n` around a circle.
fn angle(k: usize, n: usize) -> f64 {
    std::f64::consts::TAU * (k % n) as f64 / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn part_end_face_edge_follows_the_true_bore() {
        let bore = BoreForm::Lobed {
            mean_radius_m: 0.012,
            amplitude_m: 0.0004,
            lobes: 3,
            phase_rad: 0.7,
        };
        let mesh = Mesh::axle_part(&bore, 0.019, 0.07);
        let top: Vec<&MeshVertex> = mesh
            .vertices
            .iter()
            .filter(|v| v.material == Material::END_FACE)
            .collect();
        assert!(!top.is_empty());
        let mut inner = 0;
        for v in &top {
            assert!((v.position.z - 0.035).abs() < 1e-12);
            let r = v.position.coords.xy().norm();
            let t = v.position.y.atan2(v.position.x);
            if (r - 0.019).abs() > 1e-9 {
                assert!((r - bore.radius_at(t)).abs() < 1e-12, "{r} at {t}");
                inner += 1;
            }
        }
        assert_eq!(inner, 3 * BORE_SEGMENTS);
    }

    #[test]
    fn closed_meshes_have_outward_normals() {
        // For a closed mesh, the sum of (centroid . normal) * area is 3 x volume > 0.
        let volume = |mesh: &Mesh| {
            mesh.vertices
                .chunks(3)
                .map(|t| {
                    let n = (t[1].position - t[0].position).cross(&(t[2].position - t[0].position));
                    t[0].position.coords.dot(&n) / 6.0
                })
                .sum::<f64>()
        };
        let cube = Mesh::cuboid(Vector3::new(0.1, 0.2, 0.3), Material::BELT);
        assert!((volume(&cube) - 0.048).abs() < 1e-12);
        let cylinder = Mesh::cylinder_z(0.05, 0.1, Material::BELT);
        let exact = std::f64::consts::PI * 0.05 * 0.05 * 0.2;
        assert!((volume(&cylinder) - exact).abs() < 0.01 * exact);
        let bore = BoreForm::Ellipse {
            a_m: 0.0101,
            b_m: 0.0099,
            angle_rad: 0.2,
        };
        let tube = Mesh::axle_part(&bore, 0.017, 0.06);
        let exact = std::f64::consts::PI * (0.017f64.powi(2) - 0.0101 * 0.0099) * 0.06;
        assert!((volume(&tube) - exact).abs() < 1e-3 * exact);
        assert!(volume(&Mesh::bottle(0.033, 0.2)) > 0.0);
    }
}
