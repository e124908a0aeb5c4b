//! Inserting the movable things on the belt (axle parts, bottles) into the world, and the one
//! registry that tracks them by body handle.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::prelude::*;

use super::tube_prism::TubePrism;
use super::{PartInstance, Tag, World};
use crate::math::{pose_from_physics, pose_to_physics, vector_to_physics};
use crate::scenario::BottleSection;

/// A part on the belt (or past it) and its body.
#[derive(Debug, Clone)]
pub struct PartItem {
    /// The part's body.
    pub body: RigidBodyHandle,
    /// The part as drawn, with its true bore.
    pub instance: PartInstance,
}

/// A bottle on the belt (or past it) and its body.
#[derive(Debug, Clone, Copy)]
pub struct BottleItem {
    /// The bottle's body.
    pub body: RigidBodyHandle,
    /// Whether it was put down lying on its side.
    pub lying: bool,
}

/// Every part and bottle in the world, in the order they were inserted.
#[derive(Debug, Clone, Default)]
pub struct ItemSet {
    parts: Vec<PartItem>,
    bottles: Vec<BottleItem>,
}

impl ItemSet {
    /// The parts, in insertion order.
    pub fn parts(&self) -> &[PartItem] {
        &self.parts
    }

    /// The bottles, in insertion order.
    pub fn bottles(&self) -> &[BottleItem] {
        &self.bottles
    }

    /// Inserts `part` as a dynamic tube standing on the belt with its centre over `xy`; returns
    /// its index among the parts.
    pub fn insert_part(
        &mut self,
        world: &mut World,
        part: PartInstance,
        xy: [f64; 2],
        belt_top_z: f64,
    ) -> usize {
        let body = insert_part(world, &part, xy, belt_top_z);
        self.parts.push(PartItem {
            body,
            instance: part,
        });
        self.parts.len() - 1
    }

    /// Inserts a bottle with its base centre (or, lying, its middle) over `xy`; returns its
    /// index among the bottles.
    pub fn insert_bottle(
        &mut self,
        world: &mut World,
        bottle: &BottleSection,
        placement: BottlePlacement,
        belt_top_z: f64,
    ) -> usize {
        let body = insert_bottle_at(
            world,
            bottle,
            placement.xy,
            placement.lying,
            placement.yaw_rad,
            belt_top_z,
        );
        self.bottles.push(BottleItem {
            body,
            lying: placement.lying,
        });
        self.bottles.len() - 1
    }

    /// The part whose body is `body`.
    pub fn part_of(&self, body: RigidBodyHandle) -> Option<usize> {
        self.parts.iter().position(|p| p.body == body)
    }

    /// The bottle whose body is `body`.
    pub fn bottle_of(&self, body: RigidBodyHandle) -> Option<usize> {
        self.bottles.iter().position(|b| b.body == body)
    }

    /// Every movable item's body: the parts, then the bottles.
    pub fn bodies(&self) -> impl Iterator<Item = RigidBodyHandle> + '_ {
        self.parts
            .iter()
            .map(|p| p.body)
            .chain(self.bottles.iter().map(|b| b.body))
    }
}

/// Where and how a bottle is put on the belt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BottlePlacement {
    /// Base centre (standing) or middle (lying) over the belt, world x and y, m.
    pub xy: [f64; 2],
    /// Lying on its side, its axis along the belt turned by `yaw_rad`.
    pub lying: bool,
    /// Turn about the vertical, rad.
    pub yaw_rad: f64,
}

/// Pose of a body in `world`.
pub fn body_pose(world: &World, body: RigidBodyHandle) -> Option<Isometry3<f64>> {
    world
        .physics
        .bodies
        .get(body)
        .map(|b| pose_from_physics(b.position()))
}

/// Sets `body` moving at `velocity` (world, m/s), without spin: how a feeder hands an item over
/// to a running belt, at the belt's own speed (put down at rest on a belt at 0.5 m/s, the belt's
/// friction kicks a slender tube or a standing bottle over).
pub fn set_body_velocity(world: &mut World, body: RigidBodyHandle, velocity: &Vector3<f64>) {
    if let Some(b) = world.physics.bodies.get_mut(body) {
        b.set_linvel(vector_to_physics(velocity), true);
        b.set_angvel(Vector::ZERO, true);
    }
}

/// Rapier's cylinders run along y; ours stand along z.
fn z_cylinder_rotation() -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0)
}

