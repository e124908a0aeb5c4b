//! Driving the cell while the belt never stops (conveyor tracking): every tick watches the
//! photo-eye, whose rising edge latches the item's encoder count and has the camera look at
//! it there and then; and the arm plays a planned joint trajectory either as planned or moved
//! along the belt with a part, the tool's pose shifted by the belt's travel since the plan's
//! place (read from the encoder) and solved by the analytic IK, nearest the last command, with
//! the belt's speed fed forward into the joint rates.

use std::collections::VecDeque;

use nalgebra::{Isometry3, Translation3, Vector3};

use super::at_eye::AtEye;
use super::belt_hold::{BeltHold, HOLD_BACKOFF_M};
use super::cell_data::CellData;
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::control::{ENCODER_M_PER_COUNT, HoldMonitor};
use crate::kinematics::{IkSolver, JointVector, tcp_pose};
use crate::outcome::{Failure, FailureReason, Phase};
use crate::planning::JointTrajectory;
use crate::station::{Percept, TrackEnd, TrackId};

/// An item the photo-eye latched and the camera (or the oracle) saw there.
pub(super) struct Latched {
    /// The encoder's count at the eye's edge.
    pub(super) count: i64,
    /// The time of the edge, s.
    pub(super) time_s: f64,
    /// The part the truth has at the beam (for the judge), by registry index.
    pub(super) part: usize,
    /// What perception said of it, in the world as it stood at `count`.
    pub(super) percept: Percept,
    /// Its track.
    pub(super) track: Option<TrackId>,
    /// Its standing limit: the last place along the belt at which the arm can pick it from a
    /// stopped belt (`None`: nowhere, or no longer; the belt is never held for it).
    pub(super) limit_x: Option<f64>,
    /// How far short of its limit a hold may stand it, m.
    pub(super) backoff_m: f64,
}

impl Latched {
    /// Where the part stands along the belt (world x) at encoder count `count`, m.
    pub(super) fn x_at(&self, count: i64) -> f64 {
        self.percept.part_xy[0] + (count - self.count) as f64 * ENCODER_M_PER_COUNT
    }
}

/// What the eye has latched and what came of it, over a tracking stream.
#[derive(Default)]
pub(super) struct EyeWatch {
    eye_was: bool,
    /// Parts latched and not yet picked or given up, oldest first.
    pub(super) parts: VecDeque<Latched>,
    /// Items the eye latched.
    pub(super) latched: u32,
    /// When the eye latched its first item, s.
    pub(super) first_latch_s: Option<f64>,
    /// Bottles let ride on, by track.
    pub(super) bottle_tracks: Vec<TrackId>,
    pub(super) bottles: u32,
    /// Items latched that perception could not make out (they ride on), with why.
    pub(super) unseen: Vec<String>,
    /// The pick window along the belt, m.
    pub(super) window: (f64, f64),
    /// The belt's holds.
    pub(super) belt: BeltHold,
    /// Whether the arm waits over a bin (risen clear of it) rather than at home.
    pub(super) parked: bool,
}

/// The arm moved with the belt: the plan was made for the part at `plan_x_m` along the belt.
#[derive(Clone, Copy)]
pub(super) struct Follow<'l> {
    pub(super) part: &'l Latched,
    pub(super) plan_x_m: f64,
    pub(super) speed_m_s: f64,
}

/// A span of a planned trajectory to play as `phase`, from `span.0` to `span.1` s along it,
/// then its last sample held for `settle_s`; moved with the belt throughout when `follow` is
/// given.
pub(super) struct Play<'a> {
    pub(super) phase: Phase,
    pub(super) trajectory: &'a JointTrajectory,
    pub(super) span: (f64, f64),
    pub(super) settle_s: f64,
    pub(super) follow: Option<Follow<'a>>,
}

impl<'a> Play<'a> {
    /// `trajectory` from `from_s` to `to_s` as `phase`, no rest, not moved with the belt.
    pub(super) fn span(phase: Phase, trajectory: &'a JointTrajectory, span: (f64, f64)) -> Self {
        Self {
            phase,
            trajectory,
            span,
            settle_s: 0.0,
            follow: None,
        }
    }

