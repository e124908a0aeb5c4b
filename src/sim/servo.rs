//! The arm's joints driven along their servos' response instead of simulated as a multibody.
//!
//! The arm's servos are acceleration-based joint motors, stiffness 1e6 1/s^2 and damping 2e3
//! 1/s (natural frequency 1000 rad/s, critically damped): per unit inertia, so whatever the
//! links weigh and whatever the gripper carries, each joint follows its command by the same
//! implicit spring-damper law. Rapier solved that law inside the arm's multibody once per
//! substep, with the multibody's mass matrix, its LU factors and its forward kinematics
//! recomputed each time: most of a trial's instructions (docs/speed.md).
//!
//! Here each joint's coordinate and velocity are integrated by that same law, substep by
//! substep (see [`ServoJoint::substep`]), and the links are kinematic bodies placed by forward
//! kinematics through the URDF's joint frames at the end of the step: rapier moves them there
//! over the step at constant velocity and lets them push what they touch. A joint moves as an
//! ideal servo would: no gravity sag, no coupling through the links' inertia, no torque limit
//! (the arm's loads are far below its efforts; docs/physics.md). The fingers ride on the
//! gripper the same way, each at the jaws' offset (`sim::jaws`).

use rapier3d::prelude::*;

use super::jaws::Jaws;

/// One servo-driven revolute joint: the link it moves, on the link it hangs from.
#[derive(Debug, Clone)]
pub(super) struct ServoJoint {
    /// Index of the parent link in the drive's link poses.
    parent: usize,
    /// Index of the moved link in the drive's link poses.
    child: usize,
    /// The moved link's body.
    body: RigidBodyHandle,
    /// The joint's frame on the parent link, its x axis the rotation axis.
    frame1: Pose,
    /// The inverse of the joint's frame on the moved link.
    frame2_inv: Pose,
    /// Position limits, rad.
    min: f64,
    max: f64,
    /// Coordinate (rad) and velocity (rad/s).
    q: f64,
    v: f64,
    /// Commanded position and feed-forward velocity.
    target_q: f64,
    target_v: f64,
    /// Servo stiffness (1/s^2) and damping (1/s).
    stiffness: f64,
    damping: f64,
}

impl ServoJoint {
    /// A joint at rest at 0, commanded to stay there, with no gains until commanded.
    pub(super) fn new(
        (parent, child): (usize, usize),
        body: RigidBodyHandle,
        joint: &GenericJoint,
    ) -> Self {
        let limits = joint.limits(JointAxis::AngX).map(|l| [l.min, l.max]);
        let [min, max] = limits.unwrap_or([-Real::MAX, Real::MAX]);
        Self {
            parent,
            child,
            body,
            frame1: joint.local_frame1,
            frame2_inv: joint.local_frame2.inverse(),
            min: f64::from(min),
            max: f64::from(max),
            q: 0.0,
            v: 0.0,
            target_q: 0.0,
            target_v: 0.0,
            stiffness: 0.0,
            damping: 0.0,
        }
    }

    /// One substep of `h` seconds of the servo law rapier's acceleration-based motor applies
    /// (`MotorModel::AccelerationBased` and `unit_joint_motor_constraint`): with
    /// `erp = k / (h k + c)` and `cfm = 1 / (h^2 k + h c)`, the velocity the constraint leaves,
    /// solved alone, is `v' = (cfm v + vt - erp (q - qt)) / (1 + cfm)`, the target velocity
    /// `vt` first clamped to what reaches a limit within the substep; then `q' = q + h v'`.
    /// A joint that would pass a limit stops there.
    fn substep(&mut self, h: f64) {
        let (k, c) = (self.stiffness, self.damping);
        let denominator = h * h * k + h * c;
        if denominator <= 0.0 {
            // No servo: the joint keeps its speed (nothing else acts on an ideal joint).
            self.q += h * self.v;
        } else {
            let erp = k / (h * k + c);
            let cfm = 1.0 / denominator;
            let vt = self
                .target_v
                .clamp((self.min - self.q) / h, (self.max - self.q) / h);
            self.v = (cfm * self.v + vt - erp * (self.q - self.target_q)) / (1.0 + cfm);
            self.q += h * self.v;
        }
        if self.q < self.min || self.q > self.max {
            self.q = self.q.clamp(self.min, self.max);
            self.v = 0.0;
        }
    }
}

/// The arm's joints, their states and commands, the jaws, and the poses of the links they
/// move.
#[derive(Debug, Clone)]
pub(super) struct ServoDrive {
    /// The joints, each after the joint that moves its parent.
    joints: Vec<ServoJoint>,
    /// The link poses, by the drive's link index; the roots' never change.
    poses: Vec<Pose>,
    /// The gripper's jaws.
    pub(super) jaws: Jaws,
}

impl ServoDrive {
    /// A drive for `joints` and `jaws` over links whose poses are `poses` now (the roots' stay
    /// there). The joints are put in an order where each comes after the one moving its parent.
    pub(super) fn new(mut joints: Vec<ServoJoint>, jaws: Jaws, poses: Vec<Pose>) -> Self {
        let mut ordered: Vec<ServoJoint> = Vec::with_capacity(joints.len());
        while !joints.is_empty() {
            let ready = joints
                .iter()
                .position(|j| !joints.iter().any(|other| other.child == j.parent));
            // A cycle cannot come out of a URDF tree; take the rest as they are.
            let index = ready.unwrap_or(0);
            ordered.push(joints.remove(index));
        }
        Self {
            joints: ordered,
            poses,
            jaws,
        }
    }

    /// The joint that moves the link `child`.
    fn joint_mut(&mut self, child: usize) -> Option<&mut ServoJoint> {
        self.joints.iter_mut().find(|j| j.child == child)
    }

