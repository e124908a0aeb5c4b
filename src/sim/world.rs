//! The Rapier world with a fixed time step.

use rapier3d::prelude::*;

use super::Tag;
use crate::scenario::PhysicsSection;

/// Solver substeps while no robot collider has a contact (or a predicted one, within 2 cm)
/// with a moving body: the arm moves free or stands still, and the scene's contacts are parts
/// and bottles at rest on the belt or in a bin.
///
/// Each substep recomputes the arm's multibody mass matrix, which callgrind puts at 52 % of
/// a trial's instructions at 8 substeps. With nothing held, the arm's servos track as well at
/// half the substeps; as soon as a finger comes within the prediction distance of a part the
/// scenario's count is back for the whole step. Measured: paper_50 in both perception modes,
/// see docs/speed.md.
const FREE_SOLVER_ITERATIONS: usize = 4;

/// Fixed parameters of a physics world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldParams {
    /// The fixed time step.
    pub dt_s: f64,
    /// Gravity along -z.
    pub gravity_m_s2: f64,
    /// Solver iterations per step.
    pub solver_iterations: usize,
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
        }
    }

    /// The parameters the world was built with.
    pub fn params(&self) -> &WorldParams {
        &self.params
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
    /// solver iterations while the robot touches a moving body, fewer while it touches none
    /// (four; see `FREE_SOLVER_ITERATIONS` in this file for why).
    pub fn step_with_hooks(&mut self, hooks: &dyn PhysicsHooks) {
        let full = self.params.solver_iterations.max(1);
        self.physics.integration_parameters.num_solver_iterations = if self.robot_in_contact() {
            full
        } else {
            full.min(FREE_SOLVER_ITERATIONS)
        };
        self.physics.step_with_events(hooks, &());
        self.steps += 1;
    }

    /// Whether a robot collider has contact points (touching or predicted) with a body that
    /// can move, as of the last step.
    fn robot_in_contact(&self) -> bool {
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
            moving && pair.manifolds().iter().any(|m| !m.points.is_empty())
        })
    }

    /// Advances the world by one fixed step.
    pub fn step(&mut self) {
        self.step_with_hooks(&());
    }
}
