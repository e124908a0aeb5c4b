//! The stages that only drive the cell: run the belt to the photo-eye or past it, rest, and play
//! a joint trajectory while watching a held part. Each is a function of the trial's state and
//! the model it was built from.

use super::cell_data::CellData;
use super::phase::PhaseDeadline;
use super::pick_cycle::{OPEN_FORCE_N, RELEASE_MARGIN_S};
use crate::cell::CellModel;
use crate::control::{HoldMonitor, TrajectoryFollower, TrajectoryStop};
use crate::outcome::{Failure, Phase};
use crate::planning::JointTrajectory;
use crate::sim::JAW_SPEED_M_S;

/// A part held by the jaws while a trajectory plays: which one, and the monitor of its grip.
#[derive(Clone, Copy)]
pub(crate) struct Held<'h> {
    /// The part's index in the cell's registry.
    pub(crate) part: usize,
    pub(crate) monitor: &'h HoldMonitor,
}

impl CellData {
    /// Runs the belt until the photo-eye sees something, then stops it and lets things settle;
    /// notes where every bottle on the belt stands. Returns the time the belt stopped, s.
    pub(crate) fn wait_for_part(&mut self, model: &CellModel) -> Result<f64, Failure> {
        let scenario = model.scenario();
        self.phase = Phase::Wait;
        self.belt.run_at(scenario.conveyor.speed_m_s);
        let deadline = PhaseDeadline::start(Phase::Wait, self.cell.world.time_s(), &scenario.task);
        // Hold the arm at home while waiting.
        self.hold();
        let commanded_before_m = self.belt.commanded_travel_m();
        let encoder_before_m = self.belt.encoder_travel_m();
        while !self.photo_eye_reports() {
            if let Some(deadline) = &deadline
                && let Err(failure) = deadline.check(self.cell.world.time_s())
            {
                let before = (commanded_before_m, encoder_before_m);
                return Err(self.timed_out_feed(model, failure, before));
            }
            self.step(model)?;
        }
        self.note_belt_arrival(commanded_before_m, encoder_before_m);
        self.belt.run_at(0.0);
        while self.cell.conveyor.speed_m_s() > 0.0 {
            self.step(model)?;
        }
        self.settle(model, 0.25)?;
        self.note_bottle_rest(model);
        Ok(self.cell.world.time_s())
    }

    /// Notes each bottle's pose where the belt stopped: bottles still on the belt are watched
    /// through the cycle; one that has run off the belt's end (`None`) is out of the robot's
    /// reach.
    pub(crate) fn note_bottle_rest(&mut self, model: &CellModel) {
        let belt = &model.scenario().conveyor;
        let belt_end_x = belt.belt_center_m[0] + belt.length_m / 2.0;
        for (rest, bottle) in self.bottle_rest.iter_mut().zip(self.cell.items.bottles()) {
            *rest = self.cell.body_pose(bottle.body).filter(|pose| {
                pose.translation.x < belt_end_x
                    && (pose.translation.z - self.cell.belt_top_z).abs() < 0.2
            });
        }
    }

    /// Runs the belt until the bottle at the photo-eye has passed it.
    pub(crate) fn let_pass(&mut self, model: &CellModel) -> Result<(), Failure> {
        let scenario = model.scenario();
        self.phase = Phase::Pass;
        self.belt.run_at(scenario.conveyor.speed_m_s);
        let deadline = PhaseDeadline::start(Phase::Pass, self.cell.world.time_s(), &scenario.task);
        while self.photo_eye_reports() {
            if let Some(deadline) = &deadline {
                deadline.check(self.cell.world.time_s())?;
            }
            self.step(model)?;
        }
        Ok(())
    }

    /// Opens the jaws to `open_m` from where the pads stand, and waits until the drive has
    /// brought both pads clear of what they held.
    pub(crate) fn release_jaws(&mut self, model: &CellModel, open_m: f64) -> Result<(), Failure> {
        let pads = self.cell.arm.finger_positions_m(&self.cell.world);
        self.gripper
            .open_from(pads[0].min(pads[1]), open_m, OPEN_FORCE_N);
        let travel_m = (open_m - self.gripper.target_m()).max(0.0);
        self.settle(model, travel_m / JAW_SPEED_M_S + RELEASE_MARGIN_S)
    }

    /// Holds the arm where it is for `duration_s`.
    pub(crate) fn settle(&mut self, model: &CellModel, duration_s: f64) -> Result<(), Failure> {
        let end = self.cell.world.time_s() + duration_s;
        while self.cell.world.time_s() < end {
            self.step(model)?;
        }
        Ok(())
    }

    /// Plays `trajectory` from `from_s` to `to_s` seconds along it as `phase`, then holds its
    /// last sample for `settle_s`, watching the `held` part, and the bottles. Phases that share
    /// a blended trajectory each play their own span of it, without a stop between.
    pub(crate) fn execute(
        &mut self,
        model: &CellModel,
        phase: Phase,
        trajectory: &JointTrajectory,
        (from_s, to_s): (f64, f64),
        settle_s: f64,
        held: Option<Held<'_>>,
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
                    let span = (stop.at_s, to_s);
                    self.resume_after_stop(phase, trajectory, span, began_s, held.is_some())?;
                }
                if let Some(sample) = follower.command_at(&mut self.cell.world, &self.cell.arm, t_s)
                {
                    self.q = sample.q;
                }
            } else {
                self.hold();
            }
            self.tick(model)?;
            if let Some(Held { part, monitor }) = held {
                // Lowered into the bin, a part that meets the floor is placed, not slipping.
                let placed = phase == Phase::Place && self.bin_holding(part).is_some();
                if !placed {
                    let tcp_from_part = self.tcp_from_part(model.arm_model(), part)?;
                    let drift_mm = monitor.drift_m(&tcp_from_part) * 1e3;
                    self.motion.grip_drift_mm = self.motion.grip_drift_mm.max(drift_mm);
                    self.watch_grip(model, phase, monitor, &tcp_from_part)?;
                }
            }
        }
        Ok(())
    }
}
