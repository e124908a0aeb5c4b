//! The cell's geometry as Rerun archetypes: meshes, poses and colours.

use nalgebra::Isometry3;
use rerun::{Color, Mesh3D, Quaternion, Transform3D};

use crate::render::material::Material;
use crate::render::mesh::Mesh;

/// A triangle list as a Rerun mesh (no indices: every three vertices make a triangle), coloured
/// by each vertex's material.
pub(crate) fn mesh_3d(mesh: &Mesh) -> Mesh3D {
    let positions = mesh.vertices.iter().map(|v| {
        let p = v.position.coords.cast::<f32>();
        [p.x, p.y, p.z]
    });
    let normals = mesh.vertices.iter().map(|v| {
        let n = v.normal.cast::<f32>();
        [n.x, n.y, n.z]
    });
    let colors = mesh.vertices.iter().map(|v| material_color(&v.material));
    Mesh3D::new(positions)
        .with_vertex_normals(normals)
        .with_vertex_colors(colors)
}

/// A pose as the transform from an entity's frame to its parent's.
pub(crate) fn transform(parent_from_child: &Isometry3<f64>) -> Transform3D {
    let t = parent_from_child.translation.vector.cast::<f32>();
    let q = parent_from_child.rotation.quaternion().cast::<f32>();
    Transform3D::from_translation_rotation(
        [t.x, t.y, t.z],
        Quaternion::from_xyzw([q.i, q.j, q.k, q.w]),
    )
}

/// A material's diffuse albedo (linear) as an sRGB colour.
fn material_color(material: &Material) -> Color {
    let [r, g, b] = material.albedo.map(|linear| {
        let c = linear.clamp(0.0, 1.0);
        let srgb = if c <= 0.003_130_8 {
            12.92 * c
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        };
        (srgb * 255.0).round() as u8
    });
    Color::from_rgb(r, g, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn albedo_maps_to_srgb() {
        let white = Material {
            albedo: [1.0, 0.0, 0.214],
            ..Material::BELT
        };
        // 0.214 linear is about 0.5 in sRGB.
        assert_eq!(material_color(&white), Color::from_rgb(255, 0, 127));
    }
}
