//! One trial's running state and the systems it steps in order each tick: the belt and gripper
//! drives, the feeder, the physics step, the observer, and the monitors (time-out, blow-up,
//! robot-bottle contact).

use std::time::Instant;

use nalgebra::Isometry3;
use rapier3d::prelude::*;

use super::fault_handling::FaultLog;
use super::feeder::Feeder;
use super::observer::{CellView, ObserverSlot, TrialObserver};
use super::phase::PhaseDeadline;
use crate::cell::{Cell, CellModel};
use crate::control::{
    BeltDrive, FaultPlan, GripperDrive, HoldMonitor, TrajectoryFollower, TrajectoryStop,
};
use crate::kinematics::{ArmModel, JointVector};
use crate::outcome::{
    Failure, FailureReason, Misidentification, MotionRecord, Phase, TrialTiming, fail,
};
use crate::planning::{JointTrajectory, PickPlanner, capture_robot_shapes, scenery_obstacles};
use crate::rng::SimRng;
use crate::scenario::{BinId, Catalogue, Scenario};
use crate::sim::Tag;
use crate::station::CameraPerception;

/// A robot collider this close to a bottle counts as touching it, m.
const TOUCH_DISTANCE_M: f64 = 0.0005;

/// A trial in progress: the cell, the drives, the monitors, and where the task has got to.
pub(crate) struct Trial<'a> {
    pub(crate) scenario: &'a Scenario,
    /// The scenario's part types and bins by id.
    pub(crate) catalogue: &'a Catalogue,
    /// The camera pipeline; `None` reads the truth from the world (the oracle).
    pub(crate) camera: Option<&'a CameraPerception>,
    /// The trial's seed, and the camera shots taken so far (each draws its own realism).
    pub(crate) seed: u64,
    pub(crate) shots: u64,
    pub(crate) cell: Cell,
    pub(crate) planner: PickPlanner,
    pub(crate) timing: TrialTiming,
    pub(crate) belt: BeltDrive,
    pub(crate) gripper: GripperDrive,
    /// The part being handled, by its index in the cell's registry.
    pub(crate) current: usize,
    /// Each bottle's pose when the belt last stopped (`None` once it has left the belt), by its
    /// index in the cell's registry.
    pub(crate) bottle_rest: Vec<Option<Isometry3<f64>>>,
    pub(crate) feeder: Feeder,
    /// Parts placed so far per bin, by id (a stream fills its bins slot by slot).
    pub(crate) bin_fill: Vec<usize>,
    /// The phase in which the robot first touched a bottle in this cycle.
    pub(crate) touch_phase: Option<Phase>,
    pub(crate) phase: Phase,
    /// Grip force per jaw for the detected part type, N.
    pub(crate) grip_recipe_n: f64,
    /// The joint angles commanded, rad.
    pub(crate) q: JointVector,
    /// When the belt last stopped for a pick.
    pub(crate) pick_time_s: Option<f64>,
    /// The item at the photo-eye the camera took for something else, when it did.
    pub(crate) misidentified: Option<Misidentification>,
    /// How the arm has moved so far, as measured in the physics.
    pub(crate) motion: MotionRecord,
    /// The joint angles measured after the last step, rad.
    measured_q: JointVector,
    observer: ObserverSlot<'a>,
    /// The faults drawn for this trial, and what has come of them.
    pub(crate) faults: FaultLog,
}