/// Inserts the part as a dynamic tube (solid cylinder collider with the tube's mass properties).
fn insert_part(
    world: &mut World,
    part: &PartInstance,
    xy: [f64; 2],
    belt_top_z: f64,
) -> RigidBodyHandle {
    let center = Isometry3::translation(xy[0], xy[1], belt_top_z + part.height_m / 2.0);
    let body = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .pose(pose_to_physics(&center))
            .can_sleep(false)
            .user_data(Tag::Part as u128),
    );
    let (outer, inner, h, m) = (
        part.outer_radius_m,
        part.bore_radius_m(),
        part.height_m,
        part.mass_kg,
    );
    let axial = 0.5 * m * (outer * outer + inner * inner);
    let transverse = m / 12.0 * (3.0 * (outer * outer + inner * inner) + h * h);
    let rotation = z_cylinder_rotation();
    // In the collider's own frame the axis is y.
    let props = MassProperties::new(
        Vector::ZERO,
        m as f32,
        Vector::new(transverse as f32, axial as f32, transverse as f32),
    );
    let collider = ColliderBuilder::new(tube_shape(outer, h))
        .rotation(vector_to_physics(&rotation.scaled_axis()))
        .mass_properties(props)
        .friction(0.6)
        .user_data(Tag::Part as u128);
    let physics = &mut world.physics;
    physics
        .colliders
        .insert_with_parent(collider, body, &mut physics.bodies);
    body
}

/// Sides of the prism that carries a tube's flanks.
const TUBE_SIDES: u32 = 32;
/// Height of the bevel that takes a tube's end faces from its 32-gon to a square, m.
const TUBE_BEVEL_M: f64 = 0.0005;
/// Half-diagonal of a tube end face's square over the tube's radius.
const TUBE_FOOT_SHARE: f64 = 0.85;

/// A tube's collider, axis along y: a convex 32-sided prism, not a round cylinder, so that flat
/// pads touch it along lines, as real pads touch a tube, and the solver gets several contact
/// points to resist twisting. Its end faces are squares, bevelled over 0.5 mm into the 32-gon:
/// contact generation keeps at most four vertices of a face, and the first four of a 32-gon
/// are a sliver along one edge, on which a standing tube balanced and kept rocking by up to
/// 2 degrees (the camera saw up to 0.1 mm of false roundness). On a centred square it stands
/// still.
pub(super) fn tube_shape(radius: f64, height: f64) -> SharedShape {
    let mut points = Vec::with_capacity(2 * TUBE_SIDES as usize + 8);
    let mut ring = |r: f64, y: f64, sides: u32| {
        for i in 0..sides {
            let angle = std::f64::consts::TAU * f64::from(i) / f64::from(sides);
            points.push(Vector::new(
                (r * angle.cos()) as f32,
                y as f32,
                (r * angle.sin()) as f32,
            ));
        }
    };
    let (top, flank) = (height / 2.0, height / 2.0 - TUBE_BEVEL_M);
    for sign in [-1.0, 1.0] {
        ring(radius, sign * flank, TUBE_SIDES);
        ring(TUBE_FOOT_SHARE * radius, sign * top, 4);
    }
    // The same prism with its support point found near the direction (`sim::tube_prism`).
    match rapier3d::parry::shape::ConvexPolyhedron::from_convex_hull(&points) {
        Some(hull) => match TubePrism::new(hull, radius as f32, TUBE_SIDES as usize) {
            Ok(prism) => SharedShape::new(prism),
            Err(hull) => SharedShape::new(*hull),
        },
        None => SharedShape::cylinder(top as f32, radius as f32),
    }
}

/// A bottle that moves slower than this, and turns slower than [`REST_SPIN_RAD_S`], for
/// [`REST_TIME_S`] comes to rest (rapier's sleep: it is not simulated until something
/// touches it or the belt runs, `Cell::step`), m/s. A bottle left on the stopped belt while the
/// arm carries the part away rests for most of a trial, and its contacts with the belt were
/// about a sixth of a paper_50 trial's physics instructions. The thresholds are a tenth of
/// rapier's defaults, so that a bottle still rocking or tipping slowly is not frozen mid-way.
/// Parts never rest: theirs would save about 1 % of a trial's instructions, and the camera
/// measures a part standing at the station, whose settling is then the metrology's business.
const REST_SPEED_M_S: f32 = 0.005;
/// See [`REST_SPEED_M_S`], rad/s.
const REST_SPIN_RAD_S: f32 = 0.05;
/// See [`REST_SPEED_M_S`], s.
const REST_TIME_S: f32 = 0.5;

/// Lets `body` come to rest once it is still ([`REST_SPEED_M_S`]).
fn rest_when_still(world: &mut World, body: RigidBodyHandle) {
    if let Some(b) = world.physics.bodies.get_mut(body) {
        let activation = b.activation_mut();
        activation.normalized_linear_threshold = REST_SPEED_M_S;
        activation.angular_threshold = REST_SPIN_RAD_S;
        activation.time_until_sleep = REST_TIME_S;
    }
}

