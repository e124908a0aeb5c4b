//! The parallel gripper's jaws: two kinematic fingers on a rack, moved by force-limited
//! servos against what their pads pressed in the last step.
//!
//! Each finger rides on the gripper as its prismatic URDF joint puts it, at the jaws' common
//! offset from the centre line (the rack and pinion that makes a parallel gripper's jaws open
//! and close together). Being kinematic, a finger is rigid on the gripper in every direction
//! but its slide, as it was on the arm's multibody: what the pads hold moves with the gripper
//! or slides on the pads by friction, never because a finger gave way sideways.
//!
//! The offset moves once a step. While the jaws open or touch nothing it follows the two
//! fingers' servos (force-based, each [`FINGER_STIFFNESS_N_M`] and [`FINGER_DAMPING_N_S_M`]
//! towards the commanded offset, saturating at the commanded force, integrated by backward
//! Euler), at most at the fingers' joint speed. Closing on something, the squeeze is regulated
//! instead: kinematic pads press a body only through the solver's soft contacts, whose force
//! grows with how deep the pad sits in the body, so each step the jaws go a share of the way
//! that would bring the force the pads' contacts put on the fingers in the last step (the
//! solver's normal impulses over the step) to the limit, in the stiffness those contacts give a
//! body of the touching part's mass (a twentieth: the force answers a step late; a fifth while
//! a fallen limit lets go), and never deeper than a quarter of the held body's half-width. A
//! held part is squeezed with the limit's force, as by a force-limited gripper, and held by the
//! pads' contact and friction.

use rapier3d::prelude::*;

/// Each finger's position servo gain, N/m.
pub const FINGER_STIFFNESS_N_M: f64 = 4_000.0;
/// Each finger's servo damping, N s/m.
pub const FINGER_DAMPING_N_S_M: f64 = 120.0;
/// The share of the way to the force limit the squeeze goes in a step, closing.
const SQUEEZE_GAIN: f64 = 0.05;
/// The share of the way to the force limit the jaws give in a step after the limit has fallen
/// below what the pads press (a weakened grip lets go at once; on an impact the jaws give at
/// the closing share, which keeps the part still in them).
const GIVE_GAIN: f64 = 0.2;
/// How deep a pad may press into what it holds, as a share of the held body's half-width (the
/// pad's offset plus its depth). The solver's soft contacts push a body out of a kinematic pad
/// in proportion to its mass, so on a narrow light tube the limit's force would take the pads
/// through it; its grip needs far less.
const PAD_GIVE_SHARE: f64 = 0.25;
/// A pad's contact point this near (m) touches what it presses; the solver's contacts reach
/// further, predicted.
const TOUCH_M: f64 = 0.0005;
/// The share of the way to the pads' give the squeeze goes in a step.
const DEPTH_GAIN: f64 = 0.25;

/// One finger on its prismatic joint: the link it rides on, its own link and body, and the
/// joint's frames, their x axis its direction of opening.
#[derive(Debug, Clone, Copy)]
pub(super) struct JawFinger {
    /// Index of the gripper's link in the drive's link poses.
    pub(super) parent: usize,
    /// Index of the finger's link in the drive's link poses.
    pub(super) child: usize,
    /// The finger's body.
    pub(super) body: RigidBodyHandle,
    /// The joint's frame on the gripper.
    pub(super) frame1: Pose,
    /// The joint's frame on the finger.
    pub(super) frame2: Pose,
}

/// The force the pads put on the fingers in the last step, along their opening, and how it
/// changes with the jaws' motion.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct PadLoad {
    /// The opening force on both fingers together, N.
    pub(super) force_n: f64,
    /// How much the force falls per metre the jaws open, N/m.
    pub(super) stiffness_n_m: f64,
    /// How deep the deepest pad contact sinks into what it presses, m.
    pub(super) depth_m: f64,
}

/// The jaws: their state, their command and their fingers.
#[derive(Debug, Clone)]
pub(super) struct Jaws {
    fingers: [JawFinger; 2],
    /// The offset's range (the fingers' joint limits), m.
    range_m: [f64; 2],
    /// Both fingers' mass, kg.
    mass_kg: f64,
    /// The fingers' top speed (their joints' velocity limit), m/s.
    speed_m_s: f64,
    /// Each pad's offset from the centre line (m) and its rate (m/s, opening positive).
    offset_m: f64,
    rate_m_s: f64,
    /// The servos' set-point (m) and force limit per finger (N).
    target_m: f64,
    force_n: f64,
    /// Whether the force limit has fallen and the pads still press harder than it.
    relaxing: bool,
}

impl Jaws {
    /// Jaws of `fingers` (left, right), their offsets limited to `range_m` and their speed to
    /// `speed_m_s`, weighing `mass_kg` together, at rest at the lower end of their range.
    pub(super) fn new(
        fingers: [JawFinger; 2],
        range_m: [f64; 2],
        speed_m_s: f64,
        mass_kg: f64,
    ) -> Self {
        Self {
            fingers,
            range_m,
            speed_m_s,
            mass_kg: mass_kg.max(1e-3),
            offset_m: range_m[0],
            rate_m_s: 0.0,
            target_m: range_m[0],
            force_n: 0.0,
            relaxing: false,
        }
    }

