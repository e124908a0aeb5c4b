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

/// One rest-to-rest segment along a joint-space polyline `path` (two points for a plain joint
/// move, many for a straight tool line), timed by the quintic `s(u) = 10u^3 - 15u^4 + 6u^5`
/// over the path parameter: zero velocity and acceleration at both ends.
#[derive(Debug, Clone, PartialEq)]
struct Segment {
    path: Vec<JointVector>,
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
        let segments = waypoints
            .windows(2)
            .map(|pair| Segment::timed(arm, vec![pair[0], pair[1]], speed_fraction))
            .collect();
        Self::from_segments(segments)
    }

    /// One rest-to-rest motion along a dense joint-space polyline (e.g. IK solutions along a
    /// straight tool line), passed through without stopping.
    pub fn along(arm: &ArmModel, path: Vec<JointVector>, speed_fraction: f64) -> Self {
        Self::from_segments(vec![Segment::timed(arm, path, speed_fraction)])
    }

    /// This trajectory followed by `next`.
    pub fn then(mut self, next: JointTrajectory) -> Self {
        self.segments.extend(next.segments);
        self.total_s = self.segments.iter().map(|s| s.duration_s).sum();
        self
    }

    fn from_segments(segments: Vec<Segment>) -> Self {
        let total_s = segments.iter().map(|s| s.duration_s).sum();
        Self { segments, total_s }
    }

    /// Total duration.
    pub fn duration_s(&self) -> f64 {
        self.total_s
    }

    /// The final waypoint, if any segment exists.
    pub fn end(&self) -> Option<JointVector> {
        self.segments.last().and_then(|s| s.path.last().copied())
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
    /// A segment along `path` as fast as the limits allow. Along the path `dq/ds` is piecewise
    /// constant, `(n - 1) * delta` on each piece, so the quintic's peaks bound every joint.
    fn timed(arm: &ArmModel, path: Vec<JointVector>, speed_fraction: f64) -> Self {
        let fraction = speed_fraction.clamp(1e-3, 1.0);
        let pieces = path.len().saturating_sub(1).max(1) as f64;
        let mut duration_s: f64 = 0.0;
        for pair in path.windows(2) {
            for (limit, (to, from)) in arm.limits.iter().zip(pair[1].iter().zip(&pair[0])) {
                let rate = pieces * (to - from).abs();
                let v_max = limit.max_velocity_rad_s * fraction;
                let a_max = limit.max_accel_rad_s2 * fraction;
                duration_s = duration_s
                    .max(QUINTIC_PEAK_VELOCITY * rate / v_max)
                    .max((QUINTIC_PEAK_ACCEL * rate / a_max).sqrt());
            }
        }
        Self { path, duration_s }
    }

    fn sample(&self, t_s: f64) -> TrajectorySample {
        let last = *self.path.last().unwrap_or(&[0.0; DOF]);
        if t_s >= self.duration_s || self.path.len() < 2 {
            return TrajectorySample {
                q: last,
                qd: [0.0; DOF],
                qdd: [0.0; DOF],
            };
        }
        let u = (t_s / self.duration_s).clamp(0.0, 1.0);
        let (u2, u3) = (u * u, u * u * u);
        let s = u3 * (10.0 - 15.0 * u + 6.0 * u2);
        let ds = 30.0 * u2 * (1.0 - u) * (1.0 - u) / self.duration_s;
        let dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (self.duration_s * self.duration_s);
        let pieces = self.path.len() - 1;
        let position = s * pieces as f64;
        let index = (position.floor() as usize).min(pieces - 1);
        let fraction = position - index as f64;
        let (a, b) = (self.path[index], self.path[index + 1]);
        let dq_ds: JointVector = std::array::from_fn(|j| (b[j] - a[j]) * pieces as f64);
        TrajectorySample {
            q: std::array::from_fn(|j| a[j] + (b[j] - a[j]) * fraction),
            qd: std::array::from_fn(|j| dq_ds[j] * ds),
            qdd: std::array::from_fn(|j| dq_ds[j] * dds),
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
