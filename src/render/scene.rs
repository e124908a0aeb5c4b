//! What the camera sees: the cell's bodies as meshes with world poses, read from a built [`Cell`].
//!
//! The scene is a snapshot: building it reads the physics world and never changes it. Every
//! collider becomes a mesh of its own shape, except the part and the bottle, whose bodies get
//! their true geometry (the part's bore follows its [`crate::cell::BoreForm`]).

use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Vector3};
use rapier3d::prelude::{Collider, ColliderHandle, RigidBodyHandle};

use super::material::Material;
use super::mesh::{Mesh, ROUND_SEGMENTS};
use super::motion_blur::MotionBlur;
use crate::cell::Cell;
use crate::math::{pose_from_physics, vector_from_physics};
use crate::scenario::Scenario;
use crate::sim::{PartInstance, Tag};

/// What an object is, for ground truth and dataset labels.
#[derive(Debug, Clone, PartialEq)]
pub enum ObjectKind {
    /// The axle part with its true geometry.
    Part(PartInstance),
    /// The plastic bottle.
    Bottle,
    /// Anything else: belt, frame, floor, bins, robot.
    Scenery,
}

/// One rigid object in the scene.
#[derive(Debug, Clone)]
pub struct SceneObject {
    /// A name for messages (`part`, `bottle`, `belt`, a robot link's name).
    pub name: String,
    /// The physics body it was read from.
    pub body: Option<RigidBodyHandle>,
    /// The object's pose in the world.
    pub world_from_object: Isometry3<f64>,
    /// Its mesh in its own frame.
    pub mesh: Arc<Mesh>,
    /// What it is.
    pub kind: ObjectKind,
}

/// All objects the camera may see.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// The objects, in a fixed order (the physics world's collider order).
    pub objects: Vec<SceneObject>,
    /// The objects' motion over the camera's exposure, when it blurs the frame.
    pub blur: Option<MotionBlur>,
}

impl Scene {
    /// Reads the cell's bodies as they stand now.
    pub fn from_cell(cell: &Cell, scenario: &Scenario) -> Self {
        let physics = &cell.world.physics;
        let link_name = |handle: ColliderHandle| {
            cell.arm
                .link_of_collider(handle)
                .map(|link| link.name.as_str())
        };
        let mut objects = Vec::new();
        for (handle, collider) in physics.colliders.iter() {
            let Some(body) = collider.parent() else {
                continue;
            };
            let Some(rb) = physics.bodies.get(body) else {
                continue;
            };
            let world_from_body = pose_from_physics(rb.position());
            let tag = collider.user_data;
            if tag == Tag::Part.bits() || tag == Tag::Bottle.bits() || tag == Tag::PhotoEye.bits() {
                // Drawn once per body below (the photo-eye's beam is invisible).
                continue;
            }
            let material = if tag == Tag::Belt.bits() {
                Material::BELT
            } else if tag == Tag::Bin.bits() {
                Material::BIN
            } else if tag == Tag::Robot.bits() {
                match link_name(handle) {
                    Some(name) if name.starts_with("finger") || name.starts_with("gripper") => {
                        Material::GRIPPER
                    }
                    _ => Material::ROBOT,
                }
            } else if collider_is_floor(collider) {
                Material::FLOOR
            } else {
                Material::FRAME
            };
            let Some(mesh) = collider_mesh(collider, material) else {
                tracing::debug!("collider of an unsupported shape left out of the render");
                continue;
            };
            let body_from_collider = collider
                .position_wrt_parent()
                .map_or_else(Isometry3::identity, pose_from_physics);
            let name = if tag == Tag::Belt.bits() {
                "belt".to_string()
            } else {
                link_name(handle).unwrap_or("scenery").to_string()
            };
            objects.push(SceneObject {
                name,
                body: Some(body),
                world_from_object: world_from_body * body_from_collider,
                mesh: Arc::new(mesh),
                kind: ObjectKind::Scenery,
            });
        }
        let mut scene = Self {
            objects,
            blur: None,
        };
        // Every part and bottle on the belt, in the registry's order.
        for part in cell.items.parts() {
            if let Some(world_from_part) = cell.body_pose(part.body) {
                scene.push_part(part.body, world_from_part, &part.instance);
            }
        }
        for bottle in cell.items.bottles() {
            let Some(world_from_bottle) = cell.body_pose(bottle.body) else {
                continue;
            };
            scene.objects.push(SceneObject {
                name: "bottle".into(),
                body: Some(bottle.body),
                world_from_object: world_from_bottle,
                mesh: Arc::new(Mesh::bottle(
                    scenario.bottle.radius_m,
                    scenario.bottle.height_m,
                )),
                kind: ObjectKind::Bottle,
            });
        }
        scene.blur = MotionBlur::of_cell(&scene, cell, scenario.camera.exposure_ms);
        scene
    }