    /// Each pad's offset from the centre line, m.
    pub(super) fn offset_m(&self) -> f64 {
        self.offset_m
    }

    /// The lower end of the offset's range: where the pads stop closing on nothing, m.
    pub(super) fn stop_m(&self) -> f64 {
        self.range_m[0]
    }

    /// Drives the pads towards `target_m`, each pushing with at most `force_n`.
    pub(super) fn command(&mut self, target_m: f64, force_n: f64) {
        let force_n = force_n.max(0.0);
        self.relaxing |= force_n < self.force_n;
        self.target_m = target_m;
        self.force_n = force_n;
    }

    /// Puts the pads at rest at `offset_m`, held there with `force_n`.
    pub(super) fn reset(&mut self, offset_m: f64, force_n: f64) {
        self.offset_m = offset_m.clamp(self.range_m[0], self.range_m[1]);
        self.rate_m_s = 0.0;
        self.command(offset_m, force_n);
        self.relaxing = false;
    }

    /// The fingers' bodies and their links' indices in the drive's poses.
    pub(super) fn bodies(&self) -> impl Iterator<Item = (RigidBodyHandle, usize)> + '_ {
        self.fingers.iter().map(|f| (f.body, f.child))
    }

    /// Sets the fingers' poses in `poses` from the gripper's and the offset.
    pub(super) fn place_fingers(&self, poses: &mut [Pose]) {
        let slide = Pose::from_translation(Vector::new(self.offset_m as Real, 0.0, 0.0));
        for finger in &self.fingers {
            poses[finger.child] =
                poses[finger.parent] * finger.frame1 * slide * finger.frame2.inverse();
        }
    }

    /// What the pads pressed in the last step (from `physics`'s contacts; `dt` the step).
    pub(super) fn load(&self, physics: &PhysicsWorld, dt: f64) -> PadLoad {
        let softness = &physics.integration_parameters.contact_softness;
        let omega = f64::from(softness.angular_frequency());
        let mut load = PadLoad::default();
        for finger in &self.fingers {
            let Some(body) = physics.bodies.get(finger.body) else {
                continue;
            };
            let opening = (body.position() * finger.frame2).rotation * Vector::X;
            let mut impulse = Vector::ZERO;
            let mut touching_kg: f64 = 0.0;
            for &collider in body.colliders() {
                for pair in physics.narrow_phase.contact_pairs_with(collider) {
                    let other = if pair.collider1 == collider {
                        pair.collider2
                    } else {
                        pair.collider1
                    };
                    let Some(other_body) = physics
                        .colliders
                        .get(other)
                        .and_then(|c| c.parent())
                        .and_then(|b| physics.bodies.get(b))
                        .filter(|b| b.is_dynamic() && !b.is_sleeping())
                    else {
                        continue;
                    };
                    // The manifold's normal points from collider 1 to collider 2; the impulse
                    // pushes collider 2 along it and collider 1 against it.
                    let sign = if pair.collider1 == collider {
                        -1.0
                    } else {
                        1.0
                    };
                    for manifold in pair.manifolds() {
                        if manifold.data.solver_contacts.is_empty() {
                            continue;
                        }
                        // Only points touching now: a pair the solver left out keeps the
                        // impulses of its last solve while the pads move away from it.
                        let touching = manifold
                            .points
                            .iter()
                            .filter(|p| f64::from(p.dist) <= TOUCH_M);
                        let mut pressed: Real = 0.0;
                        for point in touching {
                            pressed += point.data.impulse;
                            load.depth_m = load.depth_m.max(-f64::from(point.dist));
                        }
                        if pressed > 0.0 {
                            impulse += manifold.data.normal * (sign * pressed);
                            touching_kg = touching_kg.max(f64::from(other_body.mass()));
                        }
                    }
                }
            }
            load.force_n += f64::from(impulse.dot(opening)) / dt;
            load.stiffness_n_m += touching_kg * omega * omega;
        }
        load
    }

    /// One step of `dt` against the pads' load of the last step (see the module's
    /// documentation).
    pub(super) fn advance(&mut self, physics: &PhysicsWorld, dt: f64) {
        let load = self.load(physics, dt);
        self.integrate(&load, dt);
    }

    /// One step of the offset under `load`: the servos' own motion while the jaws open or touch
    /// nothing, the squeeze regulated while they close on something (see the module's
    /// documentation).
    pub(super) fn integrate(&mut self, load: &PadLoad, dt: f64) {
        let (k, c) = (2.0 * FINGER_STIFFNESS_N_M, 2.0 * FINGER_DAMPING_N_S_M);
        let (m, s, u) = (self.mass_kg, self.offset_m, self.rate_m_s);
        // m (u' - u) = dt motor(s + dt u', u'), the motor saturating at both limits' sum.
        let free = (m * u + dt * k * (self.target_m - s)) / (m + dt * dt * k + dt * c);
        let motor = k * (self.target_m - s - dt * free) - c * free;
        let limit = 2.0 * self.force_n;
        let mut rate = if motor.abs() <= limit {
            free
        } else {
            u + dt * limit.copysign(motor) / m
        };
        let closing = self.target_m < s;
        if closing && load.stiffness_n_m > 0.0 {
            // A share of the step that would bring the pads' force to the limit, in the
            // contacts' own stiffness, or their depth to a quarter of the held body's
            // half-width, whichever opens more; never closing faster than the servos would.
            let excess = load.force_n - limit;
            self.relaxing &= excess > 0.0;
            let gain = if self.relaxing {
                GIVE_GAIN
            } else {
                SQUEEZE_GAIN
            };
            let by_force = gain * excess / load.stiffness_n_m;
            let give = PAD_GIVE_SHARE * (s + load.depth_m);
            let by_depth = DEPTH_GAIN * (load.depth_m - give);
            rate = (by_force.max(by_depth) / dt).max(rate.min(0.0));
        }
        rate = rate.clamp(-self.speed_m_s, self.speed_m_s);
        let mut offset = s + dt * rate;
        if offset < self.range_m[0] || offset > self.range_m[1] {
            offset = offset.clamp(self.range_m[0], self.range_m[1]);
            rate = 0.0;
        }
        (self.offset_m, self.rate_m_s) = (offset, rate);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jaws() -> Jaws {
        let finger = JawFinger {
            parent: 0,
            child: 1,
            body: RigidBodyHandle::invalid(),
            frame1: Pose::IDENTITY,
            frame2: Pose::IDENTITY,
        };
        Jaws::new([finger, finger], [0.004, 0.05], 0.15, 0.16)
    }

    #[test]
    fn free_jaws_follow_their_set_point_without_overshoot() {
        let mut j = jaws();
        j.reset(0.045, 40.0);
        let dt = 1.0 / 240.0;
        for step in 1..=240 {
            let target = (0.045 - 0.1 * step as f64 * dt).max(0.02);
            j.command(target, 40.0);
            j.integrate(&PadLoad::default(), dt);
            assert!(j.offset_m() >= 0.02 - 1e-9, "overshoot at step {step}");
        }
        assert!((j.offset_m() - 0.02).abs() < 1e-4, "{}", j.offset_m());
    }

    #[test]
    fn jaws_on_a_stiff_part_settle_at_the_force_limit() {
        // A part 30 mm wide (the pads meet it at 15 mm), pressed as a soft contact of a 2 kg
        // body at 60 Hz; the force the jaws read is a step old, and the contact is `scale`
        // times as stiff as the jaws reckon: they settle at the limit all the same.
        let estimate = 2.0 * 2.0 * (2.0 * std::f64::consts::PI * 60.0f64).powi(2);
        for scale in [0.3, 1.0, 4.0, 10.0] {
            let stiffness = scale * estimate;
            let mut j = jaws();
            j.reset(0.02, 40.0);
            let dt = 1.0 / 240.0;
            let mut read = PadLoad::default();
            for _ in 0..960 {
                j.command(0.0, 40.0);
                j.integrate(&read, dt);
                let depth = (0.015 - j.offset_m()).max(0.0);
                read = PadLoad {
                    force_n: stiffness * depth,
                    stiffness_n_m: if depth > 0.0 { estimate } else { 0.0 },
                    depth_m: depth,
                };
            }
            let force = stiffness * (0.015 - j.offset_m());
            assert!(
                (force - 80.0).abs() < 0.5,
                "x{scale}: squeeze {force} N on both pads"
            );
        }
    }

    #[test]
    fn jaws_on_a_light_part_stop_at_the_pads_give() {
        // A 20 g part 20 mm wide: at the soft contacts' stiffness for its mass the limit's 80 N
        // would take the pads 14 mm into it; they stop at a quarter of its half-width, the
        // force below the limit.
        let kc = 2.0 * 0.02 * (2.0 * std::f64::consts::PI * 60.0f64).powi(2);
        let mut j = jaws();
        j.reset(0.012, 40.0);
        let dt = 1.0 / 240.0;
        for _ in 0..480 {
            j.command(0.0, 40.0);
            let depth = (0.01 - j.offset_m()).max(0.0);
            let load = PadLoad {
                force_n: kc * depth,
                stiffness_n_m: if depth > 0.0 { kc } else { 0.0 },
                depth_m: depth,
            };
            j.integrate(&load, dt);
        }
        // The part's half-width is 10 mm: a quarter of it.
        let depth = 0.01 - j.offset_m();
        assert!((depth - 0.0025).abs() < 1e-5, "the pads {depth} m deep");
    }
}
