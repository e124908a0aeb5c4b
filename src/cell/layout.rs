//! Building the cell's physics world from a scenario.

use std::path::PathBuf;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::prelude::*;

use super::{ConveyorHooks, PartInstance, gripper_tcp};
use crate::kinematics::{ArmModel, DOF, link_frames};
use crate::math::{pose_from_physics, pose_to_physics, vector_to_physics};
use crate::planning::{LinkMount, Obstacle, RobotShape};
use crate::rng::SimRng;
use crate::scenario::Scenario;
use crate::sim::{SimArm, SimError, World, WorldParams};

/// What a collider is, stored in its `user_data`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tag {
    /// Static scenery: floor, pedestal, conveyor frame.
    Scenery = 1,
    /// The belt's top.
    Belt = 2,
    /// The photo-eye's beam.
    PhotoEye = 3,
    /// The trial's axle part.
    Part = 4,
    /// The plastic bottle.
    Bottle = 5,
    /// A bin's floor or wall.
    Bin = 6,
    /// A robot link.
    Robot = 7,
}

/// Why a cell could not be built.
#[derive(Debug, thiserror::Error)]
pub enum CellError {
    /// The arm could not be loaded.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The scenario lacks something the cell needs.
    #[error("scenario: {0}")]
    Scenario(String),
    /// The camera pipeline (renderer, detector model) could not be set up.
    #[error(transparent)]
    Camera(Box<super::camera_perception::CameraPerceptionError>),
}

/// A bin in the world.
#[derive(Debug, Clone)]
pub struct BinBody {
    /// The bin's name.
    pub name: String,
    /// Centre of the floor's top surface in the world, m.
    pub floor_center: Vector3<f64>,
    /// Inside size along x and y, m.
    pub size: [f64; 2],
    /// Wall height, m.
    pub wall_height: f64,
}

impl BinBody {
    /// Whether a world point lies inside the bin (within its walls, below the rim).
    pub fn contains(&self, point: &Vector3<f64>) -> bool {
        let d = point - self.floor_center;
        d.x.abs() <= self.size[0] / 2.0
            && d.y.abs() <= self.size[1] / 2.0
            && d.z >= -0.01
            && d.z <= self.wall_height
    }
}

/// The built cell: the world, the arm, and handles to everything a trial watches.
pub struct Cell {
    /// The physics world.
    pub world: World,
    /// The arm.
    pub arm: SimArm,
    /// The belt's contact hooks (its speed).
    pub conveyor: ConveyorHooks,
    /// The photo-eye's sensor collider.
    pub photo_eye: ColliderHandle,
    /// The part's body.
    pub part_body: RigidBodyHandle,
    /// The part drawn for this trial.
    pub part: PartInstance,
    /// The bottle's body, when there is one.
    pub bottle_body: Option<RigidBodyHandle>,
    /// Whether the bottle lies on its side.
    pub bottle_lying: bool,
    /// The bins.
    pub bins: Vec<BinBody>,
    /// Static obstacles for the planner, in the arm's base frame.
    pub obstacles: Vec<Obstacle>,
    /// The robot's collision shapes for the planner.
    pub robot_shapes: Vec<RobotShape>,
    /// Finger offset at which `robot_shapes` were captured, m.
    pub finger_reference_m: f64,
    /// Top of the belt, world z, m.
    pub belt_top_z: f64,
}

/// Rapier's cylinders run along y; ours stand along z.
fn z_cylinder_rotation() -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0)
}

struct Builder<'a> {
    world: &'a mut World,
    base_from_world: Isometry3<f64>,
    obstacles: Vec<Obstacle>,
}

