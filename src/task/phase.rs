//! Which phases of a trial end by a time-out rather than by a trajectory's end.

use crate::outcome::{Failure, FailureReason, Phase};
use crate::scenario::TaskSection;

/// The longest `phase` may wait for the world (the belt bringing something, a bottle clearing
/// the beam); `None` for phases that end when their motion does.
pub fn time_limit_s(phase: Phase, task: &TaskSection) -> Option<f64> {
    match phase {
        Phase::Wait | Phase::Pass => Some(task.wait_timeout_s),
        _ => None,
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
            deadline_s: now_s + time_limit_s(phase, task)?,
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
    fn waiting_phases_time_out_and_motions_do_not() {
        let task = TaskSection {
            wait_timeout_s: 2.5,
            ..TaskSection::default()
        };
        assert_eq!(time_limit_s(Phase::Wait, &task), Some(2.5));
        assert_eq!(time_limit_s(Phase::Pass, &task), Some(2.5));
        for phase in Phase::PICK_CYCLE {
            assert_eq!(time_limit_s(phase, &task), None, "{phase:?}");
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