impl<'a> Trial<'a> {
    /// A trial of `scenario` in `cell` as built; `rng` continues the cell's stream (the feeder
    /// draws from it).
    pub(crate) fn new(
        cell_model: &'a CellModel,
        camera: Option<&'a CameraPerception>,
        cell: Cell,
        rng: SimRng,
        seed: u64,
    ) -> Self {
        let scenario = cell_model.scenario();
        let model = cell_model.arm_model().clone();
        let home = scenario.robot.home_q_rad;
        let world_from_base = *cell.arm.world_from_base();
        let planner = PickPlanner {
            robot_shapes: capture_robot_shapes(&cell.world, &cell.arm, &model, &home),
            model,
            ik: cell_model.ik().clone(),
            world_from_base,
            finger_reference_m: cell.finger_reference_m,
            obstacles: scenery_obstacles(&cell.scenery, &world_from_base.inverse()),
            belt_top_z: cell.belt_top_z,
            open_clearance_m: scenario.gripper.open_clearance_m,
            speed_fraction: scenario.robot.speed_fraction,
            carry_speed_fraction: scenario.robot.carry_speed_fraction,
            home_q_rad: home,
        };
        let feeder = Feeder::new(scenario, rng);
        let measured_q = cell.arm.joint_positions(&cell.world);
        let motion = MotionRecord {
            joint_limit_margin_rad: limit_margin_rad(&planner.model, &measured_q),
            ..MotionRecord::default()
        };
        let bottle_rest = vec![None; cell.items.bottles().len()];
        let faults = FaultLog::new(FaultPlan::draw(scenario, seed));
        let mut belt = BeltDrive::with_creep(scenario.conveyor.creep_speed_m_s);
        if let Some(fault) = &faults.plan.belt {
            belt.inject(fault);
        }
        Self {
            scenario,
            catalogue: cell_model.catalogue(),
            camera,
            seed,
            shots: 0,
            planner,
            timing: TrialTiming::default(),
            belt,
            gripper: GripperDrive::new(cell.finger_reference_m, scenario.gripper.grip_force_n),
            current: 0,
            bottle_rest,
            feeder,
            bin_fill: vec![0; scenario.bins.len()],
            touch_phase: None,
            phase: Phase::Wait,
            grip_recipe_n: scenario.gripper.grip_force_n,
            q: home,
            pick_time_s: None,
            misidentified: None,
            motion,
            measured_q,
            observer: ObserverSlot::default(),
            faults,
            cell,
        }
    }

