//! Triangle meshes of the cell's bodies in their own frames, with per-vertex materials.
//!
//! Every mesh is a plain triangle list (three vertices per triangle, outward normals, counter-
//! clockwise seen from outside). The axle part's mesh carries its true bore: the end face's inner
//! edge follows [`BoreForm::radius_at`] at [`BORE_SEGMENTS`] points.
//!
//! Triangles are kept few and wide where that costs no accuracy: a software rasteriser shades
//! whole 4x4 pixel blocks, so a sub-pixel sliver costs as much as a block of pixels.

use nalgebra::{Point3, Vector3};

use super::material::Material;
use crate::cell::BoreForm;

/// Segments around a bore (its edge error is below 0.1 um for a 44 mm bore).
pub const BORE_SEGMENTS: usize = 1024;
/// Segments around other round bodies.
pub const ROUND_SEGMENTS: usize = 64;
/// Segments around a part's outer wall (its edge error is below 10 um for a 62 mm part).
pub const OUTER_SEGMENTS: usize = 128;

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

    /// Fills the band between two closed rings, each listed counter-clockwise about z from the
    /// same angle: each point is joined to the other ring's points nearest in turn. The
    /// triangles wind counter-clockwise seen from +z where `a` lies inside `b` in a plane (swap
    /// the rings for the other side). `normal` is the band's, or each triangle's own if `None`.
    fn zip_rings(
        &mut self,
        a: &[Point3<f64>],
        b: &[Point3<f64>],
        normal: Option<Vector3<f64>>,
        material: Material,
    ) {
        let (n, m) = (a.len(), b.len());
        let (mut i, mut j) = (0, 0);
        while i < n || j < m {
            let (p, q) = (a[i % n], b[j % m]);
            // Advance the ring whose next point comes first in the turn.
            let next = if j == m || (i < n && (i + 1) * m <= (j + 1) * n) {
                i += 1;
                a[i % n]
            } else {
                j += 1;
                b[j % m]
            };
            match normal {
                Some(normal) => {
                    for position in [p, q, next] {
                        self.vertices.push(MeshVertex {
                            position,
                            normal,
                            material,
                        });
                    }
                }
                None => self.flat_triangle([p, q, next], material),
            }
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
    /// top, a turned outer wall ([`OUTER_SEGMENTS`]) and a dark bore wall.
    ///
    /// Only the end face's bore edge needs all [`BORE_SEGMENTS`] points; the triangles along it
    /// are kept short: the end face is a narrow band from the bore edge out to a ring a quarter of
    /// the wall thickness away, then a wide band to the outer edge, and the bore wall a band as
    /// deep as that below the edge, then [`OUTER_SEGMENTS`] facets down to the bottom (on the
    /// true bore at their corners). The bottom face, never in view, has [`OUTER_SEGMENTS`].
    pub fn axle_part(bore: &BoreForm, outer_radius_m: f64, height_m: f64) -> Self {
        let mut mesh = Self::default();
        let (n, m) = (BORE_SEGMENTS, OUTER_SEGMENTS);
        let (top, bottom) = (height_m / 2.0, -height_m / 2.0);
        let ring = |count: usize, z: f64, radius: &dyn Fn(f64) -> f64| -> Vec<Point3<f64>> {
            (0..count)
                .map(|k| {
                    let t = angle(k, count);
                    let r = radius(t);
                    Point3::new(r * t.cos(), r * t.sin(), z)
                })
                .collect()
        };
        let edge = ring(n, top, &|t| bore.radius_at(t));
        let widest = edge
            .iter()
            .map(|p| p.coords.xy().norm())
            .fold(0.0, f64::max);
        let band = ((outer_radius_m - widest) / 4.0).min(height_m / 4.0);
        let bore_at = |z: f64| ring(m, z, &|t| bore.radius_at(t));
        let outer_at = |z: f64| ring(m, z, &|_| outer_radius_m);
        let up = Some(Vector3::z());
        // End face.
        let middle = ring(m, top, &|t| bore.radius_at(t) + band);
        mesh.zip_rings(&edge, &middle, up, Material::END_FACE);
        mesh.zip_rings(&middle, &outer_at(top), up, Material::END_FACE);
        // The underside stands on the belt at the belt's own depth; dark, so where the two fight
        // for the depth test (seen down the bore) it looks like the belt.
        mesh.zip_rings(
            &outer_at(bottom),
            &bore_at(bottom),
            Some(-Vector3::z()),
            Material::BORE,
        );
        let radial = |p: &Point3<f64>| Vector3::new(p.x, p.y, 0.0).normalize();
        let (low, high) = (outer_at(bottom), outer_at(top));
        for k in 0..m {
            let (a, b) = (k, (k + 1) % m);
            mesh.quad(
                [low[a], low[b], high[b], high[a]],
                [
                    radial(&low[a]),
                    radial(&low[b]),
                    radial(&high[b]),
                    radial(&high[a]),
                ],
                Material::PART_WALL,
            );
        }
        // The bore wall faces the axis.
        let below_edge = bore_at(top - band);
        mesh.zip_rings(&below_edge, &edge, None, Material::BORE);
        mesh.zip_rings(&bore_at(bottom), &below_edge, None, Material::BORE);
        mesh
    }

    /// A plastic bottle standing on its base at the origin, its axis along z: a rounded body,
    /// a shoulder, a neck and a cap.
    pub fn bottle(radius_m: f64, height_m: f64) -> Self {
        Self::bottle_lathe(radius_m, height_m, ROUND_SEGMENTS)
    }

    /// [`Self::bottle`] with `segments` facets around (the renderer's [`ROUND_SEGMENTS`]; a
    /// fit that projects the bottle many times may take fewer).
    pub fn bottle_lathe(radius_m: f64, height_m: f64, segments: usize) -> Self {
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
        Self::lathe(&profile, segments)
    }
}

/// Angle of segment boundary `k` of `n` around a circle.
fn angle(k: usize, n: usize) -> f64 {
    std::f64::consts::TAU * (k % n) as f64 / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Twice the signed area of a polygon in the xy plane.
    fn twice_area(points: impl Iterator<Item = (f64, f64)> + Clone) -> f64 {
        let next = points.clone().cycle().skip(1);
        points.zip(next).map(|(a, b)| a.0 * b.1 - a.1 * b.0).sum()
    }

    #[test]
    fn part_end_face_edge_follows_the_true_bore() {
        let bore = BoreForm::Lobed {
            mean_radius_m: 0.012,
            amplitude_m: 0.0004,
            lobes: 3,
            phase_rad: 0.7,
        };
        let (outer, height) = (0.019, 0.07);
        let mesh = Mesh::axle_part(&bore, outer, height);
        let top: Vec<&[MeshVertex]> = mesh
            .vertices
            .chunks_exact(3)
            .filter(|t| t[0].material == Material::END_FACE)
            .collect();
        let mut on_bore: Vec<(f64, f64)> = Vec::new();
        let mut face_area = 0.0;
        for t in &top {
            let [a, b, c] = [t[0].position, t[1].position, t[2].position];
            // Flat, facing up, counter-clockwise seen from above.
            let normal = (b - a).cross(&(c - a));
            assert!(normal.z > 0.0 && normal.xy().norm() < 1e-15, "{normal}");
            face_area += normal.z / 2.0;
            for p in [a, b, c] {
                assert!((p.z - height / 2.0).abs() < 1e-12);
                let (r, angle) = (p.coords.xy().norm(), p.y.atan2(p.x));
                assert!(r <= outer + 1e-12 && r >= bore.radius_at(angle) - 1e-12);
                if (r - bore.radius_at(angle)).abs() < 1e-12 {
                    on_bore.push((p.x, p.y));
                }
            }
        }
        // The face's inner edge is the bore at every one of its points...
        on_bore.sort_by(|a, b| a.1.atan2(a.0).total_cmp(&b.1.atan2(b.0)));
        on_bore.dedup();
        assert_eq!(on_bore.len(), BORE_SEGMENTS);
        // ...and the face covers exactly the outer polygon less the bore polygon: no gap, no
        // overlap.
        let outer_polygon = (0..OUTER_SEGMENTS).map(|k| {
            let t = angle(k, OUTER_SEGMENTS);
            (outer * t.cos(), outer * t.sin())
        });
        let exact = (twice_area(outer_polygon) - twice_area(on_bore.iter().copied())) / 2.0;
        assert!(
            (face_area - exact).abs() < 1e-12 * exact,
            "{face_area} {exact}"
        );
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