impl Builder<'_> {
    /// A fixed box with centre `center` and half extents `half`, tagged, optionally an obstacle.
    fn fixed_box(
        &mut self,
        name: &str,
        center: [f64; 3],
        half: [f64; 3],
        tag: Tag,
        friction: f32,
        obstacle: bool,
    ) -> ColliderHandle {
        let pose = Isometry3::translation(center[0], center[1], center[2]);
        let shape = SharedShape::cuboid(half[0] as f32, half[1] as f32, half[2] as f32);
        let body = self
            .world
            .physics
            .bodies
            .insert(RigidBodyBuilder::fixed().pose(pose_to_physics(&pose)));
        let collider = ColliderBuilder::new(shape.clone())
            .friction(friction)
            .user_data(tag as u128);
        let physics = &mut self.world.physics;
        let handle = physics
            .colliders
            .insert_with_parent(collider, body, &mut physics.bodies);
        if obstacle {
            self.obstacles.push(Obstacle {
                name: name.to_string(),
                base_from_shape: self.base_from_world * pose,
                shape,
            });
        }
        handle
    }
}

impl Cell {
    /// Builds the cell for one trial: the scenario's fixed layout plus a part and a bottle drawn
    /// from `rng`, the arm at home.
    pub fn build(
        scenario: &Scenario,
        urdf: Option<&(PathBuf, String)>,
        rng: &mut SimRng,
    ) -> Result<Self, CellError> {
        let mut world = World::new(WorldParams {
            dt_s: scenario.physics.dt_s,
            gravity_m_s2: 9.81,
            solver_iterations: scenario.physics.solver_iterations,
            contact_frequency_hz: scenario.physics.contact_frequency_hz,
            contact_damping_ratio: scenario.physics.contact_damping_ratio,
        });
        let base = scenario.robot.base_xyz_m;
        let world_from_base = Isometry3::translation(base[0], base[1], base[2]);
        let arm = match urdf {
            Some((path, text)) => SimArm::from_urdf_str(&mut world, text, path, world_from_base)?,
            None => SimArm::load_builtin(&mut world, world_from_base)?,
        };
        let mut builder = Builder {
            world: &mut world,
            base_from_world: world_from_base.inverse(),
            obstacles: Vec::new(),
        };
        builder.fixed_box(
            "floor",
            [0.0, 0.0, -0.05],
            [3.0, 3.0, 0.05],
            Tag::Scenery,
            0.8,
            true,
        );
        let side = scenario.robot.pedestal_side_m / 2.0;
        builder.fixed_box(
            "pedestal",
            [base[0], base[1], base[2] / 2.0],
            [side, side, base[2] / 2.0],
            Tag::Scenery,
            0.8,
            true,
        );

        let belt = &scenario.conveyor;
        let belt_top_z = belt.belt_center_m[2];
        let thickness = 0.05;
        let belt_collider = builder.fixed_box(
            "conveyor",
            [
                belt.belt_center_m[0],
                belt.belt_center_m[1],
                belt_top_z - thickness / 2.0,
            ],
            [belt.length_m / 2.0, belt.width_m / 2.0, thickness / 2.0],
            Tag::Belt,
            belt.friction as f32,
            true,
        );
        // Side rails keep the planner's fingers off the belt edges.
        for side_sign in [-1.0, 1.0] {
            let y = belt.belt_center_m[1] + side_sign * (belt.width_m / 2.0 + 0.015);
            builder.fixed_box(
                "conveyor rail",
                [belt.belt_center_m[0], y, belt_top_z - 0.005],
                [belt.length_m / 2.0, 0.015, 0.03],
                Tag::Scenery,
                0.5,
                true,
            );
        }
        // The photo-eye's beam across the belt, 10-50 mm above it.
        let eye_body = builder
            .world
            .physics
            .bodies
            .insert(
                RigidBodyBuilder::fixed().pose(pose_to_physics(&Isometry3::translation(
                    belt.photo_eye_x_m,
                    belt.belt_center_m[1],
                    belt_top_z + 0.03,
                ))),
            );
        let physics = &mut builder.world.physics;
        let photo_eye = physics.colliders.insert_with_parent(
            ColliderBuilder::cuboid(0.002, belt.width_m as f32 / 2.0, 0.02)
                .sensor(true)
                .user_data(Tag::PhotoEye as u128),
            eye_body,
            &mut physics.bodies,
        );
        if let Some(collider) = physics.colliders.get_mut(belt_collider) {
            collider.set_active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS);
        }

