//! The Rapier world with a fixed time step.

use rapier3d::prelude::*;

use super::Tag;
use super::servo::ServoDrive;
use crate::scenario::PhysicsSection;

/// Solver substeps while no robot collider is within [`CONTACT_MARGIN_M`] of a moving body: the
/// arm moves free or stands still, and the scene's contacts are parts and bottles at rest on
/// the belt or in a bin, or riding it.
///
/// Parts and bottles resting on the belt or in a bin need no more than one; the arm's servos
/// (1000 rad/s, critically damped, integrated implicitly per substep: `sim::servo`; measured
/// when rapier's multibody integrated the same law) need two once it moves at
/// its published limits: with one, a joint ending an acceleration ramp overshot its velocity
/// limit by up to 20 % (measured joint speed over 50 trials of paper_50 in camera mode, seeds
/// 731 and 1-5), with two by up to 2 % at 0.92 of the limits and not at all at 0.9 (the
/// scenario default). As soon as a finger comes within the margin of a part, the scenario's
/// count is back for the whole step.
/// Measured: docs/speed.md.
pub const FREE_SOLVER_ITERATIONS: usize = 2;

/// How near (m) a robot collider's nearest contact point with a moving body must be for the
/// step to get the scenario's solver substeps. Rapier predicts contacts 2 cm out; counting
/// those kept the full count through the whole descent, where the open jaws pass a part at the
/// gripper's open clearance (12 mm by default). The contacts read are a step old, and 1 cm is
/// what a finger covers in two steps at 1.2 m/s: up to that speed no finger reaches a part
/// before the full count is on.
pub const CONTACT_MARGIN_M: f64 = 0.01;

/// Fixed parameters of a physics world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldParams {
    /// The fixed time step.
    pub dt_s: f64,
    /// Gravity along -z.
    pub gravity_m_s2: f64,
    /// Solver iterations per step.
    pub solver_iterations: usize,
    /// Solver substeps while no robot collider is near a moving body (see
    /// [`FREE_SOLVER_ITERATIONS`]); at most `solver_iterations`.
    pub free_solver_iterations: usize,
    /// Distance within which a robot collider's contact with a moving body brings back the
    /// full `solver_iterations`, m (see [`CONTACT_MARGIN_M`]).
    pub contact_margin_m: f64,
    /// Natural frequency of contact constraints, Hz.
    pub contact_frequency_hz: f64,
    /// Damping ratio of contact constraints.
    pub contact_damping_ratio: f64,
}

impl WorldParams {
    /// The world a scenario's `[physics]` section asks for, under standard gravity.
    pub fn from_section(physics: &PhysicsSection) -> Self {
        Self {
            dt_s: physics.dt_s,
            gravity_m_s2: 9.81,
            solver_iterations: physics.solver_iterations,
            free_solver_iterations: FREE_SOLVER_ITERATIONS,
            contact_margin_m: CONTACT_MARGIN_M,
            contact_frequency_hz: physics.contact_frequency_hz,
            contact_damping_ratio: physics.contact_damping_ratio,
        }
    }
}

impl Default for WorldParams {
    fn default() -> Self {
        Self::from_section(&PhysicsSection::default())
    }
}

/// The simulated world: Rapier's sets and pipelines, z up, stepped at a fixed rate.
pub struct World {
    /// Rapier's bundle of sets and pipelines.
    pub physics: PhysicsWorld,
    params: WorldParams,
    steps: u64,
    /// The arm's joints and jaws, integrated by their servo laws, placing the arm's links.
    pub(super) drive: Option<ServoDrive>,
}