    /// Attaches an observer to trial `index` and shows it the cell as built.
    pub(crate) fn attach(
        &mut self,
        observer: Option<&'a mut (dyn TrialObserver + 'static)>,
        index: u32,
    ) {
        self.observer = ObserverSlot::new(observer);
        let scenario = self.scenario;
        self.observe(|slot, view| slot.begin(index, scenario, view));
    }

    /// Hands `f` the observer's slot and a view of the cell as it is now.
    pub(crate) fn observe(&mut self, f: impl FnOnce(&mut ObserverSlot<'a>, &CellView<'_>)) {
        let view = CellView {
            cell: &self.cell,
            phase: self.phase,
            joint_command_rad: self.q,
            grip_force_limit_n: self.gripper.force_n(),
        };
        f(&mut self.observer, &view);
    }

    /// The observer's slot (perception frames go through it).
    pub(crate) fn observer(&mut self) -> &mut ObserverSlot<'a> {
        &mut self.observer
    }

    /// Runs the belt until the photo-eye sees something, then stops it and lets things settle;
    /// notes where every bottle on the belt stands.
    pub(crate) fn wait_for_part(&mut self) -> Result<(), Failure> {
        self.phase = Phase::Wait;
        self.belt.run_at(self.scenario.conveyor.speed_m_s);
        let deadline =
            PhaseDeadline::start(Phase::Wait, self.cell.world.time_s(), &self.scenario.task);
        // Hold the arm at home while waiting.
        self.hold();
        let commanded_before_m = self.belt.commanded_travel_m();
        let encoder_before_m = self.belt.encoder_travel_m();
        while !self.photo_eye_reports() {
            if let Some(deadline) = &deadline
                && let Err(failure) = deadline.check(self.cell.world.time_s())
            {
                return Err(self.timed_out_feed(failure, commanded_before_m, encoder_before_m));
            }
            self.step()?;
        }
        self.note_belt_arrival(commanded_before_m, encoder_before_m);
        self.belt.run_at(0.0);
        while self.cell.conveyor.speed_m_s() > 0.0 {
            self.step()?;
        }
        self.settle(0.25)?;
        self.pick_time_s = Some(self.cell.world.time_s());
        // Bottles still on the belt are watched through the cycle; one that has run off the
        // belt's end is out of the robot's reach.
        let belt = &self.scenario.conveyor;
        let belt_end_x = belt.belt_center_m[0] + belt.length_m / 2.0;
        for (rest, bottle) in self.bottle_rest.iter_mut().zip(self.cell.items.bottles()) {
            *rest = self.cell.body_pose(bottle.body).filter(|pose| {
                pose.translation.x < belt_end_x
                    && (pose.translation.z - self.cell.belt_top_z).abs() < 0.2
            });
        }
        Ok(())
    }

    /// Runs the belt until the bottle at the photo-eye has passed it.
    pub(crate) fn let_pass(&mut self) -> Result<(), Failure> {
        self.phase = Phase::Pass;
        self.belt.run_at(self.scenario.conveyor.speed_m_s);
        let deadline =
            PhaseDeadline::start(Phase::Pass, self.cell.world.time_s(), &self.scenario.task);
        while self.photo_eye_reports() {
            if let Some(deadline) = &deadline {
                deadline.check(self.cell.world.time_s())?;
            }
            self.step()?;
        }
        Ok(())
    }

    /// The TCP's pose in the world.
    pub(crate) fn world_from_tcp(&self) -> Isometry3<f64> {
        self.cell.arm.flange_in_world(&self.cell.world) * self.planner.model.flange_from_tcp
    }

    /// The handled part's pose in the TCP frame.
    pub(crate) fn tcp_from_part(&self) -> Result<Isometry3<f64>, Failure> {
        let body = self.cell.items.parts()[self.current].body;
        let Some(world_from_part) = self.cell.body_pose(body) else {
            return fail(FailureReason::PhysicsBlowUp, "part body missing");
        };
        Ok(self.world_from_tcp().inverse() * world_from_part)
    }

    /// Plays `trajectory` from `from_s` to `to_s` seconds along it as `phase`, then holds its
    /// last sample for `settle_s`, watching a held part with `hold`, and the bottles. Phases
    /// that share a blended trajectory each play their own span of it, without a stop between.
    pub(crate) fn execute(
        &mut self,
        phase: Phase,
        trajectory: &JointTrajectory,
        (from_s, to_s): (f64, f64),
        settle_s: f64,
        hold: Option<&HoldMonitor>,
    ) -> Result<(), Failure> {
        self.phase = phase;
        let mut follower = TrajectoryFollower::new(trajectory.clone(), 0.0);
        let cycle = self.faults.cycles.saturating_sub(1);
        let stop = self
            .faults
            .plan
            .arm_stop_in(cycle, phase)
            .map(|stop| TrajectoryStop {
                at_s: from_s + stop.at_fraction * (to_s - from_s).max(0.0),
                duration_s: stop.duration_s,
            });
        if let Some(stop) = stop {
            follower = follower.with_stop(stop);
        }
        // Each command aims at the end of the coming step; the span's last one at `to_s`
        // exactly, so that the next span starts where this one stopped.
        let dt = self.cell.world.params().dt_s;
        let span_s = (follower.elapsed_s_at(to_s) - from_s).max(0.0);
        let steps = (span_s / dt - 1e-9).ceil().max(0.0) as usize;
        let settle_steps = (settle_s / dt - 1e-9).ceil().max(0.0) as usize;
        let mut stop_began_s = None;
        for step in 0..steps + settle_steps {
            if step < steps {
                let t_s = from_s + (dt * (step + 1) as f64).min(span_s);
                if follower.stopped_at(t_s) {
                    stop_began_s.get_or_insert(self.cell.world.time_s());
                } else if let (Some(began_s), Some(stop)) = (stop_began_s.take(), stop) {
                    // The servos release: the rest of the motion is checked again first.
                    self.resume_after_stop(phase, trajectory, (stop.at_s, to_s), began_s, hold)?;
                }
                if let Some(sample) = follower.command_at(&mut self.cell.world, &self.cell.arm, t_s)
                {
                    self.q = sample.q;
                }
            } else {
                self.hold();
            }
            self.step_physics()?;
            if let Some(hold) = hold {
                // Lowered into the bin, a part that meets the floor is placed, not slipping.
                let placed = phase == Phase::Place && self.bin_holding_part().is_some();
                if !placed {
                    let tcp_from_part = self.tcp_from_part()?;
                    let drift_mm = hold.drift_m(&tcp_from_part) * 1e3;
                    self.motion.grip_drift_mm = self.motion.grip_drift_mm.max(drift_mm);
                    self.watch_grip(phase, hold, &tcp_from_part)?;
                }
            }
        }
        Ok(())
    }

    /// Holds the arm where it is for `duration_s`.
    pub(crate) fn settle(&mut self, duration_s: f64) -> Result<(), Failure> {
        let end = self.cell.world.time_s() + duration_s;
        while self.cell.world.time_s() < end {
            self.step()?;
        }
        Ok(())
    }

    fn hold(&mut self) {
        self.cell
            .arm
            .command(&mut self.cell.world, &self.q, &[0.0; 6]);
    }

    /// One step holding the current arm command.
    fn step(&mut self) -> Result<(), Failure> {
        self.hold();
        self.step_physics()
    }

    /// One tick: the belt and gripper drives and the feeder, a physics step, the observer, then
    /// the time-out, blow-up and bottle-contact monitors.
    fn step_physics(&mut self) -> Result<(), Failure> {
        let dt = self.cell.world.params().dt_s;
        self.belt.set_zone_occupied(self.cell.slow_zone_occupied());
        let travel_m = self.belt.advance(&self.cell.conveyor, dt);
        self.feeder.advance(
            travel_m,
            self.scenario,
            &mut self.cell,
            &mut self.bottle_rest,
        );
        self.gripper
            .advance(&mut self.cell.world, &self.cell.arm, dt);
        let started = Instant::now();
        self.cell.step();
        self.timing.physics_ms += started.elapsed().as_secs_f64() * 1e3;
        if self.faults.plan.photo_eye_lies() {
            let beam = self.cell.photo_eye_blocked();
            self.faults.eye_reports = self.faults.eye.read(beam, self.cell.world.time_s());
        }
        self.measure_motion(dt);
        self.observe(|slot, view| slot.step(view));
        let time_s = self.cell.world.time_s();
        if time_s > self.scenario.task.trial_timeout_s {
            return fail(
                FailureReason::Timeout,
                format!("trial ran past {:.0} s", self.scenario.task.trial_timeout_s),
            );
        }
        for body in self.cell.items.bodies() {
            let finite = self
                .cell
                .world
                .physics
                .bodies
                .get(body)
                .is_some_and(|b| b.position().is_finite() && b.linvel().is_finite());
            if !finite {
                return fail(
                    FailureReason::PhysicsBlowUp,
                    format!("a body's state became non-finite at t = {time_s:.3} s"),
                );
            }
        }
        if self.touch_phase.is_none() && self.robot_touches_bottle() {
            self.touch_phase = Some(self.phase);
        }
        Ok(())
    }

    /// Books the step's simulated time to the phase, and checks the joints as measured.
    fn measure_motion(&mut self, dt_s: f64) {
        self.motion.phase_s[self.phase] += dt_s;
        let q = self.cell.arm.joint_positions(&self.cell.world);
        let motion = &mut self.motion;
        for (j, limit) in self.planner.model.limits.iter().enumerate() {
            let speed = (q[j] - self.measured_q[j]).abs() / dt_s;
            motion.joint_speed_ratio = motion
                .joint_speed_ratio
                .max(speed / limit.max_velocity_rad_s);
            motion.tracking_error_rad = motion.tracking_error_rad.max((q[j] - self.q[j]).abs());
        }
        motion.joint_limit_margin_rad = motion
            .joint_limit_margin_rad
            .min(limit_margin_rad(&self.planner.model, &q));
        self.measured_q = q;
    }

    fn robot_touches_bottle(&self) -> bool {
        self.cell
            .items
            .bottles()
            .iter()
            .any(|bottle| self.robot_touches(bottle.body))
    }

    fn robot_touches(&self, bottle: RigidBodyHandle) -> bool {
        self.cell
            .world
            .touches(bottle, Tag::Robot, TOUCH_DISTANCE_M)
    }

    /// The bin the handled part rests in, if any.
    pub(crate) fn bin_holding_part(&self) -> Option<BinId> {
        let pose = self
            .cell
            .body_pose(self.cell.items.parts()[self.current].body)?;
        let center = pose.translation.vector;
        self.cell
            .bins
            .iter()
            .position(|bin| bin.contains(&center))
            .map(BinId)
    }

    /// The largest move of a bottle since the belt last stopped, m.
    pub(crate) fn bottle_displacement_m(&self) -> f64 {
        self.cell
            .items
            .bottles()
            .iter()
            .zip(&self.bottle_rest)
            .filter_map(|(bottle, rest)| {
                let (now, rest) = (self.cell.body_pose(bottle.body)?, (*rest)?);
                Some((now.translation.vector - rest.translation.vector).norm())
            })
            .fold(0.0, f64::max)
    }

    /// Whether a bottle has been lifted since the belt last stopped.
    pub(crate) fn bottle_lifted(&self) -> bool {
        self.cell
            .items
            .bottles()
            .iter()
            .zip(&self.bottle_rest)
            .any(|(bottle, rest)| {
                let (Some(now), Some(rest)) = (self.cell.body_pose(bottle.body), rest) else {
                    return false;
                };
                now.translation.z - rest.translation.z > 0.02
            })
    }
}

/// The smallest distance of any joint of `q` from its position limits, rad (negative past one).
fn limit_margin_rad(model: &ArmModel, q: &JointVector) -> f64 {
    model
        .limits
        .iter()
        .zip(q)
        .map(|(limit, &value)| (value - limit.min_rad).min(limit.max_rad - value))
        .fold(f64::INFINITY, f64::min)
}