        let mut bins = Vec::with_capacity(scenario.bins.len());
        for bin in &scenario.bins {
            let [cx, cy, floor_z] = bin.floor_center_m;
            let [sx, sy] = bin.size_m;
            let (wall, h) = (0.006, bin.wall_height_m);
            let name = format!("bin {}", bin.name);
            let (hx, hy, hw) = (sx / 2.0, sy / 2.0, wall / 2.0);
            // Floor, then the walls at -x, +x, -y, +y.
            let slabs = [
                ([cx, cy, floor_z - hw], [hx + wall, hy + wall, hw]),
                (
                    [cx - hx - hw, cy, floor_z + h / 2.0],
                    [hw, hy + wall, h / 2.0],
                ),
                (
                    [cx + hx + hw, cy, floor_z + h / 2.0],
                    [hw, hy + wall, h / 2.0],
                ),
                ([cx, cy - hy - hw, floor_z + h / 2.0], [hx, hw, h / 2.0]),
                ([cx, cy + hy + hw, floor_z + h / 2.0], [hx, hw, h / 2.0]),
            ];
            for (center, half) in slabs {
                builder.fixed_box(&name, center, half, Tag::Bin, 0.6, true);
            }
            // The stand the bin sits on.
            let stand_h = floor_z - wall;
            if stand_h > 0.0 {
                builder.fixed_box(
                    &name,
                    [cx, cy, stand_h / 2.0],
                    [sx / 2.0, sy / 2.0, stand_h / 2.0],
                    Tag::Scenery,
                    0.6,
                    true,
                );
            }
            bins.push(BinBody {
                name: bin.name.clone(),
                floor_center: Vector3::new(cx, cy, floor_z),
                size: bin.size_m,
                wall_height: h,
            });
        }
        let obstacles = builder.obstacles;

        // The part, upstream of the photo-eye at a random lateral offset.
        let part = PartInstance::draw(scenario, rng);
        let lateral = rng.range(
            -scenario.parts.max_lateral_offset_m,
            scenario.parts.max_lateral_offset_m,
        );
        let part_xy = spawn_xy(scenario, lateral);
        let part_body = insert_part(&mut world, &part, part_xy, belt_top_z);

        let (bottle_body, bottle_lying) = if scenario.bottle.enabled {
            let (body, lying) = insert_bottle(
                &mut world,
                scenario,
                part_xy,
                part.outer_radius_m,
                belt_top_z,
                rng,
            );
            (Some(body), lying)
        } else {
            (None, false)
        };