impl World {
    /// An empty world.
    pub fn new(params: WorldParams) -> Self {
        let mut physics = PhysicsWorld::new();
        physics.gravity = Vector::new(0.0, 0.0, -(params.gravity_m_s2 as f32));
        physics.integration_parameters.dt = params.dt_s as f32;
        physics.integration_parameters.num_solver_iterations = params.solver_iterations.max(1);
        // One Coulomb cone per contact point: the simplified per-manifold model let a part
        // held by 40 N per finger creep down the pads under its own weight.
        physics.integration_parameters.friction_model = FrictionModel::Coulomb;
        // Friction in both passes of every substep. By default rapier leaves it out of the
        // biased (penetration-correcting) pass, after which positions are integrated: a part
        // squeezed between two pads then slid a little in every substep, unopposed by
        // friction, and crept up to 25 mm out of the jaws over a carry (median 12 mm). With
        // friction in that pass too the median drift is 0.9 mm (250 trials, five seeds).
        physics.integration_parameters.friction_in_bias_pass = true;
        // No contact is recycled. By default rapier keeps a pair's contact points, normal and
        // lever arms frozen while the pair's relative pose moves less than 5 cm, and tracks its
        // separation along the frozen normal by the frozen points' motion. Between a moving
        // body and another that is near it, that pushes without touching: the gripper housing,
        // descending past a standing bottle 18 mm from it, knocked it over; a part falling into
        // the collector past its wall was thrown 0.3 m back out; a held part turned in the jaws
        // along the pads' stale normals. Every contact is rebuilt every step (about +3 %
        // instructions on a trial).
        physics.integration_parameters.contact_recycling = false;
        // Contacts between moving bodies: rapier's default (30 Hz, damping ratio 10) lets a
        // jaw pressing a part with 60 N sink through it. At 60 Hz and damping ratio 2 a firm
        // grasp settles 1-2 mm into the part, about what rubber pads give; softer ones (30 Hz)
        // let parts fall. Contacts with fixed bodies keep rapier's default (60 Hz, damping
        // ratio 10), which lets a tall part stand still on the belt.
        physics.integration_parameters.contact_softness = SpringCoefficients::new(
            params.contact_frequency_hz as f32,
            params.contact_damping_ratio as f32,
        );
        Self {
            physics,
            params,
            steps: 0,
            drive: None,
        }
    }

    /// The parameters the world was built with.
    pub fn params(&self) -> &WorldParams {
        &self.params
    }

    /// Sets the solver substeps of later steps: `full` while a robot collider is within
    /// `contact_margin_m` of a moving body, `free` (at most `full`) otherwise. The task may
    /// call this per phase (for example, the scenario's count from the grasp to the release
    /// whatever the contacts say); the cell's defaults come from the scenario and
    /// [`FREE_SOLVER_ITERATIONS`] / [`CONTACT_MARGIN_M`].
    pub fn set_solver_schedule(&mut self, full: usize, free: usize, contact_margin_m: f64) {
        self.params.solver_iterations = full.max(1);
        self.params.free_solver_iterations = free.clamp(1, full.max(1));
        self.params.contact_margin_m = contact_margin_m;
    }

    /// The solver substeps the next step gets (see [`World::set_solver_schedule`]).
    pub fn next_solver_iterations(&self) -> usize {
        let full = self.params.solver_iterations.max(1);
        if self.robot_near_moving_body() {
            full
        } else {
            full.min(self.params.free_solver_iterations.max(1))
        }
    }

