//! The phases of a trial, as an explicit state machine: what follows what, and which phases end
//! by a time-out rather than by a trajectory's end.

use crate::outcome::{Failure, FailureReason, PhaseSeconds};
use crate::scenario::TaskSection;

/// What the cell is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Phase {
    /// The belt runs until something breaks the photo-eye's beam, then stops and settles.
    Wait,
    /// The camera (or the oracle) looks at the pick station.
    Perceive,
    /// Grasp and place are searched for and collision-checked.
    Plan,
    /// Jaws open, the arm moves above the part.
    Approach,
    /// Straight down around the part.
    Descend,
    /// The jaws close with the part type's force until they stop on it.
    Grasp,
    /// Straight up with the part.
    Lift,
    /// Over to the bin, carrying.
    Transport,
    /// Down into the bin's slot.
    Place,
    /// Jaws open over the placed part.
    Release,
    /// Up and home.
    Retreat,
    /// The belt runs a bottle through the station (a stream lets bottles pass).
    Pass,
}

impl Phase {
    /// The pick cycle, in order: from a stopped belt to the arm back home.
    pub const PICK_CYCLE: [Phase; 10] = [
        Phase::Perceive,
        Phase::Plan,
        Phase::Approach,
        Phase::Descend,
        Phase::Grasp,
        Phase::Lift,
        Phase::Transport,
        Phase::Place,
        Phase::Release,
        Phase::Retreat,
    ];

    /// The phase's name in records, logs and recordings.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Wait => "wait",
            Self::Perceive => "perceive",
            Self::Plan => "plan",
            Self::Approach => "approach",
            Self::Descend => "descend",
            Self::Grasp => "grasp",
            Self::Lift => "lift",
            Self::Transport => "transport",
            Self::Place => "place",
            Self::Release => "release",
            Self::Retreat => "retreat",
            Self::Pass => "pass",
        }
    }

    /// The phase after this one when it succeeds: along the pick cycle, back to waiting after
    /// the retreat or a bottle's pass.
    pub fn next(self) -> Phase {
        match self {
            Self::Wait => Self::Perceive,
            Self::Perceive => Self::Plan,
            Self::Plan => Self::Approach,
            Self::Approach => Self::Descend,
            Self::Descend => Self::Grasp,
            Self::Grasp => Self::Lift,
            Self::Lift => Self::Transport,
            Self::Transport => Self::Place,
            Self::Place => Self::Release,
            Self::Release => Self::Retreat,
            Self::Retreat | Self::Pass => Self::Wait,
        }
    }

    /// This phase's entry in a trial's seconds per phase.
    pub fn seconds_in(self, seconds: &mut PhaseSeconds) -> &mut f64 {
        match self {
            Self::Wait => &mut seconds.wait,
            Self::Perceive => &mut seconds.perceive,
            Self::Plan => &mut seconds.plan,
            Self::Approach => &mut seconds.approach,
            Self::Descend => &mut seconds.descend,
            Self::Grasp => &mut seconds.grasp,
            Self::Lift => &mut seconds.lift,
            Self::Transport => &mut seconds.transport,
            Self::Place => &mut seconds.place,
            Self::Release => &mut seconds.release,
            Self::Retreat => &mut seconds.retreat,
            Self::Pass => &mut seconds.pass,
        }
    }

    /// Whether the part is in the jaws, so that the hold monitor watches it.
    pub fn holds_part(self) -> bool {
        matches!(self, Self::Lift | Self::Transport | Self::Place)
    }

    /// The longest this phase may wait for the world (the belt bringing something, a bottle
    /// clearing the beam); `None` for phases that end when their motion does.
    pub fn time_limit_s(self, task: &TaskSection) -> Option<f64> {
        match self {
            Self::Wait | Self::Pass => Some(task.wait_timeout_s),
            _ => None,
        }
    }
}

/// A phase that waits for the world, and when it must give up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhaseDeadline {
    phase: Phase,
    deadline_s: f64,
}