/// Inserts a bottle with its base centre (or, lying, its middle) over `xy` on the belt.
fn insert_bottle_at(
    world: &mut World,
    bottle: &BottleSection,
    xy: [f64; 2],
    lying: bool,
    yaw: f64,
    belt_top_z: f64,
) -> RigidBodyHandle {
    let (z, rotation) = if lying {
        (
            belt_top_z + bottle.radius_m,
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw)
                * UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
        )
    } else {
        (belt_top_z, UnitQuaternion::from_euler_angles(0.0, 0.0, yaw))
    };
    // The body's origin is the bottle's base centre; its axis is the body's z.
    let pose = Isometry3::from_parts(Translation3::new(xy[0], xy[1], z), rotation);
    let pose = if lying {
        pose * Isometry3::translation(0.0, 0.0, -bottle.height_m / 2.0)
    } else {
        pose
    };
    let body = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .pose(pose_to_physics(&pose))
            .user_data(Tag::Bottle as u128),
    );
    rest_when_still(world, body);
    let shoulder_h = bottle.height_m * 0.72;
    let neck_h = bottle.height_m - shoulder_h;
    let axis = z_cylinder_rotation();
    let parts = [
        (shoulder_h / 2.0, shoulder_h / 2.0, bottle.radius_m, 0.85),
        (
            shoulder_h + neck_h / 2.0,
            neck_h / 2.0,
            bottle.radius_m * 0.42,
            0.15,
        ),
    ];
    let physics = &mut world.physics;
    for (i, (center_z, half_h, radius, mass_share)) in parts.into_iter().enumerate() {
        // The lying bottle's body rests on the belt; see `lying_body_shape` for why it is not
        // a round cylinder. The neck never touches the belt (its radius is smaller).
        let shape = if lying && i == 0 {
            lying_body_shape(radius, half_h)
        } else {
            SharedShape::cylinder(half_h as f32, radius as f32)
        };
        let collider = ColliderBuilder::new(shape)
            .translation(Vector::new(0.0, 0.0, center_z as f32))
            .rotation(vector_to_physics(&axis.scaled_axis()))
            .mass((bottle.mass_kg * mass_share) as f32)
            .friction(0.5)
            .user_data(Tag::Bottle as u128);
        physics
            .colliders
            .insert_with_parent(collider, body, &mut physics.bodies);
    }
    body
}

/// Sides of the prism that carries a lying bottle's body.
const LYING_BOTTLE_SIDES: u32 = 16;

/// A lying bottle's body, axis along y: a convex 16-sided prism whose flat faces touch the
/// body's radius, with one face down once the bottle lies (the collider's +x turns to world -z).
///
/// A round cylinder lying on the belt rolls without any resistance, and rapier's contact
/// between a rolling cylinder and the belt's box (parry's polygonal-feature contact, which
/// stands the cylinder's curved side in by a single segment plus one GJK point) neither keeps
/// the rolling constraint nor conserves energy: on a belt ramping at 1 m/s^2 a bottle lying
/// across it lost its spin within a step and rode on at the belt's speed, then rolled on for
/// metres once the belt stopped (off the belt's end and off the floor's edge in the suite's
/// clutter trials); at 32 of 48 yaws and belt speeds a bottle sped up to 1.8-30 m/s, and even
/// one lying nearly along the belt moved 130 mm after the stop (`tests/lying_bottle.rs`). A prism rests on a face and only tips over an edge when the
/// belt's acceleration exceeds g tan(180/16 degrees) = 1.95 m/s^2, twice the drive's ramp: the
/// bottle rides the belt and stops with it, as a bottle does whose rolling resistance (its
/// shoulder, ribs and label) holds it against the belt's gentle ramp.
fn lying_body_shape(radius: f64, half_height: f64) -> SharedShape {
    let step = std::f64::consts::TAU / f64::from(LYING_BOTTLE_SIDES);
    // Corners on the circle through r / cos(half a step), so that every face is `radius`
    // from the axis: the bottle lies at the height it was put at.
    let corner = radius / (step / 2.0).cos();
    let mut points = Vec::with_capacity(2 * LYING_BOTTLE_SIDES as usize);
    for y in [-half_height, half_height] {
        for i in 0..LYING_BOTTLE_SIDES {
            let angle = step * (f64::from(i) + 0.5);
            points.push(Vector::new(
                (corner * angle.cos()) as f32,
                y as f32,
                (corner * angle.sin()) as f32,
            ));
        }
    }
    SharedShape::convex_hull(&points)
        .unwrap_or_else(|| SharedShape::cylinder(half_height as f32, radius as f32))
}