    /// Coordinate and velocity of the joint moving link `child`.
    pub(super) fn state(&self, child: usize) -> Option<(f64, f64)> {
        self.joints
            .iter()
            .find(|j| j.child == child)
            .map(|j| (j.q, j.v))
    }

    /// Commands the joint moving link `child` to `q` at feed-forward velocity `qd` with the
    /// servo gains `stiffness` and `damping`.
    pub(super) fn command(&mut self, child: usize, q: f64, qd: f64, gains: (f64, f64)) {
        if let Some(joint) = self.joint_mut(child) {
            joint.target_q = q;
            joint.target_v = qd;
            (joint.stiffness, joint.damping) = gains;
        }
    }

    /// Sets the joint moving link `child` at rest at `q`, held there.
    pub(super) fn reset(&mut self, child: usize, q: f64) {
        if let Some(joint) = self.joint_mut(child) {
            joint.q = q;
            joint.v = 0.0;
            joint.target_q = q;
            joint.target_v = 0.0;
        }
    }

    /// Integrates every joint over a step of `dt` seconds in `substeps` substeps, as rapier's
    /// solver would have, and the jaws over the step against what their pads pressed in the
    /// last one (read from `physics`), and works out the links' poses at the step's end.
    pub(super) fn advance(&mut self, physics: &PhysicsWorld, dt: f64, substeps: usize) {
        let h = dt / substeps.max(1) as f64;
        for joint in &mut self.joints {
            for _ in 0..substeps.max(1) {
                joint.substep(h);
            }
        }
        self.jaws.advance(physics, dt);
        self.forward_kinematics();
    }

    /// The links' poses from the joints' coordinates and the jaws' offset.
    pub(super) fn forward_kinematics(&mut self) {
        for joint in &self.joints {
            let rotation = Rotation::from_rotation_x(joint.q as Real);
            let pose = self.poses[joint.parent]
                * joint.frame1
                * Pose::from_rotation(rotation)
                * joint.frame2_inv;
            self.poses[joint.child] = pose;
        }
        self.jaws.place_fingers(&mut self.poses);
    }

    /// Hands the moved links' poses to their kinematic bodies as where the step ends (rapier
    /// moves them there over the step); `now` also puts them there at once (a reset).
    pub(super) fn place(&self, physics: &mut PhysicsWorld, now: bool) {
        let bodies = &mut physics.bodies;
        let moved = self
            .joints
            .iter()
            .map(|j| (j.body, j.child))
            .chain(self.jaws.bodies());
        for (handle, link) in moved {
            let Some(body) = bodies.get_mut(handle) else {
                continue;
            };
            let pose = self.poses[link];
            if now {
                body.set_position(pose, true);
            }
            body.set_next_kinematic_position(pose);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn joint(min: f64, max: f64) -> ServoJoint {
        ServoJoint {
            parent: 0,
            child: 1,
            body: RigidBodyHandle::invalid(),
            frame1: Pose::IDENTITY,
            frame2_inv: Pose::IDENTITY,
            min,
            max,
            q: 0.0,
            v: 0.0,
            target_q: 0.0,
            target_v: 0.0,
            stiffness: 1.0e6,
            damping: 2.0e3,
        }
    }

    #[test]
    fn a_step_command_settles_like_a_critically_damped_servo() {
        // A 10 mrad step: the continuous critically damped response at 1000 rad/s is
        // 1 - (1 + w t) e^(-w t); the implicit law is its backward-Euler-like discretisation,
        // close to it at 4 substeps of a 240 Hz step and never overshooting.
        let mut j = joint(-3.0, 3.0);
        j.target_q = 0.01;
        let h = 1.0 / 240.0 / 4.0;
        let mut worst: f64 = 0.0;
        for n in 1..=400 {
            j.substep(h);
            let t = n as f64 * h;
            let ideal = 0.01 * (1.0 - (1.0 + 1000.0 * t) * (-1000.0 * t).exp());
            worst = worst.max((j.q - ideal).abs());
            assert!(j.q <= 0.01 + 1e-12, "overshoot {} at substep {n}", j.q);
        }
        assert!((j.q - 0.01).abs() < 1e-9, "settled at {}", j.q);
        assert!(
            worst < 0.004,
            "largest departure from the continuous law {worst}"
        );
    }

    #[test]
    fn a_ramp_is_tracked_and_a_limit_stops_the_joint() {
        // Commanded along q = 2 t with its feed-forward velocity, sampled per 240 Hz step.
        let mut j = joint(-1.0, 0.5);
        let dt = 1.0 / 240.0;
        let mut last = 0.0;
        for step in 1..=48 {
            j.target_q = 2.0 * step as f64 * dt;
            j.target_v = 2.0;
            for _ in 0..2 {
                j.substep(dt / 2.0);
            }
            // Started from rest, it catches up within a few steps, then moves step to step at
            // the ramp's speed, a steady few milliradians off the step's end point (the target
            // is held through the step's substeps).
            let error = (j.q - j.target_q).abs();
            assert!(error < 1.5e-2, "step {step}: {error}");
            let speed = (j.q - last) / dt;
            last = j.q;
            if step > 12 {
                assert!((speed - 2.0).abs() < 0.02, "step {step}: {speed} rad/s");
            }
        }
        // On to 0.3 rad past the upper limit: it stops at the limit, at rest.
        for _ in 0..240 {
            j.target_q = 0.8;
            j.target_v = 0.0;
            j.substep(dt / 2.0);
            assert!(j.q <= 0.5);
        }
        assert_eq!((j.q, j.v), (0.5, 0.0));
    }
}