impl PhaseDeadline {
    /// `phase` starting at `now_s`; `None` when the phase has no time limit.
    pub fn start(phase: Phase, now_s: f64, task: &TaskSection) -> Option<Self> {
        Some(Self {
            phase,
            deadline_s: now_s + phase.time_limit_s(task)?,
        })
    }

    /// A time-out failure once `now_s` is past the deadline.
    pub fn check(&self, now_s: f64) -> Result<(), Failure> {
        if now_s <= self.deadline_s {
            return Ok(());
        }
        let detail = match self.phase {
            Phase::Pass => "a bottle stuck at the photo-eye",
            _ => "no part reached the photo-eye",
        };
        Err(Failure::new(FailureReason::Timeout, detail))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pick_cycle_follows_next_and_returns_to_waiting() {
        let mut phase = Phase::Wait;
        let mut seen = Vec::new();
        for _ in 0..Phase::PICK_CYCLE.len() {
            phase = phase.next();
            seen.push(phase);
        }
        assert_eq!(seen, Phase::PICK_CYCLE);
        assert_eq!(Phase::Retreat.next(), Phase::Wait);
        assert_eq!(Phase::Pass.next(), Phase::Wait);
    }

    #[test]
    fn each_phase_counts_its_own_seconds() {
        let mut seconds = PhaseSeconds::default();
        let all = [Phase::Wait, Phase::Pass]
            .into_iter()
            .chain(Phase::PICK_CYCLE);
        for (k, phase) in all.enumerate() {
            *phase.seconds_in(&mut seconds) += k as f64 + 1.0;
        }
        for (name, s) in seconds.named() {
            let phase = [Phase::Wait, Phase::Pass]
                .into_iter()
                .chain(Phase::PICK_CYCLE)
                .position(|p| p.as_str() == name)
                .expect("every named phase is a phase");
            assert_eq!(s, phase as f64 + 1.0, "{name}");
        }
    }

    #[test]
    fn only_the_carrying_phases_watch_the_hold() {
        let holding: Vec<Phase> = Phase::PICK_CYCLE
            .into_iter()
            .filter(|p| p.holds_part())
            .collect();
        assert_eq!(holding, [Phase::Lift, Phase::Transport, Phase::Place]);
    }

    #[test]
    fn names_are_distinct() {
        let mut names: Vec<&str> = Phase::PICK_CYCLE.iter().map(|p| p.as_str()).collect();
        names.extend([Phase::Wait.as_str(), Phase::Pass.as_str()]);
        let count = names.len();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), count);
    }

    #[test]
    fn waiting_phases_time_out_and_motions_do_not() {
        let task = TaskSection {
            wait_timeout_s: 2.5,
            ..TaskSection::default()
        };
        assert_eq!(Phase::Wait.time_limit_s(&task), Some(2.5));
        assert_eq!(Phase::Pass.time_limit_s(&task), Some(2.5));
        for phase in Phase::PICK_CYCLE {
            assert_eq!(phase.time_limit_s(&task), None, "{phase:?}");
            assert!(PhaseDeadline::start(phase, 1.0, &task).is_none());
        }
        let Some(wait) = PhaseDeadline::start(Phase::Wait, 10.0, &task) else {
            panic!("wait has a deadline");
        };
        assert_eq!(wait.check(12.5), Ok(()));
        let Err(late) = wait.check(12.51) else {
            panic!("no time-out past the deadline");
        };
        assert_eq!(late.reason, FailureReason::Timeout);
        assert_eq!(late.detail, "no part reached the photo-eye");
        let Some(pass) = PhaseDeadline::start(Phase::Pass, 0.0, &task) else {
            panic!("pass has a deadline");
        };
        let Err(stuck) = pass.check(3.0) else {
            panic!("no time-out past the deadline");
        };
        assert_eq!(stuck.detail, "a bottle stuck at the photo-eye");
    }
}
