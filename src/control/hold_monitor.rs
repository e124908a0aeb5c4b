//! Watches a held part: it must stay where it was in the TCP frame when the jaws closed.

use nalgebra::Isometry3;

use crate::outcome::{Failure, FailureReason, Phase, fail};

/// A drift beyond this, or a part this far from the TCP, is a drop rather than a slip, m.
const DROP_DRIFT_M: f64 = 0.05;
/// A part this far from the TCP has left the jaws, m.
const DROP_DISTANCE_M: f64 = 0.2;

/// The part's pose in the TCP frame when the grasp closed, and how far it may drift.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoldMonitor {
    /// The part's pose in the TCP frame at the grasp.
    pub tcp_from_part: Isometry3<f64>,
    /// Largest drift that is still a hold, m.
    pub slip_tolerance_m: f64,
}

impl HoldMonitor {
    /// How far the part at `now` (its pose in the TCP frame) has moved from where the jaws
    /// closed on it, m.
    pub fn drift_m(&self, now: &Isometry3<f64>) -> f64 {
        (now.translation.vector - self.tcp_from_part.translation.vector).norm()
    }

    /// Checks the part's pose in the TCP frame `now` during `phase`: a slip or a drop is a
    /// failure with the drift in its detail.
    pub fn check(&self, phase: Phase, now: &Isometry3<f64>) -> Result<(), Failure> {
        let drift = self.drift_m(now);
        if drift <= self.slip_tolerance_m {
            return Ok(());
        }
        let distance = now.translation.vector.norm();
        if drift > DROP_DRIFT_M || distance > DROP_DISTANCE_M {
            fail(
                FailureReason::Dropped,
                format!("part fell from the fingers ({:.0} mm away)", drift * 1e3),
            )
        } else {
            fail(
                FailureReason::Slipped,
                format!(
                    "part slid {:.1} mm in the fingers during {phase}",
                    drift * 1e3
                ),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn monitor() -> HoldMonitor {
        HoldMonitor {
            tcp_from_part: Isometry3::translation(0.0, 0.0, -0.02),
            slip_tolerance_m: 0.025,
        }
    }

    #[test]
    fn a_part_within_the_tolerance_is_held() {
        let now = Isometry3::translation(0.0, 0.01, -0.03);
        assert_eq!(monitor().check(Phase::Lift, &now), Ok(()));
    }

    #[test]
    fn a_drift_past_the_tolerance_is_a_slip_and_a_large_one_a_drop() {
        let Err(slip) = monitor().check(Phase::Transport, &Isometry3::translation(0.0, 0.0, -0.05))
        else {
            panic!("a 30 mm drift passed");
        };
        assert_eq!(slip.reason, FailureReason::Slipped);
        assert!(slip.detail.contains("30.0 mm") && slip.detail.contains("transport"));
        let Err(drop) = monitor().check(Phase::Transport, &Isometry3::translation(0.0, 0.0, -0.09))
        else {
            panic!("a 70 mm drift passed");
        };
        assert_eq!(drop.reason, FailureReason::Dropped);
    }
}
