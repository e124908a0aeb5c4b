//! Building the cell's physics world from a scenario, through `sim`: the scenery, the belt and
//! its photo-eye, the bins, the arm at home, and the trial's part and its bottles.

use nalgebra::{Isometry3, Point3, Vector3};
use rapier3d::prelude::*;

use super::cell_model::CellModel;
use super::placement::{PartSpot, PlacementError, place_bottles};
use crate::math::pose_to_physics;
use crate::rng::SimRng;
use crate::scenario::Scenario;
use crate::sim::{
    BELT_ACCEL_M_S2, BottlePlacement, CellHooks, ConveyorHooks, FINGER_LINKS, ItemSet, PadStiction,
    PartInstance, SimArm, SimError, Tag, World, body_pose, groups, set_body_velocity,
};

/// The pads' offset from the centre line with which the arm stands at home, m: where the
/// planner captures the fingers' shapes.
pub(super) const FINGER_REFERENCE_M: f64 = 0.045;

/// Why a cell could not be built.
#[derive(Debug, thiserror::Error)]
pub enum CellError {
    /// The arm could not be loaded.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The scenario lacks something the cell needs.
    #[error("scenario: {0}")]
    Scenario(String),
    /// The trial's bottles fit nowhere the scenario allows.
    #[error(transparent)]
    Placement(#[from] PlacementError),
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

    /// Whether a body whose axis runs `length_m` along its own z from its origin, at
    /// `world_from_body`, lies in the bin: its lower end inside it (within the walls, below
    /// the rim) and its middle over the floor. Either end may be the lower one: a bottle lying
    /// on others with its base end raised is in the bin as much as one raised at its cap.
    pub fn holds_axis(&self, world_from_body: &Isometry3<f64>, length_m: f64) -> bool {
        let ends = [
            world_from_body * Point3::origin(),
            world_from_body * Point3::new(0.0, 0.0, length_m),
        ];
        let lower = if ends[0].z <= ends[1].z {
            ends[0]
        } else {
            ends[1]
        };
        let middle = world_from_body * Point3::new(0.0, 0.0, length_m / 2.0);
        let over_floor = Vector3::new(middle.x, middle.y, self.floor_center.z);
        self.contains(&lower.coords) && self.contains(&over_floor)
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
    /// The finger pads' stiction (see [`PadStiction`]).
    pub pads: PadStiction,
    /// The photo-eye's sensor collider.
    pub photo_eye: ColliderHandle,
    /// The slow-down zone's sensor collider, just upstream of the photo-eye, when the belt runs
    /// faster than its creep speed (`ConveyorSection::slow_zone_m`).
    pub slow_zone: Option<ColliderHandle>,
    /// Every part and bottle in the world: the trial's first part (index 0) and bottles, then
    /// whatever a stream's feeder adds.
    pub items: ItemSet,
    /// The bins.
    pub bins: Vec<BinBody>,
    /// The fixed boxes an arm could hit (floor, pedestal, belt, rails, bins), world frame.
    pub scenery: Vec<SceneryBox>,
    /// Finger offset at which the arm was put at home, m.
    pub finger_reference_m: f64,
    /// Top of the belt, world z, m.
    pub belt_top_z: f64,
}

/// A fixed box of the cell's scenery that the arm could hit.
#[derive(Debug, Clone)]
pub struct SceneryBox {
    /// Name, for reports (`floor`, `conveyor rail`, `bin reject`, ...).
    pub name: String,
    /// Pose of the box's centre in the world.
    pub world_from_shape: Isometry3<f64>,
    /// The box.
    pub shape: SharedShape,
}

struct Builder<'a> {
    world: &'a mut World,
    scenery: Vec<SceneryBox>,
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
            .user_data(tag.bits());
        let physics = &mut self.world.physics;
        let handle = physics
            .colliders
            .insert_with_parent(collider, body, &mut physics.bodies);
        if obstacle {
            self.scenery.push(SceneryBox {
                name: name.to_string(),
                world_from_shape: pose,
                shape,
            });
        }
        handle
    }

    /// Takes a fixed collider out of the arm's pairs (see [`groups::out_of_reach`]).
    fn out_of_reach(&mut self, collider: ColliderHandle) {
        if let Some(collider) = self.world.physics.colliders.get_mut(collider) {
            collider.set_collision_groups(groups::out_of_reach());
        }
    }
}

impl Cell {
    /// Advances the world one step with the cell's contact hooks (the belt's speed, the pads'
    /// stiction), then brings the pads' anchors up to date.
    pub fn step(&mut self) {
        // The belt's motion reaches the bodies on it through the contact hooks, which rapier
        // does not see: a body at rest on the belt is woken while the belt runs.
        if self.conveyor.speed_m_s() != 0.0 {
            self.world.wake_resting();
        }
        let hooks = CellHooks {
            conveyor: &self.conveyor,
            pads: &self.pads,
        };
        self.world.step_with_hooks(&hooks);
        self.pads.update(&self.world.physics);
    }