    /// Simulated time since creation.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.params.dt_s
    }

    /// Steps taken so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Advances the world by one fixed step with the given contact hooks: with the scenario's
    /// solver substeps while a robot collider is near a moving body, fewer while none is (see
    /// [`FREE_SOLVER_ITERATIONS`] for why).
    ///
    /// The arm's joints and jaws are advanced first, over the same substeps, and its links
    /// handed where the step ends (`sim::servo`, `sim::jaws`).
    pub fn step_with_hooks(&mut self, hooks: &dyn PhysicsHooks) {
        let substeps = self.next_solver_iterations();
        if let Some(drive) = self.drive.as_mut() {
            drive.advance(&self.physics, self.params.dt_s, substeps);
            drive.place(&mut self.physics, false);
        }
        self.physics.integration_parameters.num_solver_iterations = substeps;
        self.physics.step_with_events(hooks, &());
        self.steps += 1;
    }

    /// Whether a robot collider has a contact point with a body that can move, touching or
    /// predicted within `contact_margin_m`, as of the last step.
    fn robot_near_moving_body(&self) -> bool {
        let margin = self.params.contact_margin_m as f32;
        let physics = &self.physics;
        let robot = Tag::Robot.bits();
        physics.narrow_phase.contact_pairs().any(|pair| {
            let (Some(c1), Some(c2)) = (
                physics.colliders.get(pair.collider1),
                physics.colliders.get(pair.collider2),
            ) else {
                return false;
            };
            let other = match (c1.user_data == robot, c2.user_data == robot) {
                (true, false) => c2,
                (false, true) => c1,
                _ => return false,
            };
            let moving = other
                .parent()
                .and_then(|body| physics.bodies.get(body))
                .is_some_and(|body| !body.is_fixed());
            moving
                && pair
                    .manifolds()
                    .iter()
                    .any(|m| m.points.iter().any(|p| p.dist < margin))
        })
    }

    /// Wakes every body at rest (asleep, in rapier's terms), as a push rapier cannot see would.
    pub fn wake_resting(&mut self) {
        let physics = &mut self.physics;
        let resting = physics.bodies.iter().filter(|(_, b)| b.is_sleeping());
        let resting: Vec<RigidBodyHandle> = resting.map(|(handle, _)| handle).collect();
        for handle in resting {
            physics.wake_up(handle, true);
        }
    }

    /// Advances the world by one fixed step.
    pub fn step(&mut self) {
        self.step_with_hooks(&());
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Point3};
    use rapier3d::prelude::*;

    use super::*;
    use crate::math::vector_to_physics;
    use crate::sim::{FINGER_LINKS, SimArm};

    /// A weightless world with the arm at rest and a ball `gap_m` beyond the left finger's tip,
    /// after one step (which finds the contacts the next step reads).
    fn ball_beyond_finger(gap_m: f64, fixed: bool) -> World {
        let params = WorldParams {
            gravity_m_s2: 0.0,
            ..WorldParams::default()
        };
        let mut world = World::new(params);
        let arm = match SimArm::load_builtin(&mut world, Isometry3::translation(0.0, 0.0, 0.6)) {
            Ok(arm) => arm,
            Err(e) => panic!("{e}"),
        };
        arm.reset_to(&mut world, &[0.3, 0.2, 1.4, 0.0, 1.5, 0.0], 0.03);
        arm.dress_colliders(&mut world, 1.0);
        let Some(finger) = arm.link_body(FINGER_LINKS[0]) else {
            panic!("no left finger")
        };
        let Some(finger_pose) = world.physics.bodies.get(finger).map(|b| *b.position()) else {
            panic!("no finger body")
        };
        // The pad is a 12 x 30 x 90 mm box centred 95 mm out along the finger's z: its tip is
        // at 140 mm. The ball (radius 5 mm) sits on that axis, `gap_m` past the tip.
        let radius = 0.005;
        let local = Point3::new(0.006, 0.0, 0.14 + gap_m + radius);
        let centre = crate::math::pose_from_physics(&finger_pose) * local;
        let builder = if fixed {
            RigidBodyBuilder::fixed()
        } else {
            RigidBodyBuilder::dynamic()
        };
        let physics = &mut world.physics;
        let ball = physics
            .bodies
            .insert(builder.translation(vector_to_physics(&centre.coords)));
        physics.colliders.insert_with_parent(
            ColliderBuilder::ball(radius as f32),
            ball,
            &mut physics.bodies,
        );
        world.step();
        world
    }

    /// The scenarios' default home pose.
    fn home_q() -> [f64; 6] {
        crate::scenario::RobotSection::default().home_q_rad
    }

    /// The arm at home under gravity with its jaws open as the cell puts them, held.
    fn held_arm() -> (World, SimArm) {
        let mut world = World::new(WorldParams::default());
        let arm = match SimArm::load_builtin(&mut world, Isometry3::translation(0.0, 0.0, 0.6)) {
            Ok(arm) => arm,
            Err(e) => panic!("{e}"),
        };
        arm.reset_to(&mut world, &home_q(), 0.045);
        arm.dress_colliders(&mut world, 1.0);
        (world, arm)
    }

    #[test]
    fn the_links_follow_the_joints_and_the_jaws_their_command() {
        let (mut world, arm) = held_arm();
        let start = home_q();
        let kinematics = arm.kinematics().model.clone();
        let sign = |i: usize| if i.is_multiple_of(2) { 1.0 } else { -1.0 };
        // Each joint along a smooth 0.2 rad move over a second, then held; the jaws close to
        // 20 mm.
        for step in 0..360 {
            let t = ((step + 1) as f64 * world.params().dt_s).min(1.0);
            let s = 0.5 - 0.5 * (std::f64::consts::PI * t).cos();
            let ds = 0.5 * std::f64::consts::PI * (std::f64::consts::PI * t).sin();
            let q: [f64; 6] = std::array::from_fn(|i| start[i] + 0.2 * sign(i) * s);
            let qd: [f64; 6] = std::array::from_fn(|i| 0.2 * sign(i) * ds);
            arm.command(&mut world, &q, &qd);
            arm.command_gripper(&mut world, 0.02, 40.0);
            world.step();
            let measured = arm.joint_positions(&world);
            for i in 0..6 {
                assert!((measured[i] - q[i]).abs() < 2e-3, "step {step} joint {i}");
            }
            // The flange body is where forward kinematics puts it for the measured joints.
            let flange = crate::kinematics::flange_pose(&kinematics, &measured);
            let expected = Isometry3::translation(0.0, 0.0, 0.6) * flange;
            let body = arm.flange_in_world(&world);
            let error = (body.translation.vector - expected.translation.vector).norm();
            assert!(error < 1e-4, "step {step}: flange {error} m off");
        }
        let measured = arm.joint_positions(&world);
        for i in 0..6 {
            let end = start[i] + 0.2 * sign(i);
            assert!((measured[i] - end).abs() < 1e-6, "joint {i} settled off");
        }
        for pad in arm.finger_positions_m(&world) {
            assert!((pad - 0.02).abs() < 5e-4, "a pad at {pad} m");
        }
    }

    #[test]
    fn a_joint_commanded_past_its_limit_stops_at_it() {
        let (mut world, arm) = held_arm();
        let mut q = home_q();
        let upper = 3.04;
        q[5] = upper + 0.3;
        for _ in 0..480 {
            arm.command(&mut world, &q, &[0.0; 6]);
            world.step();
            assert!(arm.joint_positions(&world)[5] <= upper + 1e-5);
        }
        let wrist = arm.joint_positions(&world)[5];
        assert!(
            (wrist - upper).abs() < 1e-5,
            "the wrist ended at {wrist} rad"
        );
    }

    #[test]
    fn the_full_count_comes_back_within_the_margin_of_a_moving_body_only() {
        let full = WorldParams::default().solver_iterations;
        assert!(full > FREE_SOLVER_ITERATIONS);
        // Far away, and inside rapier's 2 cm prediction but outside the 1 cm margin: free.
        for gap in [0.10, 0.015] {
            let world = ball_beyond_finger(gap, false);
            assert_eq!(
                world.next_solver_iterations(),
                FREE_SOLVER_ITERATIONS,
                "{gap} m"
            );
        }
        // Within the margin of a body that can move: the full count.
        for gap in [0.006, 0.002, 0.0] {
            let world = ball_beyond_finger(gap, false);
            assert_eq!(world.next_solver_iterations(), full, "{gap} m");
        }
        // A fixed body within the margin does not count.
        assert_eq!(
            ball_beyond_finger(0.002, true).next_solver_iterations(),
            FREE_SOLVER_ITERATIONS
        );
        // The schedule can be set: the previous one counted every predicted contact.
        let mut world = ball_beyond_finger(0.015, false);
        world.set_solver_schedule(full, 4, f64::INFINITY);
        assert_eq!(world.next_solver_iterations(), full);
        world.set_solver_schedule(full, 4, 0.01);
        assert_eq!(world.next_solver_iterations(), 4);
    }
}
