//! Time-scaled quintic joint trajectories through waypoints, stopping at each.

use crate::kinematics::{ArmModel, DOF, JointVector};

/// Desired joint state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectorySample {
    /// Joint angles.
    pub q: JointVector,
    /// Joint rates.
    pub qd: JointVector,
    /// Joint accelerations.
    pub qdd: JointVector,
}

/// One rest-to-rest segment: `q(t) = start + (end - start) s(t / duration)` with the quintic
/// `s(u) = 10u^3 - 15u^4 + 6u^5` (zero velocity and acceleration at both ends).
#[derive(Debug, Clone, PartialEq)]
struct Segment {
    start: JointVector,
    end: JointVector,
    duration_s: f64,
}

/// Peak of `ds/du` for the quintic.
const QUINTIC_PEAK_VELOCITY: f64 = 1.875;
/// Peak of `|d2s/du2|` for the quintic: 10 / sqrt(3).
const QUINTIC_PEAK_ACCEL: f64 = 5.773_502_691_896_258;

/// A joint-space trajectory through waypoints, at rest at each, within velocity and
/// acceleration limits scaled by a speed fraction.
#[derive(Debug, Clone, PartialEq)]
pub struct JointTrajectory {
    segments: Vec<Segment>,
    total_s: f64,
}

impl JointTrajectory {
    /// The fastest synchronised quintic path through `waypoints` (the first is the start) with
    /// every joint within `speed_fraction` of its velocity and acceleration limits.
    pub fn through(arm: &ArmModel, waypoints: &[JointVector], speed_fraction: f64) -> Self {
        let fraction = speed_fraction.clamp(1e-3, 1.0);
        let mut segments = Vec::with_capacity(waypoints.len().saturating_sub(1));
        for pair in waypoints.windows(2) {
            let (start, end) = (pair[0], pair[1]);
            let mut duration_s: f64 = 0.0;
            for j in 0..DOF {
                let distance = (end[j] - start[j]).abs();
                let v_max = arm.limits[j].max_velocity_rad_s * fraction;
                let a_max = arm.limits[j].max_accel_rad_s2 * fraction;
                duration_s = duration_s
                    .max(QUINTIC_PEAK_VELOCITY * distance / v_max)
                    .max((QUINTIC_PEAK_ACCEL * distance / a_max).sqrt());
            }
            segments.push(Segment {
                start,
                end,
                duration_s,
            });
        }
        let total_s = segments.iter().map(|s| s.duration_s).sum();
        Self { segments, total_s }
    }

    /// Total duration.
    pub fn duration_s(&self) -> f64 {
        self.total_s
    }

    /// The final waypoint, if any segment exists.
    pub fn end(&self) -> Option<JointVector> {
        self.segments.last().map(|s| s.end)
    }

    /// The desired state at `t_s` seconds from the start (held at the ends).
    pub fn sample(&self, t_s: f64) -> Option<TrajectorySample> {
        let mut remaining = t_s.max(0.0);
        for (index, segment) in self.segments.iter().enumerate() {
            let last = index + 1 == self.segments.len();
            if remaining <= segment.duration_s || last {
                return Some(segment.sample(remaining));
            }
            remaining -= segment.duration_s;
        }
        None
    }
}

impl Segment {
    fn sample(&self, t_s: f64) -> TrajectorySample {
        if t_s >= self.duration_s {
            return TrajectorySample {
                q: self.end,
                qd: [0.0; DOF],
                qdd: [0.0; DOF],
            };
        }
        let u = (t_s / self.duration_s).clamp(0.0, 1.0);
        let (u2, u3) = (u * u, u * u * u);
        let s = u3 * (10.0 - 15.0 * u + 6.0 * u2);
        let ds = 30.0 * u2 * (1.0 - u) * (1.0 - u) / self.duration_s;
        let dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (self.duration_s * self.duration_s);
        let delta: JointVector = std::array::from_fn(|j| self.end[j] - self.start[j]);
        TrajectorySample {
            q: std::array::from_fn(|j| self.start[j] + delta[j] * s),
            qd: std::array::from_fn(|j| delta[j] * ds),
            qdd: std::array::from_fn(|j| delta[j] * dds),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn respects_limits_and_reaches_waypoints() {
        let arm = ArmModel::aubo_i5();
        let waypoints = [
            [0.0; DOF],
            [1.0, -0.5, 1.2, 0.3, -2.0, 2.5],
            [-1.5, 0.4, 0.2, -1.0, 1.0, 0.0],
        ];
        let trajectory = JointTrajectory::through(&arm, &waypoints, 0.5);
        let n = 20_000;
        let mut peak_v = [0.0f64; DOF];
        let mut peak_a = [0.0f64; DOF];
        for i in 0..=n {
            let t = trajectory.duration_s() * f64::from(i) / f64::from(n);
            let sample = trajectory.sample(t).expect("non-empty");
            for j in 0..DOF {
                peak_v[j] = peak_v[j].max(sample.qd[j].abs());
                peak_a[j] = peak_a[j].max(sample.qdd[j].abs());
            }
        }
        for j in 0..DOF {
            assert!(peak_v[j] <= 0.5 * arm.limits[j].max_velocity_rad_s + 1e-9);
            assert!(peak_a[j] <= 0.5 * arm.limits[j].max_accel_rad_s2 + 1e-6);
        }
        // The binding joint reaches its limit (the scaling is tight, not merely safe).
        let tight = (0..DOF).any(|j| {
            peak_v[j] > 0.49 * arm.limits[j].max_velocity_rad_s
                || peak_a[j] > 0.49 * arm.limits[j].max_accel_rad_s2
        });
        assert!(tight, "{peak_v:?} {peak_a:?}");
        let end = trajectory
            .sample(trajectory.duration_s() + 1.0)
            .expect("non-empty");
        assert_eq!(end.q, waypoints[2]);
        assert_eq!(end.qd, [0.0; DOF]);
    }
}