    /// Builds the cell for one trial: the scenario's fixed layout plus a part and a bottle drawn
    /// from `rng`, the arm at home.
    pub fn build(model: &CellModel, rng: &mut SimRng) -> Result<Self, CellError> {
        let scenario = model.scenario();
        let (mut world, arm) = model.arm_world()?;
        let base = scenario.robot.base_xyz_m;
        let mut builder = Builder {
            world: &mut world,
            scenery: Vec::new(),
        };
        let floor = builder.fixed_box(
            "floor",
            [0.0, 0.0, -0.05],
            [3.0, 3.0, 0.05],
            Tag::Scenery,
            0.8,
            true,
        );
        let side = scenario.robot.pedestal_side_m / 2.0;
        builder.out_of_reach(floor);
        let pedestal = builder.fixed_box(
            "pedestal",
            [base[0], base[1], base[2] / 2.0],
            [side, side, base[2] / 2.0],
            Tag::Scenery,
            0.8,
            true,
        );
        builder.out_of_reach(pedestal);

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
                .collision_groups(groups::photo_eye())
                .user_data(Tag::PhotoEye.bits()),
            eye_body,
            &mut physics.bodies,
        );
        // The slow-down zone: the belt ahead of the beam, as high as the beam, as long as the
        // drive needs to brake from the belt's speed to its creep speed.
        let zone_m = belt.slow_zone_m(BELT_ACCEL_M_S2);
        let slow_zone = (zone_m > 0.0).then(|| {
            physics.colliders.insert_with_parent(
                ColliderBuilder::cuboid(zone_m as f32 / 2.0, belt.width_m as f32 / 2.0, 0.02)
                    .translation(Vector::new(-(0.002 + zone_m as f32 / 2.0), 0.0, 0.0))
                    .sensor(true)
                    .collision_groups(groups::photo_eye())
                    .user_data(Tag::PhotoEye.bits()),
                eye_body,
                &mut physics.bodies,
            )
        });
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
                let stand = builder.fixed_box(
                    &name,
                    [cx, cy, stand_h / 2.0],
                    [sx / 2.0, sy / 2.0, stand_h / 2.0],
                    Tag::Scenery,
                    0.6,
                    true,
                );
                builder.out_of_reach(stand);
            }
            bins.push(BinBody {
                name: bin.name.clone(),
                floor_center: Vector3::new(cx, cy, floor_z),
                size: bin.size_m,
                wall_height: h,
            });
        }
        let scenery = builder.scenery;

        // The part, upstream of the photo-eye at a random lateral offset.
        let part = PartInstance::draw(model.catalogue(), scenario.parts.max_roundness_mm, rng);
        let lateral = rng.range(
            -scenario.parts.max_lateral_offset_m,
            scenario.parts.max_lateral_offset_m,
        );
        let part_xy = spawn_xy(scenario, lateral);
        let part_radius_m = part.outer_radius_m;
        let mut items = ItemSet::default();
        items.insert_part(&mut world, part, part_xy, belt_top_z);

        if scenario.bottle.enabled {
            let part = PartSpot {
                xy: part_xy,
                radius: part_radius_m,
            };
            for placement in place_bottles(scenario, part, rng)? {
                items.insert_bottle(&mut world, &scenario.bottle, placement, belt_top_z);
            }
        }

        let home = scenario.robot.home_q_rad;
        let finger_reference_m = FINGER_REFERENCE_M;
        arm.reset_to(&mut world, &home, finger_reference_m);
        arm.dress_colliders(&mut world, scenario.gripper.pad_friction);
        let pads = PadStiction::new(
            FINGER_LINKS
                .iter()
                .filter_map(|name| arm.link_body(name))
                .collect(),
            scenario.gripper.pad_preslide_mm / 1000.0,
        );
        Ok(Self {
            world,
            arm,
            conveyor: ConveyorHooks::new(belt_collider),
            pads,
            photo_eye,
            slow_zone,
            items,
            bins,
            scenery,
            finger_reference_m,
            belt_top_z,
        })
    }

    /// Pose of a body in the world.
    pub fn body_pose(&self, body: RigidBodyHandle) -> Option<Isometry3<f64>> {
        body_pose(&self.world, body)
    }

    /// Puts a newly drawn part on the belt at the spawn point (a stream's feeder); returns its
    /// index among the parts.
    pub fn spawn_part(&mut self, model: &CellModel, rng: &mut SimRng) -> usize {
        let scenario = model.scenario();
        let part = PartInstance::draw(model.catalogue(), scenario.parts.max_roundness_mm, rng);
        let lateral = rng.range(
            -scenario.parts.max_lateral_offset_m,
            scenario.parts.max_lateral_offset_m,
        );
        let xy = spawn_xy(scenario, lateral);
        let index = self
            .items
            .insert_part(&mut self.world, part, xy, self.belt_top_z);
        self.hand_over(self.items.parts()[index].body);
        index
    }

    /// Starts a fed item at the belt's speed, as a feeder running with the belt hands it over.
    fn hand_over(&mut self, body: RigidBodyHandle) {
        let belt_m_s = f64::from(self.conveyor.speed_m_s());
        set_body_velocity(&mut self.world, body, &Vector3::new(belt_m_s, 0.0, 0.0));
    }

    /// Puts a bottle on the belt at the spawn point (a stream's feeder); returns its index among
    /// the bottles.
    pub fn spawn_bottle(&mut self, scenario: &Scenario, rng: &mut SimRng) -> usize {
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
        let placement = BottlePlacement {
            xy: spawn_xy(scenario, lateral),
            lying,
            yaw_rad: yaw,
        };
        let index = self
            .items
            .insert_bottle(&mut self.world, bottle, placement, self.belt_top_z);
        self.hand_over(self.items.bottles()[index].body);
        index
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

    /// Whether anything is in the slow-down zone ahead of the photo-eye (never, without one).
    pub fn slow_zone_occupied(&self) -> bool {
        self.slow_zone.is_some_and(|zone| {
            self.world
                .physics
                .narrow_phase
                .intersection_pairs_with(zone)
                .any(|(_, _, intersecting)| intersecting)
        })
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

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    use super::BinBody;
    use crate::rng::SimRng;

    /// A body of `length` lying at `yaw` with its middle at `(x, y)`, tilted by `pitch` (its
    /// origin end raised for a positive pitch), and the same body turned end for end.
    fn lying_both_ways(
        x: f64,
        y: f64,
        z: f64,
        yaw: f64,
        pitch: f64,
        length: f64,
    ) -> [Isometry3<f64>; 2] {
        let along = |flip: bool| {
            let (yaw, pitch) = if flip {
                (yaw + std::f64::consts::PI, -pitch)
            } else {
                (yaw, pitch)
            };
            let axis = Vector3::new(
                yaw.cos() * pitch.cos(),
                yaw.sin() * pitch.cos(),
                -pitch.sin(),
            );
            let rotation = UnitQuaternion::rotation_between(&Vector3::z(), &axis)
                .unwrap_or_else(UnitQuaternion::identity);
            let origin = Vector3::new(x, y, z) - axis * (length / 2.0);
            Isometry3::from_parts(Translation3::from(origin), rotation)
        };
        [along(false), along(true)]
    }

    #[test]
    fn a_body_lying_in_a_bin_is_in_it_whichever_end_is_raised() {
        let mut rng = SimRng::new(2602);
        for _ in 0..400 {
            let bin = BinBody {
                name: "waste".into(),
                floor_center: Vector3::new(rng.range(-0.6, 0.6), rng.range(-0.6, 0.6), 0.5),
                size: [rng.range(0.25, 0.5), rng.range(0.25, 0.5)],
                wall_height: rng.range(0.06, 0.2),
            };
            let length = rng.range(0.1, 0.22);
            let c = bin.floor_center;
            let yaw = rng.range(-3.2, 3.2);
            // Lying on what the bin already holds, its lower end 30 mm over the floor, the other
            // up to 43 degrees higher, the middle over the floor's inner part.
            let pitch = rng.range(0.0, 0.75);
            let (hx, hy) = (bin.size[0] / 2.0, bin.size[1] / 2.0);
            let reach = (length / 2.0) * pitch.cos();
            let (x, y) = (
                c.x + rng.range(-1.0, 1.0) * (hx - reach).max(0.0) * 0.9,
                c.y + rng.range(-1.0, 1.0) * (hy - reach).max(0.0) * 0.9,
            );
            let z = c.z + 0.03 + (length / 2.0) * pitch.sin();
            let [a, b] = lying_both_ways(x, y, z, yaw, pitch, length);
            // Either way round, it is in the bin.
            assert!(bin.holds_axis(&a, length), "{bin:?} {a:?}");
            assert!(
                bin.holds_axis(&b, length),
                "turned end for end: {bin:?} {b:?}"
            );
            // Standing on its floor, or upside down.
            let standing = Isometry3::translation(x, y, c.z);
            assert!(bin.holds_axis(&standing, length));
            let upside_down = Isometry3::from_parts(
                Translation3::new(x, y, c.z + length),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
            );
            assert!(bin.holds_axis(&upside_down, length));
            // Beside the bin on the table, over its rim, or with its middle outside the walls.
            let beside = Isometry3::translation(c.x + hx + 0.05, y, c.z);
            assert!(!bin.holds_axis(&beside, length));
            let above = Isometry3::translation(x, y, c.z + bin.wall_height + 0.02);
            assert!(!bin.holds_axis(&above, length));
            let [hanging, _] = lying_both_ways(c.x + hx + 0.01, y, c.z + 0.03, 0.0, 0.0, length);
            assert!(!bin.holds_axis(&hanging, length));
        }
    }
}