        let home = scenario.robot.home_q_rad;
        let finger_reference_m = 0.045;
        arm.reset_to(&mut world, &home, finger_reference_m);
        set_robot_friction(&mut world, &arm, scenario.gripper.pad_friction);
        let robot_shapes = robot_shapes(&world, &arm, &home);
        Ok(Self {
            world,
            arm,
            conveyor: ConveyorHooks::new(belt_collider),
            photo_eye,
            part_body,
            part,
            bottle_body,
            bottle_lying,
            bins,
            obstacles,
            robot_shapes,
            finger_reference_m,
            belt_top_z,
        })
    }

    /// The arm's kinematic model with the gripper's TCP.
    pub fn arm_model() -> ArmModel {
        ArmModel::aubo_i5().with_tool(gripper_tcp())
    }

    /// Pose of a body in the world.
    pub fn body_pose(&self, body: RigidBodyHandle) -> Option<Isometry3<f64>> {
        self.world
            .physics
            .bodies
            .get(body)
            .map(|b| pose_from_physics(b.position()))
    }

    /// Puts a newly drawn part on the belt at the spawn point (a stream's feeder).
    pub fn spawn_part(
        &mut self,
        scenario: &Scenario,
        rng: &mut SimRng,
    ) -> (RigidBodyHandle, PartInstance) {
        let part = PartInstance::draw(scenario, rng);
        let lateral = rng.range(
            -scenario.parts.max_lateral_offset_m,
            scenario.parts.max_lateral_offset_m,
        );
        let xy = spawn_xy(scenario, lateral);
        let body = insert_part(&mut self.world, &part, xy, self.belt_top_z);
        (body, part)
    }

    /// Puts a bottle on the belt at the spawn point (a stream's feeder).
    pub fn spawn_bottle(&mut self, scenario: &Scenario, rng: &mut SimRng) -> RigidBodyHandle {
        let bottle = &scenario.bottle;
        let lying = rng.uniform() < bottle.lying_fraction;
        let footprint = if lying {
            bottle.height_m / 2.0
        } else {
            bottle.radius_m
        };
        let room = (scenario.conveyor.width_m / 2.0 - footprint).max(0.0);
        let lateral = rng.range(-room, room);
        // Lying bottles run along the belt so that they pass the station within its width.
        let yaw = if lying {
            rng.range(-0.3, 0.3)
        } else {
            rng.range(0.0, std::f64::consts::TAU)
        };
        let xy = spawn_xy(scenario, lateral);
        insert_bottle_at(&mut self.world, bottle, xy, lying, yaw, self.belt_top_z)
    }

    /// The bodies whose colliders break the photo-eye's beam, in handle order.
    pub fn bodies_at_photo_eye(&self) -> Vec<RigidBodyHandle> {
        let physics = &self.world.physics;
        let mut bodies: Vec<RigidBodyHandle> = physics
            .narrow_phase
            .intersection_pairs_with(self.photo_eye)
            .filter(|(_, _, intersecting)| *intersecting)
            .filter_map(|(c1, c2, _)| {
                let other = if c1 == self.photo_eye { c2 } else { c1 };
                physics.colliders.get(other)?.parent()
            })
            .collect();
        bodies.sort_by_key(|h| h.into_raw_parts());
        bodies.dedup();
        bodies
    }

    /// Whether the photo-eye's beam is broken by any body.
    pub fn photo_eye_blocked(&self) -> bool {
        self.world
            .physics
            .narrow_phase
            .intersection_pairs_with(self.photo_eye)
            .any(|(_, _, intersecting)| intersecting)
    }
}

