//! One trial's running state, reset from a seed: the world and its items, the drives, the
//! feeder, the phase, the bins' fill and what the monitors have seen. What the scenario fixes
//! (the arm, its IK, the catalogue) stays in the [`CellModel`]; every function here that needs
//! it takes it as an argument.

use std::time::Instant;

use nalgebra::Isometry3;
use rapier3d::prelude::*;

use super::fault_handling::FaultLog;
use super::feeder::Feeder;
use super::judge::CycleEvidence;
use super::observer::{CellView, ObserverSlot, PerceptionFrame, TrialObserver};
use crate::cell::{Cell, CellError, CellModel};
use crate::control::{BeltDrive, FaultPlan, GripperDrive};
use crate::kinematics::{ArmModel, JointVector};
use crate::outcome::{Failure, FailureReason, MotionRecord, Phase, TrialTiming, fail};
use crate::rng::SimRng;
use crate::scenario::{BinId, PartTypeId};
use crate::sim::Tag;

/// A robot collider this close to a bottle counts as touching it, m.
const TOUCH_DISTANCE_M: f64 = 0.0005;

/// A trial's state: built by [`CellData::reset`] from the model and a seed, then stepped.
pub struct CellData {
    /// The cell as built for this trial: world, arm, belt, bins, items.
    pub(crate) cell: Cell,
    /// The trial's seed, and the camera shots taken so far (each draws its own realism).
    pub(crate) seed: u64,
    pub(crate) shots: u64,
    pub(crate) belt: BeltDrive,
    pub(crate) gripper: GripperDrive,
    pub(crate) feeder: Feeder,
    pub(crate) phase: Phase,
    /// Parts placed so far per bin, by id (a stream fills its bins slot by slot).
    pub(crate) bin_fill: Vec<usize>,
    /// The joint angles commanded, rad.
    pub(crate) q: JointVector,
    /// Each bottle's pose when the belt last stopped (`None` once it has left the belt), by its
    /// index in the cell's registry.
    pub(crate) bottle_rest: Vec<Option<Isometry3<f64>>>,
    /// The phase in which the robot first touched a bottle in this cycle.
    pub(crate) touch_phase: Option<Phase>,
    /// Bottles a planned removal has put into the waste bin, by index: no longer watched.
    pub(crate) removed: Vec<bool>,
    /// While a removal runs, each bottle's first touch by the robot and its phase: the one the
    /// removal puts into the waste bin was meant to be touched, any other was not.
    pub(crate) removal_touches: Option<Vec<Option<Phase>>>,
    /// Bottles removed into the waste bin so far in the trial.
    pub(crate) removals: u32,
    /// Where the removals let their bottles come to rest in the waste bin, as planned: the
    /// next one is let go clear of them.
    pub(crate) waste_contents: Vec<crate::station::PerceivedObstacle>,
    /// How the arm has moved so far, as measured in the physics.
    pub(crate) motion: MotionRecord,
    pub(crate) timing: TrialTiming,
    /// The faults drawn for this trial from its seed, and what has come of them.
    pub(crate) faults: FaultLog,
    /// The joint angles measured after the last step, rad.
    measured_q: JointVector,
    observer: ObserverSlot,
}

impl CellData {
    /// The cell of the trial with `seed`, as built, the arm at home and the belt stopped.
    pub fn reset(model: &CellModel, seed: u64) -> Result<Self, CellError> {
        let scenario = model.scenario();
        let mut rng = SimRng::new(seed);
        let cell = Cell::build(model, &mut rng)?;
        // The feeder continues the cell's stream.
        let feeder = Feeder::new(scenario, rng);
        let measured_q = cell.arm.joint_positions(&cell.world);
        let motion = MotionRecord {
            joint_limit_margin_rad: limit_margin_rad(model.arm_model(), &measured_q),
            ..MotionRecord::default()
        };
        let faults = FaultLog::new(FaultPlan::draw(scenario, seed));
        let mut belt = BeltDrive::with_creep(scenario.conveyor.creep_speed_m_s);
        if let Some(fault) = &faults.plan.belt {
            belt.inject(fault);
        }
        Ok(Self {
            faults,
            seed,
            shots: 0,
            belt,
            gripper: GripperDrive::new(cell.finger_reference_m, scenario.gripper.grip_force_n),
            feeder,
            phase: Phase::Wait,
            bin_fill: vec![0; scenario.bins.len()],
            q: scenario.robot.home_q_rad,
            bottle_rest: vec![None; cell.items.bottles().len()],
            touch_phase: None,
            removed: Vec::new(),
            removal_touches: None,
            removals: 0,
            waste_contents: Vec::new(),
            motion,
            timing: TrialTiming::default(),
            measured_q,
            observer: ObserverSlot::default(),
            cell,
        })
    }