    /// With the last sample held `settle_s` after the span.
    pub(super) fn settle(mut self, settle_s: f64) -> Self {
        self.settle_s = settle_s;
        self
    }

    /// Moved with the belt by `follow`, when given.
    pub(super) fn follow(mut self, follow: Option<Follow<'a>>) -> Self {
        self.follow = follow;
        self
    }
}

/// A part held while a motion plays: its monitor, and the largest drift seen, mm.
pub(super) struct HeldPart {
    pub(super) part: usize,
    pub(super) monitor: HoldMonitor,
    pub(super) drift_mm: f64,
}

impl Sorter<'_> {
    /// One tick; the eye's rising edge latches the item there.
    pub(super) fn tick_watching(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
    ) -> Result<(), Failure> {
        data.tick(model)?;
        let blocked = data.photo_eye_reports();
        if blocked && !watch.eye_was {
            self.latch(model, data, watch)?;
        }
        watch.eye_was = blocked;
        let parts: Vec<&Latched> = watch.parts.iter().collect();
        watch.belt.watch(data, &parts);
        Ok(())
    }

    /// The eye's edge: latch the count, look, and queue a part or let a bottle ride on. A
    /// misidentification halts the stream (`Err`); an item perception cannot make out rides on.
    fn latch(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
    ) -> Result<(), Failure> {
        let count = data.belt.encoder_counts();
        let time_s = data.cell.world.time_s();
        watch.latched += 1;
        watch.first_latch_s.get_or_insert(time_s);
        let (held, held_track) = (self.current, self.station_track.take());
        let phase = data.phase;
        let result = self.identify_at_eye(model, data);
        let at_beam = self.current;
        let track = self.station_track.take();
        let outcome = match result {
            Ok(AtEye::Bottle) => {
                watch.bottles += 1;
                watch.bottle_tracks.extend(track);
                Ok(())
            }
            Ok(AtEye::Part(seen)) => {
                match self.perceive(model, data, seen.map(|s| *s)) {
                    Ok(percept) => {
                        let mut item = Latched {
                            count,
                            time_s,
                            part: at_beam,
                            percept,
                            track,
                            limit_x: None,
                            backoff_m: HOLD_BACKOFF_M,
                        };
                        if let (Some(tracking), Some(id)) = (self.tracking.as_mut(), track) {
                            let seen = &item.percept;
                            tracking.note_size(id, seen.part_outer_radius_m, seen.part_height_m);
                        }
                        item.limit_x = self.standing_limit(model, data, &item, watch.window);
                        watch.parts.push_back(item);
                    }
                    Err(f) => watch.unseen.push(f.detail),
                }
                Ok(())
            }
            Err(f) if f.reason == FailureReason::Misidentified => Err(f),
            Err(f) => {
                watch.unseen.push(f.detail);
                Ok(())
            }
        };
        self.current = held;
        self.station_track = held_track;
        data.phase = phase;
        outcome
    }

    /// Holds the arm where it was last commanded for `duration_s`, watching the eye.
    pub(super) fn wait_watching(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
        duration_s: f64,
    ) -> Result<(), Failure> {
        let end = data.cell.world.time_s() + duration_s;
        while data.cell.world.time_s() < end - 1e-9 {
            data.hold();
            self.tick_watching(model, data, watch)?;
        }
        Ok(())
    }

    /// Plays `play`, watching a `held` part and the eye.
    pub(super) fn play_watching(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
        play: Play<'_>,
        mut held: Option<&mut HeldPart>,
    ) -> Result<(), Failure> {
        let Play {
            phase,
            trajectory,
            span: (from_s, to_s),
            settle_s,
            follow,
        } = play;
        data.phase = phase;
        let dt = data.cell.world.params().dt_s;
        let span_s = (to_s - from_s).max(0.0);
        let steps = (span_s / dt - 1e-9).ceil().max(0.0) as usize;
        let settle_steps = (settle_s / dt - 1e-9).ceil().max(0.0) as usize;
        for step in 0..steps + settle_steps {
            let t_s = from_s + (dt * (step + 1) as f64).min(span_s);
            let Some(mut sample) = trajectory.sample(t_s) else {
                return Err(Failure::new(FailureReason::Panic, "an empty trajectory"));
            };
            if step >= steps {
                sample.qd = [0.0; 6];
            }
            let (q, qd) = match follow {
                Some(f) => self.follow_command(data, &f, &sample.q, &sample.qd, dt)?,
                None => (sample.q, sample.qd),
            };
            data.cell.arm.command(&mut data.cell.world, &q, &qd);
            data.q = q;
            self.tick_watching(model, data, watch)?;
            if let Some(h) = held.as_deref_mut() {
                let placed = phase == Phase::Place && data.bin_holding(h.part).is_some();
                if !placed {
                    let tcp_from_part = data.tcp_from_part(model.arm_model(), h.part)?;
                    let drift_mm = h.monitor.drift_m(&tcp_from_part) * 1e3;
                    h.drift_mm = h.drift_mm.max(drift_mm);
                    data.motion.grip_drift_mm = data.motion.grip_drift_mm.max(drift_mm);
                    data.watch_grip(model, phase, &h.monitor, &tcp_from_part)?;
                }
            }
        }
        Ok(())
    }

    /// The joint command for the planned `q_plan` (rates `qd_plan`) moved along the belt with
    /// `follow`'s part by the end of the coming step `dt`: the planned tool pose shifted by the
    /// part's travel from the plan's place, solved nearest the last command; the rates are
    /// the planned ones with the belt's speed fed forward, by the IK of the pose one step on.
    fn follow_command(
        &self,
        data: &CellData,
        follow: &Follow<'_>,
        q_plan: &JointVector,
        qd_plan: &JointVector,
        dt: f64,
    ) -> Result<(JointVector, JointVector), Failure> {
        let count = data.belt.encoder_counts();
        let offset_m = follow.part.x_at(count) + follow.speed_m_s * dt - follow.plan_x_m;
        let q = self.shifted_ik(q_plan, offset_m, &data.q)?;
        let mut q_next_plan = *q_plan;
        for (q, qd) in q_next_plan.iter_mut().zip(qd_plan) {
            *q += qd * dt;
        }
        let q_next = self.shifted_ik(&q_next_plan, offset_m + follow.speed_m_s * dt, &q)?;
        let mut qd = [0.0; 6];
        for j in 0..6 {
            qd[j] = (q_next[j] - q[j]) / dt;
        }
        Ok((q, qd))
    }

    /// The joints that put the tool where `q_plan` puts it, moved `offset_m` along the belt
    /// (world +x), nearest `near`; fails when the arm cannot reach there.
    pub(super) fn shifted_ik(
        &self,
        q_plan: &JointVector,
        offset_m: f64,
        near: &JointVector,
    ) -> Result<JointVector, Failure> {
        self.moved_ik(q_plan, &Vector3::new(offset_m, 0.0, 0.0), near)
            .ok_or_else(|| {
                Failure::new(
                    FailureReason::Unreachable,
                    format!(
                        "the belt carried the tool {:.0} mm past where the arm reaches",
                        offset_m * 1e3
                    ),
                )
            })
    }

    /// The joints that put the tool where `q_plan` puts it, moved by `offset_m` (world),
    /// nearest `near`; `None` where the arm cannot reach there.
    pub(super) fn moved_ik(
        &self,
        q_plan: &JointVector,
        offset_m: &Vector3<f64>,
        near: &JointVector,
    ) -> Option<JointVector> {
        let planner = &self.planner;
        let pose = tcp_pose(&planner.model, q_plan);
        let shift = planner.world_from_base.inverse().rotation * offset_m;
        let moved = Isometry3::from_parts(
            Translation3::from(pose.translation.vector + shift),
            pose.rotation,
        );
        planner.ik.solve(&moved).nearest(near)
    }

    /// Closes `track` as picked.
    pub(super) fn close_picked(&mut self, track: Option<TrackId>) {
        if let (Some(tracking), Some(track)) = (self.tracking.as_mut(), track) {
            tracking.tracks.close(track, TrackEnd::Picked);
        }
    }
}
