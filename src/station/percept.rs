//! What perception tells the planner about the pick station: the part to pick and the things
//! near it that the arm must not touch.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use rapier3d::geometry::SharedShape;

use crate::scenario::{BottleSection, PartTypeId};

/// What perception reports about the pick station, from the camera or from the oracle.
#[derive(Debug, Clone)]
pub struct Percept {
    /// The part's type, as detected.
    pub part_type: PartTypeId,
    /// Part's centre on the belt (x, y), world, m.
    pub part_xy: [f64; 2],
    /// The detected type's outer radius, m.
    pub part_outer_radius_m: f64,
    /// The detected type's height, m.
    pub part_height_m: f64,
    /// Measured bore roundness, mm (`None` when the bore was not measured).
    pub roundness_mm: Option<f64>,
    /// Measured bore diameter, mm.
    pub bore_diameter_mm: Option<f64>,
    /// Why the measurement contradicts the detection, if it does (the part is then rejected).
    pub inconsistency: Option<String>,
    /// Why the part's type could not be named by measurement, if it could not (the part is then
    /// rejected; `part_type` is only the geometry it is handled with).
    pub unidentified: Option<String>,
    /// Other things on the belt near the part.
    pub obstacles: Vec<PerceivedObstacle>,
}

/// Something on the belt the arm must keep clear of, as perception placed it.
#[derive(Debug, Clone)]
pub struct PerceivedObstacle {
    /// What it is (`bottle`, `other part`), for reports.
    pub name: &'static str,
    /// Pose of the shape's centre in the world.
    pub world_from_shape: Isometry3<f64>,
    /// Its bounding shape.
    pub shape: SharedShape,
    /// Its highest point, world z, m.
    pub top_z: f64,
}

/// Rapier's cylinders run along y; ours stand along z.
fn z_cylinder_rotation() -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0)
}

/// A bottle at `world_from_bottle` (origin at its base centre, axis along local z) as the
/// planner's obstacle: its bounding cylinder grown by `growth_m` all round.
pub fn bottle_obstacle(
    bottle: &BottleSection,
    world_from_bottle: &Isometry3<f64>,
    lying: bool,
    growth_m: f64,
) -> PerceivedObstacle {
    let half_height = bottle.height_m / 2.0 + growth_m;
    let radius = bottle.radius_m + growth_m;
    let shape = SharedShape::cylinder(half_height as f32, radius as f32);
    let world_from_shape = world_from_bottle
        * Isometry3::from_parts(
            Translation3::new(0.0, 0.0, bottle.height_m / 2.0),
            z_cylinder_rotation(),
        );
    let top_z = world_from_shape.translation.z + if lying { radius } else { half_height };
    PerceivedObstacle {
        name: "bottle",
        world_from_shape,
        shape,
        top_z,
    }
}

/// Another upright part centred at `center_in_world` as the planner's obstacle.
pub fn part_obstacle(
    center_in_world: &Point3<f64>,
    outer_radius_m: f64,
    height_m: f64,
) -> PerceivedObstacle {
    let shape = SharedShape::cylinder((height_m / 2.0) as f32, outer_radius_m as f32);
    let world_from_shape = Isometry3::from_parts(
        Translation3::from(center_in_world.coords),
        z_cylinder_rotation(),
    );
    PerceivedObstacle {
        name: "other part",
        world_from_shape,
        shape,
        top_z: center_in_world.z + height_m / 2.0,
    }
}