    /// Adds a part on `body` at `world_from_part` (a stream's further parts).
    pub fn push_part(
        &mut self,
        body: RigidBodyHandle,
        world_from_part: Isometry3<f64>,
        part: &PartInstance,
    ) {
        self.objects.push(SceneObject {
            name: "part".into(),
            body: Some(body),
            world_from_object: world_from_part,
            mesh: Arc::new(Mesh::axle_part(
                &part.bore,
                part.outer_radius_m,
                part.height_m,
            )),
            kind: ObjectKind::Part(part.clone()),
        });
    }

    /// Moves every object of `body` by `offset` (world frame), as if the body had been placed
    /// elsewhere: used to stage a shot without touching the physics world.
    pub fn translate_body(&mut self, body: RigidBodyHandle, offset: &Vector3<f64>) {
        for object in &mut self.objects {
            if object.body == Some(body) {
                object.world_from_object.translation.vector += offset;
            }
        }
    }

    /// The scene of `cell` with its first part standing where the belt stops it (leading edge
    /// at the photo-eye's beam, its drawn lateral offset kept) and the bottles keeping their
    /// offsets from it: how `twincell calibrate` stages a shot of a pick station without
    /// stepping the physics. Also gives the part's index among the scene's objects; `None`
    /// when the cell has no part.
    pub fn at_photo_eye(cell: &Cell, scenario: &Scenario) -> Option<(Self, usize)> {
        let mut scene = Self::from_cell(cell, scenario);
        let first = cell.items.parts().first()?;
        let (part, body) = (&first.instance, first.body);
        let pose = cell.body_pose(body)?;
        let stop_x = scenario.conveyor.photo_eye_x_m - part.outer_radius_m;
        let offset = Vector3::new(stop_x - pose.translation.x, 0.0, 0.0);
        scene.translate_body(body, &offset);
        for bottle in cell.items.bottles() {
            scene.translate_body(bottle.body, &offset);
        }
        let index = scene
            .objects
            .iter()
            .position(|o| o.body == Some(body) && matches!(o.kind, ObjectKind::Part(_)))?;
        Some((scene, index))
    }

    /// The part, if the scene has one.
    pub fn part(&self) -> Option<(&SceneObject, &PartInstance)> {
        self.objects.iter().find_map(|o| match &o.kind {
            ObjectKind::Part(part) => Some((o, part)),
            _ => None,
        })
    }

    /// Total triangles.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.triangle_count()).sum()
    }
}

impl SceneObject {
    /// The mesh's vertices in the world.
    pub fn world_points(&self) -> impl Iterator<Item = Point3<f64>> + '_ {
        self.mesh
            .vertices
            .iter()
            .map(|v| self.world_from_object * v.position)
    }
}

/// The floor is the one collider wider than 2 m.
fn collider_is_floor(collider: &Collider) -> bool {
    collider
        .shape()
        .as_cuboid()
        .is_some_and(|c| c.half_extents.x > 1.0 && c.half_extents.y > 1.0)
}

/// A mesh of a collider's shape in the collider's frame, or `None` for shapes never used here.
fn collider_mesh(collider: &Collider, material: Material) -> Option<Mesh> {
    let shape = collider.shape();
    if let Some(cuboid) = shape.as_cuboid() {
        return Some(Mesh::cuboid(
            vector_from_physics(cuboid.half_extents),
            material,
        ));
    }
    if let Some(cylinder) = shape.as_cylinder() {
        // Rapier's cylinders run along y; ours along z: rotate the vertices.
        let mesh = Mesh::cylinder_z(
            f64::from(cylinder.radius),
            f64::from(cylinder.half_height),
            material,
        );
        return Some(rotate_z_to_y(mesh));
    }
    if let Some(ball) = shape.as_ball() {
        let r = f64::from(ball.radius);
        let profile: Vec<(f64, f64, Material)> = (0..=ROUND_SEGMENTS / 4)
            .map(|i| {
                let a = std::f64::consts::PI * i as f64 / (ROUND_SEGMENTS / 4) as f64;
                (r * a.sin(), -r * a.cos(), material)
            })
            .collect();
        return Some(Mesh::lathe(&profile, ROUND_SEGMENTS));
    }
    None
}

/// Maps a mesh built along z onto the y axis (x stays, z -> y, y -> -z).
fn rotate_z_to_y(mut mesh: Mesh) -> Mesh {
    let rotation =
        nalgebra::UnitQuaternion::from_euler_angles(-std::f64::consts::FRAC_PI_2, 0.0, 0.0);
    for v in &mut mesh.vertices {
        v.position = rotation * v.position;
        v.normal = rotation * v.normal;
    }
    mesh
}