    /// Attaches an observer to trial `index` and shows it the cell as built.
    pub fn attach(
        &mut self,
        model: &CellModel,
        observer: Option<Box<dyn TrialObserver>>,
        index: u32,
    ) {
        self.observer = ObserverSlot::new(observer);
        let view = view_of(&self.cell, self.phase, self.q, &self.gripper);
        self.observer.begin(index, model.scenario(), &view);
    }

    /// Takes the observer back (to show it the trial's record).
    pub fn detach(&mut self) -> Option<Box<dyn TrialObserver>> {
        self.observer.take()
    }

    /// The cell as it is now, read-only.
    pub fn view(&self) -> CellView<'_> {
        view_of(&self.cell, self.phase, self.q, &self.gripper)
    }

    /// Hands perception's result to the observer; `frame` is built only when one is attached.
    pub(crate) fn observe_perception(&mut self, frame: impl FnOnce() -> PerceptionFrame) {
        self.observer.perception(frame);
    }

    /// Commands the arm to hold the joint angles last commanded.
    pub(crate) fn hold(&mut self) {
        self.cell
            .arm
            .command(&mut self.cell.world, &self.q, &[0.0; 6]);
    }

    /// One tick holding the current arm command.
    pub(crate) fn step(&mut self, model: &CellModel) -> Result<(), Failure> {
        self.hold();
        self.tick(model)
    }

    /// One tick: the belt and gripper drives and the feeder, a physics step, the observer, then
    /// the time-out, blow-up and bottle-contact monitors.
    pub(crate) fn tick(&mut self, model: &CellModel) -> Result<(), Failure> {
        let scenario = model.scenario();
        let dt = self.cell.world.params().dt_s;
        self.belt.set_zone_occupied(self.cell.slow_zone_occupied());
        let travel_m = self.belt.advance(&self.cell.conveyor, dt);
        self.feeder
            .advance(travel_m, model, &mut self.cell, &mut self.bottle_rest);
        self.gripper
            .advance(&mut self.cell.world, &self.cell.arm, dt);
        let started = Instant::now();
        self.cell.step();
        self.timing.physics_ms += started.elapsed().as_secs_f64() * 1e3;
        if self.faults.plan.photo_eye_lies() {
            let beam = self.cell.photo_eye_blocked();
            self.faults.eye_reports = self.faults.eye.read(beam, self.cell.world.time_s());
        }
        self.measure_motion(model.arm_model(), dt);
        let view = view_of(&self.cell, self.phase, self.q, &self.gripper);
        self.observer.step(&view);
        let time_s = self.cell.world.time_s();
        if time_s > scenario.task.trial_timeout_s {
            return fail(
                FailureReason::Timeout,
                format!("trial ran past {:.0} s", scenario.task.trial_timeout_s),
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
        if self.removal_touches.is_some() {
            self.note_removal_touches();
        } else if self.touch_phase.is_none() && self.robot_touches_bottle() {
            self.touch_phase = Some(self.phase);
        }
        Ok(())
    }

    /// Books the step's simulated time to the phase, and checks the joints as measured.
    fn measure_motion(&mut self, arm: &ArmModel, dt_s: f64) {
        self.motion.phase_s[self.phase] += dt_s;
        let q = self.cell.arm.joint_positions(&self.cell.world);
        let motion = &mut self.motion;
        for (j, limit) in arm.limits.iter().enumerate() {
            let speed = (q[j] - self.measured_q[j]).abs() / dt_s;
            motion.joint_speed_ratio = motion
                .joint_speed_ratio
                .max(speed / limit.max_velocity_rad_s);
            motion.tracking_error_rad = motion.tracking_error_rad.max((q[j] - self.q[j]).abs());
        }
        motion.joint_limit_margin_rad =
            motion.joint_limit_margin_rad.min(limit_margin_rad(arm, &q));
        self.measured_q = q;
    }

    /// The TCP's pose in the world.
    pub(crate) fn world_from_tcp(&self, arm: &ArmModel) -> Isometry3<f64> {
        self.cell.arm.flange_in_world(&self.cell.world) * arm.flange_from_tcp
    }

    /// The pose of part `part` (by its index in the cell's registry) in the TCP frame.
    pub(crate) fn tcp_from_part(
        &self,
        arm: &ArmModel,
        part: usize,
    ) -> Result<Isometry3<f64>, Failure> {
        let body = self.cell.items.parts()[part].body;
        let Some(world_from_part) = self.cell.body_pose(body) else {
            return fail(FailureReason::PhysicsBlowUp, "part body missing");
        };
        Ok(self.world_from_tcp(arm).inverse() * world_from_part)
    }

    /// The bin part `part` rests in, if any.
    pub(crate) fn bin_holding(&self, part: usize) -> Option<BinId> {
        let pose = self.cell.body_pose(self.cell.items.parts()[part].body)?;
        let center = pose.translation.vector;
        self.cell
            .bins
            .iter()
            .position(|bin| bin.contains(&center))
            .map(BinId)
    }

    /// Whether bottle `index` was removed into the waste bin by a planned removal.
    pub(crate) fn is_removed(&self, index: usize) -> bool {
        self.removed.get(index).copied().unwrap_or(false)
    }

    fn robot_touches_bottle(&self) -> bool {
        self.cell
            .items
            .bottles()
            .iter()
            .enumerate()
            .any(|(i, bottle)| !self.is_removed(i) && self.robot_touches(bottle.body))
    }

    /// Notes the bottles the robot touches now, each under the phase it was first touched in.
    fn note_removal_touches(&mut self) {
        let touching: Vec<usize> = (0..self.cell.items.bottles().len())
            .filter(|&i| {
                !self.is_removed(i) && self.robot_touches(self.cell.items.bottles()[i].body)
            })
            .collect();
        let phase = self.phase;
        if let Some(touches) = self.removal_touches.as_mut() {
            for i in touching {
                if i >= touches.len() {
                    touches.resize(i + 1, None);
                }
                touches[i].get_or_insert(phase);
            }
        }
    }

    fn robot_touches(&self, bottle: RigidBodyHandle) -> bool {
        self.cell
            .world
            .touches(bottle, Tag::Robot, TOUCH_DISTANCE_M)
    }

    /// The largest move of a bottle since the belt last stopped, m.
    pub(crate) fn bottle_displacement_m(&self) -> f64 {
        self.cell
            .items
            .bottles()
            .iter()
            .zip(&self.bottle_rest)
            .enumerate()
            .filter(|(i, _)| !self.is_removed(*i))
            .filter_map(|(_, (bottle, rest))| {
                let (now, rest) = (self.cell.body_pose(bottle.body)?, (*rest)?);
                Some((now.translation.vector - rest.translation.vector).norm())
            })
            .fold(0.0, f64::max)
    }

    /// The judge's evidence on part `part` as the cell stands now: its type, the bin it rests
    /// in, and what happened to the bottles.
    pub(crate) fn cycle_evidence(&self, part: usize) -> CycleEvidence {
        CycleEvidence {
            part_type: PartTypeId(self.cell.items.parts()[part].instance.type_index),
            placed_bin: self.bin_holding(part),
            bottle_lifted: self.bottle_lifted(),
            touch_phase: self.touch_phase,
            bottle_displacement_m: self.bottle_displacement_m(),
        }
    }

    /// Whether a bottle has been lifted since the belt last stopped.
    pub(crate) fn bottle_lifted(&self) -> bool {
        self.cell
            .items
            .bottles()
            .iter()
            .zip(&self.bottle_rest)
            .enumerate()
            .filter(|(i, _)| !self.is_removed(*i))
            .any(|(_, (bottle, rest))| {
                let (Some(now), Some(rest)) = (self.cell.body_pose(bottle.body), rest) else {
                    return false;
                };
                now.translation.z - rest.translation.z > 0.02
            })
    }
}

fn view_of<'a>(
    cell: &'a Cell,
    phase: Phase,
    joint_command_rad: JointVector,
    gripper: &GripperDrive,
) -> CellView<'a> {
    CellView {
        cell,
        phase,
        joint_command_rad,
        grip_force_limit_n: gripper.force_n(),
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
