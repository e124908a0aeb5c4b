//! The arm's multibody put to sleep while a step would leave it exactly where it is.
//!
//! Held at a pose with nothing near it, the arm's servos settle into a state that one step maps
//! onto itself, bit for bit: the same joint coordinates and generalized velocities after the
//! step as before it. While the commands stay the same and no moving body comes near, every
//! further step would do the same, so the multibody (its mass matrix is most of a step's cost)
//! is put to sleep instead, and wakes before the first step that could change it.

use rapier3d::prelude::*;

/// Steps in a row the arm's state must come out of the step unchanged, bit for bit, its
/// commands unchanged and no moving body in rapier's contact prediction of it, before its
/// multibody sleeps.
pub const IDLE_STEPS: u32 = 12;

/// Whether the world's multibodies (the arm) sleep while idle, and where that stands.
#[derive(Debug, Clone, Default)]
pub(super) struct IdleArm {
    /// Off: the multibodies are stepped whatever they do.
    enabled: bool,
    /// The motors' commands and the multibodies' state before the last step, as bits.
    last_commands: Vec<u32>,
    last_state: Vec<u32>,
    /// This step's bits, before they are compared.
    scratch: Vec<u32>,
    /// Consecutive steps that left the arm's state as it was.
    still_steps: u32,
    /// Whether the multibodies were put to sleep.
    asleep: bool,
}

impl IdleArm {
    /// Nothing seen yet; `enabled` says whether the multibodies may sleep.
    pub(super) fn new(enabled: bool) -> Self {
        Self {
            enabled,
            ..Self::default()
        }
    }

    /// Allows or stops the sleep; stopping it wakes the multibodies at the next step.
    pub(super) fn set_enabled(&mut self, enabled: bool) {
        self.enabled = enabled;
    }

    /// Before a step: wakes the multibodies when a command changed or a moving body came near;
    /// puts them to sleep after [`IDLE_STEPS`] steps that changed nothing of them. `clear`
    /// says that no robot collider has a contact point with a moving body.
    pub(super) fn update(&mut self, physics: &mut PhysicsWorld, clear: bool) {
        let joints = &physics.multibody_joints;
        motor_commands(joints, &mut self.scratch);
        let held = replace_if_changed(&mut self.last_commands, &self.scratch);
        multibody_state(joints, &mut self.scratch);
        let unchanged = replace_if_changed(&mut self.last_state, &self.scratch);
        if self.asleep {
            if !(held && clear && self.enabled) {
                for body in link_bodies(&physics.multibody_joints) {
                    physics.islands.wake_up(&mut physics.bodies, body, true);
                }
                self.asleep = false;
                self.still_steps = 0;
            }
            return;
        }
        // The last step was taken under these commands (a new one is written just before its
        // step), so an unchanged state means that step mapped the state onto itself.
        self.still_steps = if held && clear && unchanged {
            self.still_steps + 1
        } else {
            0
        };
        if self.enabled && self.still_steps >= IDLE_STEPS {
            for body in link_bodies(&physics.multibody_joints) {
                if let Some(body) = physics.bodies.get_mut(body) {
                    body.sleep();
                }
            }
            self.asleep = true;
        }
    }

    /// Whether the multibodies sleep now.
    pub(super) fn asleep(&self) -> bool {
        self.asleep
    }
}

/// Writes `bits` into `last`; whether they were already there.
fn replace_if_changed(last: &mut Vec<u32>, bits: &[u32]) -> bool {
    let same = last.as_slice() == bits;
    if !same {
        last.clear();
        last.extend_from_slice(bits);
    }
    same
}

/// Every command of every enabled motor of every multibody joint into `bits`, as bits (the
/// motor's impulse left out: that is the solver's).
fn motor_commands(joints: &MultibodyJointSet, bits: &mut Vec<u32>) {
    bits.clear();
    for multibody in joints.multibodies() {
        for link in multibody.links() {
            let data = &link.joint().data;
            let axes = data.motor_axes.bits();
            bits.push(u32::from(axes));
            for (i, motor) in data.motors.iter().enumerate() {
                if axes & (1 << i) != 0 {
                    bits.extend([
                        motor.target_pos.to_bits(),
                        motor.target_vel.to_bits(),
                        motor.stiffness.to_bits(),
                        motor.damping.to_bits(),
                        motor.max_force.to_bits(),
                        u32::from(motor.model == MotorModel::ForceBased),
                    ]);
                }
            }
        }
    }
}

/// The joint coordinates and generalized velocities of every multibody into `bits`, as bits.
fn multibody_state(joints: &MultibodyJointSet, bits: &mut Vec<u32>) {
    bits.clear();
    for multibody in joints.multibodies() {
        for link in multibody.links() {
            bits.extend(link.joint().coords().iter().map(|c| c.to_bits()));
        }
        bits.extend(multibody.generalized_velocity().iter().map(|v| v.to_bits()));
    }
}

/// The bodies of every multibody link.
fn link_bodies(joints: &MultibodyJointSet) -> Vec<RigidBodyHandle> {
    joints
        .multibodies()
        .flat_map(|m| m.links().map(|link| link.rigid_body_handle()))
        .collect()
}