/// The feeder's spawn point on the belt, `lateral` off the centre line.
fn spawn_xy(scenario: &Scenario, lateral: f64) -> [f64; 2] {
    let belt = &scenario.conveyor;
    [
        belt.photo_eye_x_m - belt.spawn_upstream_m,
        belt.belt_center_m[1] + lateral,
    ]
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
fn tube_shape(radius: f64, height: f64) -> SharedShape {
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
    SharedShape::convex_hull(&points)
        .unwrap_or_else(|| SharedShape::cylinder(top as f32, radius as f32))
}

/// Inserts the bottle near the part, on the belt and clear of it.
fn insert_bottle(
    world: &mut World,
    scenario: &Scenario,
    part_xy: [f64; 2],
    part_radius: f64,
    belt_top_z: f64,
    rng: &mut SimRng,
) -> (RigidBodyHandle, bool) {
    let bottle = &scenario.bottle;
    let belt = &scenario.conveyor;
    let lying = rng.uniform() < bottle.lying_fraction;
    let footprint = if lying {
        bottle.height_m / 2.0
    } else {
        bottle.radius_m
    };
    let y_low = belt.belt_center_m[1] - belt.width_m / 2.0 + footprint.min(belt.width_m / 2.0);
    let y_high = belt.belt_center_m[1] + belt.width_m / 2.0 - footprint.min(belt.width_m / 2.0);
    let mut xy = [part_xy[0] + bottle.distance_range_m[1], part_xy[1]];
    for _ in 0..64 {
        let distance = rng.range(bottle.distance_range_m[0], bottle.distance_range_m[1]);
        let angle = rng.range(0.0, std::f64::consts::TAU);
        let candidate = [
            part_xy[0] + distance * angle.cos(),
            part_xy[1] + distance * angle.sin(),
        ];
        if candidate[1] >= y_low
            && candidate[1] <= y_high
            && distance > part_radius + footprint + 0.01
        {
            xy = candidate;
            break;
        }
    }
    let yaw = rng.range(0.0, std::f64::consts::TAU);
    let body = insert_bottle_at(world, bottle, xy, lying, yaw, belt_top_z);
    (body, lying)
}

/// Inserts a bottle with its base centre (or, lying, its middle) over `xy` on the belt.
fn insert_bottle_at(
    world: &mut World,
    bottle: &crate::scenario::BottleSection,
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
            .can_sleep(false)
            .user_data(Tag::Bottle as u128),
    );
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
    for (center_z, half_h, radius, mass_share) in parts {
        let collider = ColliderBuilder::cylinder(half_h as f32, radius as f32)
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

/// Finger pads get the scenario's friction, the rest of the robot a moderate one.
fn set_robot_friction(world: &mut World, arm: &SimArm, pad_friction: f64) {
    let physics = &mut world.physics;
    for (name, body) in arm.link_bodies() {
        let friction = if name.starts_with("finger") {
            pad_friction
        } else {
            0.5
        };
        let Some(rb) = physics.bodies.get(*body) else {
            continue;
        };
        let handles: Vec<ColliderHandle> = rb.colliders().to_vec();
        for handle in handles {
            if let Some(collider) = physics.colliders.get_mut(handle) {
                collider.set_friction(friction as f32);
                if name.starts_with("finger") {
                    // Rubber pads grip with their own coefficient, whatever they touch.
                    collider.set_friction_combine_rule(CoefficientCombineRule::Max);
                    // Contacts of a hooked collider are never recycled: rapier otherwise keeps
                    // a pair's contacts, normal and lever arms frozen in world space while the
                    // pair's relative pose barely changes, which is exactly a held part. As
                    // the arm turned the gripper (up to 11 deg before a refresh) the pads'
                    // squeeze then pushed along stale normals, twisted the part and walked it
                    // out of the jaws. Pad contacts are rebuilt every step instead.
                    collider.set_active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS);
                }
                collider.user_data = Tag::Robot as u128;
            }
        }
    }
}

/// The robot's collision shapes, mounted on DH frames, captured with the arm at `q`.
fn robot_shapes(world: &World, arm: &SimArm, q: &[f64; DOF]) -> Vec<RobotShape> {
    let model = Cell::arm_model();
    let frames = link_frames(&model, q);
    let base_from_world = arm.world_from_base().inverse();
    let mut shapes = Vec::new();
    for (name, body) in arm.link_bodies() {
        let mount = match name.as_str() {
            // The base and shoulder sit on the pedestal by design; they are not checked.
            "shoulder_Link" | "base_link" => continue,
            "upperArm_Link" => LinkMount::Dh(2),
            "foreArm_Link" => LinkMount::Dh(3),
            "wrist1_Link" => LinkMount::Dh(4),
            "wrist2_Link" => LinkMount::Dh(5),
            "wrist3_Link" | "gripper_Link" => LinkMount::Dh(6),
            "finger_left_Link" => LinkMount::Finger { sign: 1.0 },
            "finger_right_Link" => LinkMount::Finger { sign: -1.0 },
            _ => continue,
        };
        let mount_frame = match mount {
            LinkMount::Dh(k) => frames[k],
            LinkMount::Finger { .. } => frames[DOF],
        };
        let Some(rb) = world.physics.bodies.get(*body) else {
            continue;
        };
        for handle in rb.colliders() {
            let Some(collider) = world.physics.colliders.get(*handle) else {
                continue;
            };
            // Colliders' world poses lag their bodies until the next step; compose from the body.
            let body_from_collider = collider
                .position_wrt_parent()
                .map_or_else(Isometry3::identity, pose_from_physics);
            let shape_in_base =
                base_from_world * pose_from_physics(rb.position()) * body_from_collider;
            shapes.push(RobotShape {
                link: name.clone(),
                mount,
                mount_from_shape: mount_frame.inverse() * shape_in_base,
                shape: collider.shared_shape().clone(),
            });
        }
    }
    shapes
}
