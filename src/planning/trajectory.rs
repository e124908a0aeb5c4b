//! Time-optimal joint trajectories: each segment follows a joint-space polyline under a
//! trapezoidal time scaling at the arm's full velocity and acceleration limits; consecutive
//! segments may blend (the next starts while the previous one slows down) instead of stopping.
//!
//! No jerk limit is applied: none is published for the AUBO i5 (its MoveIt `joint_limits.yaml`
//! gives velocity and acceleration only), so accelerations switch between their limits.

use super::time_scaling::{ScalingSample, TimeScaling};
use crate::kinematics::{ArmModel, DOF, JointVector, tcp_pose};
use rate::RateTable;

#[path = "trajectory_rate.rs"]
mod rate;

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

/// Limits on the tool centre point's motion, on top of the joints' own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolLimits {
    /// Largest TCP speed, m/s.
    pub speed_m_s: f64,
    /// Largest TCP acceleration, m/s^2.
    pub accel_m_s2: f64,
}

/// One rest-to-rest motion along a joint-space polyline `path` (two points for a plain joint
/// move, many for a straight tool line), the path parameter timed by `scaling` from `start_s`.
#[derive(Debug, Clone, PartialEq)]
struct Segment {
    path: Vec<JointVector>,
    scaling: Profile,
    start_s: f64,
}

/// How a segment's path parameter is timed.
#[derive(Debug, Clone, PartialEq)]
enum Profile {
    /// Under one rate limit for the whole path.
    Trapezoid(TimeScaling),
    /// Under a rate limit that varies along the path.
    Table(RateTable),
}

impl Profile {
    fn duration_s(&self) -> f64 {
        match self {
            Self::Trapezoid(p) => p.duration_s(),
            Self::Table(p) => p.duration_s(),
        }
    }

    fn accel_s(&self) -> f64 {
        match self {
            Self::Trapezoid(p) => p.accel_s(),
            Self::Table(p) => p.accel_s(),
        }
    }

    fn decel_s(&self) -> f64 {
        match self {
            Self::Trapezoid(p) => p.decel_s(),
            Self::Table(p) => p.decel_s(),
        }
    }

    fn sample(&self, t_s: f64) -> ScalingSample {
        match self {
            Self::Trapezoid(p) => p.sample(t_s),
            Self::Table(p) => p.sample(t_s),
        }
    }

    fn stretched(&self, factor: f64) -> Self {
        match self {
            Self::Trapezoid(p) => Self::Trapezoid(p.stretched(factor)),
            Self::Table(p) => Self::Table(p.stretched(factor)),
        }
    }

    fn with_ramps(&self, accel_factor: f64, decel_factor: f64) -> Self {
        match self {
            Self::Trapezoid(p) => Self::Trapezoid(p.with_ramps(accel_factor, decel_factor)),
            Self::Table(p) => Self::Table(p.with_ramps(accel_factor, decel_factor)),
        }
    }
}

/// A joint-space trajectory: segments that play one after the other, overlapping where blended.
#[derive(Debug, Clone, PartialEq)]
pub struct JointTrajectory {
    segments: Vec<Segment>,
    /// Start time of each part joined by [`JointTrajectory::join`], the first at 0.
    part_starts_s: Vec<f64>,
    /// End time of each joined part.
    part_ends_s: Vec<f64>,
}

/// Time within which a segment counts as finished, s: laying segments out end to end sums
/// durations, and the rounding must not leave a segment a hair short of its end point.
const END_TOLERANCE_S: f64 = 1e-9;

/// Cells of the grid on which [`JointTrajectory::along_tool_speed`] times its path.
const RATE_NODES: usize = 200;

/// The tool speed a varying-rate profile aims under its cap, as the cap over this: the speed
/// between the grid's nodes and the sampled check's peaks may differ a little.
const TOOL_SPEED_MARGIN: f64 = 1.02;

/// Sampling interval of the TCP check in [`JointTrajectory::within_tool_limits`], s.
const TOOL_CHECK_DT_S: f64 = 0.004;

impl JointTrajectory {
    /// The fastest trajectory through `waypoints` (the first is the start), at rest at each,
    /// every joint within `speed_fraction` of its velocity and acceleration limits.
    pub fn through(arm: &ArmModel, waypoints: &[JointVector], speed_fraction: f64) -> Self {
        let parts = waypoints
            .windows(2)
            .map(|pair| Self::along(arm, vec![pair[0], pair[1]], speed_fraction))
            .collect();
        Self::join(parts, false)
    }

    /// One rest-to-rest motion along a dense joint-space polyline (e.g. IK solutions along a
    /// straight tool line), passed through without stopping.
    pub fn along(arm: &ArmModel, path: Vec<JointVector>, speed_fraction: f64) -> Self {
        let fraction = speed_fraction.clamp(1e-3, 1.0);
        // Along piece i of n, dq/ds is n * (path[i+1] - path[i]): the binding joint and piece
        // bound the path parameter's rate and acceleration.
        let pieces = path.len().saturating_sub(1).max(1) as f64;
        let (mut max_rate, mut max_accel) = (f64::INFINITY, f64::INFINITY);
        for pair in path.windows(2) {
            for (limit, (to, from)) in arm.limits.iter().zip(pair[1].iter().zip(&pair[0])) {
                let dq_ds = pieces * (to - from).abs();
                if dq_ds > 0.0 {
                    max_rate = max_rate.min(limit.max_velocity_rad_s * fraction / dq_ds);
                    max_accel = max_accel.min(limit.max_accel_rad_s2 * fraction / dq_ds);
                }
            }
        }
        let scaling = if max_rate.is_finite() {
            TimeScaling::new(max_rate, max_accel, max_accel)
        } else {
            // Nothing moves: a zero-length segment.
            TimeScaling::new(1e9, 1e18, 1e18)
        };
        let duration_s = scaling.duration_s();
        Self {
            segments: vec![Segment {
                path,
                scaling: Profile::Trapezoid(scaling),
                start_s: 0.0,
            }],
            part_starts_s: vec![0.0],
            part_ends_s: vec![duration_s],
        }
    }

    /// One rest-to-rest motion along `path` (a joint-space polyline), as [`Self::along`], with
    /// the tool centre point's speed at most `limits.speed_m_s` at every point of the path: the
    /// rate varies along the path (fast where the tool moves little for the joints' motion,
    /// slow where it swings out), time-optimal on a grid of 200 cells under the
    /// joints' velocity limits, that tool speed and the joints' acceleration limits; then
    /// slowed down uniformly if the measured tool motion still breaks `limits` (the tool's
    /// acceleration, or the speed between the grid's nodes).
    pub fn along_tool_speed(
        arm: &ArmModel,
        path: Vec<JointVector>,
        speed_fraction: f64,
        limits: &ToolLimits,
    ) -> Self {
        let plain = Self::along(arm, path.clone(), speed_fraction);
        let Profile::Trapezoid(trapezoid) = plain.segments[0].scaling else {
            return plain;
        };
        if path.len() < 2 || trapezoid.max_rate >= 1e8 {
            return plain;
        }
        let at = |s: f64| {
            let pieces = path.len() - 1;
            let position = s.clamp(0.0, 1.0) * pieces as f64;
            let index = (position.floor() as usize).min(pieces - 1);
            let fraction = position - index as f64;
            let (a, b) = (path[index], path[index + 1]);
            let q: JointVector = std::array::from_fn(|j| a[j] + (b[j] - a[j]) * fraction);
            tcp_pose(arm, &q).translation.vector
        };
        let n = RATE_NODES;
        let ds = 1.0 / n as f64;
        let tcp: Vec<_> = (0..=n).map(|i| at(i as f64 * ds)).collect();
        // The tool's path length per unit of the parameter at each node (central differences).
        let cap = limits.speed_m_s / TOOL_SPEED_MARGIN;
        let bound: Vec<f64> = (0..=n)
            .map(|i| {
                let (lo, hi) = (i.saturating_sub(1), (i + 1).min(n));
                let dp_ds = (tcp[hi] - tcp[lo]).norm() / ((hi - lo) as f64 * ds);
                let tool = if dp_ds > 0.0 {
                    cap / dp_ds
                } else {
                    f64::INFINITY
                };
                trapezoid.max_rate.min(tool)
            })
            .collect();
        // Each node keeps to its neighbours' bounds too: the tool speed between two nodes.
        let limit: Vec<f64> = (0..=n)
            .map(|i| {
                bound[i.saturating_sub(1)..=(i + 1).min(n)]
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        let table = RateTable::new(limit, trapezoid.accel, trapezoid.decel);
        let duration_s = table.duration_s();
        Self {
            segments: vec![Segment {
                path,
                scaling: Profile::Table(table),
                start_s: 0.0,
            }],
            part_starts_s: vec![0.0],
            part_ends_s: vec![duration_s],
        }
        .within_tool_limits(arm, limits)
    }

    /// `parts` one after the other, each starting where the previous one ends. `blended`
    /// starts each part while the previous one is still slowing down: the previous part's
    /// deceleration and the next one's acceleration are halved and overlap for as long as both
    /// last, so the summed motion stays within every joint's velocity and acceleration limits
    /// and its velocity is continuous, while the arm no longer stops at the junction (it cuts
    /// the corner there; check the blended trajectory, not its parts).
    pub fn join(parts: Vec<JointTrajectory>, blended: bool) -> Self {
        let part_count = parts.len();
        let mut segments: Vec<Segment> = Vec::new();
        let mut part_starts_s = Vec::with_capacity(part_count);
        let mut part_ends_s = Vec::with_capacity(part_count);
        let mut end_s: f64 = 0.0;
        for (index, part) in parts.into_iter().enumerate() {
            let mut part_segments = part.segments;
            let count = part_segments.len();
            // A part keeps its own inner timing; only the ramps at its junctions change, and a
            // longer first ramp delays the rest of the part by as much.
            let mut shift_s = 0.0;
            let mut overlap_s = 0.0;
            for (k, segment) in part_segments.iter_mut().enumerate() {
                if blended {
                    let accel = if k == 0 && index > 0 { 0.5 } else { 1.0 };
                    let decel = if k + 1 == count && index + 1 < part_count {
                        0.5
                    } else {
                        1.0
                    };
                    let before_s = segment.scaling.duration_s();
                    segment.scaling = segment.scaling.with_ramps(accel, decel);
                    if k == 0 {
                        shift_s = segment.scaling.duration_s() - before_s;
                        if let Some(previous) = segments.last() {
                            overlap_s = previous.scaling.decel_s().min(segment.scaling.accel_s());
                        }
                    }
                }
            }
            let offset_s = (end_s - overlap_s).max(0.0);
            part_starts_s.push(offset_s);
            for (k, mut segment) in part_segments.into_iter().enumerate() {
                segment.start_s += offset_s + if k > 0 { shift_s } else { 0.0 };
                end_s = end_s.max(segment.start_s + segment.scaling.duration_s());
                segments.push(segment);
            }
            part_ends_s.push(end_s);
        }
        if part_starts_s.is_empty() {
            part_starts_s.push(0.0);
            part_ends_s.push(0.0);
        }
        Self {
            segments,
            part_starts_s,
            part_ends_s,
        }
    }

    /// This trajectory followed by `next`, stopping between them.
    pub fn then(self, next: JointTrajectory) -> Self {
        Self::join(vec![self, next], false)
    }

    /// The same path played `factor` times slower (rates divide by it, accelerations by its
    /// square).
    pub fn stretched(mut self, factor: f64) -> Self {
        let k = factor.max(1.0);
        for segment in &mut self.segments {
            segment.scaling = segment.scaling.stretched(k);
            segment.start_s *= k;
        }
        for time in self.part_starts_s.iter_mut().chain(&mut self.part_ends_s) {
            *time *= k;
        }
        self
    }

    /// The same path slowed down just enough that the TCP of `arm` stays within `limits`
    /// (measured along the trajectory by forward kinematics).
    pub fn within_tool_limits(self, arm: &ArmModel, limits: &ToolLimits) -> Self {
        let peaks = self.peak_tool_motion(arm);
        self.within_peaks(peaks, limits)
    }

    /// [`Self::within_tool_limits`] for a trajectory whose peak TCP speed and acceleration
    /// (`peak_tool_motion`) are `(speed, accel)`.
    fn within_peaks(self, (speed, accel): (f64, f64), limits: &ToolLimits) -> Self {
        let factor = (speed / limits.speed_m_s.max(1e-9))
            .max((accel / limits.accel_m_s2.max(1e-9)).sqrt())
            .max(1.0);
        // Stretch a hair beyond the measured ratio: the sampled peaks may miss the true ones.
        if factor > 1.0 {
            self.stretched(factor * 1.02)
        } else {
            self
        }
    }

    /// The same path with the TCP's speed capped by lowering the cruise rates alone (the ramps
    /// keep their acceleration, so a speed cap costs less time than a uniform slow-down), then
    /// slowed down uniformly if the TCP still breaks `limits`. For a trajectory without blends;
    /// one with blends is only slowed down uniformly.
    pub fn with_tool_limits(self, arm: &ArmModel, limits: &ToolLimits) -> Self {
        let peaks = self.peak_tool_motion(arm);
        let speed = peaks.0;
        let blended = self
            .segments
            .windows(2)
            .any(|w| w[1].start_s + END_TOLERANCE_S < w[0].start_s + w[0].scaling.duration_s());
        if speed <= limits.speed_m_s || blended {
            return self.within_peaks(peaks, limits);
        }
        // The TCP's speed is linear in the joint rates at each point of the path.
        let factor = limits.speed_m_s / speed / 1.02;
        let mut slowed = self;
        let mut end_s = 0.0;
        let mut part = 0;
        for segment in &mut slowed.segments {
            if let Profile::Trapezoid(s) = &segment.scaling {
                let s = *s;
                segment.scaling =
                    Profile::Trapezoid(TimeScaling::new(s.max_rate * factor, s.accel, s.decel));
            }
            if part < slowed.part_starts_s.len()
                && (segment.start_s - slowed.part_starts_s[part]).abs() <= END_TOLERANCE_S
            {
                slowed.part_starts_s[part] = end_s;
                part += 1;
            }
            segment.start_s = end_s;
            end_s += segment.scaling.duration_s();
            if part > 0 && part <= slowed.part_ends_s.len() {
                slowed.part_ends_s[part - 1] = end_s;
            }
        }
        slowed.within_tool_limits(arm, limits)
    }

    /// Peak TCP speed (m/s) and acceleration (m/s^2) along the trajectory, by finite
    /// differences of forward kinematics.
    pub fn peak_tool_motion(&self, arm: &ArmModel) -> (f64, f64) {
        let dt = TOOL_CHECK_DT_S;
        let steps = (self.duration_s() / dt).ceil() as usize + 2;
        let position = |i: usize| {
            let t = i as f64 * dt - dt;
            self.sample(t)
                .map(|s| tcp_pose(arm, &s.q).translation.vector)
                .unwrap_or_default()
        };
        let (mut speed, mut accel) = (0.0f64, 0.0f64);
        let (mut a, mut b) = (position(0), position(1));
        for i in 2..=steps {
            let c = position(i);
            speed = speed.max((c - a).norm() / (2.0 * dt));
            accel = accel.max((c - 2.0 * b + a).norm() / (dt * dt));
            (a, b) = (b, c);
        }
        (speed, accel)
    }

    /// Total duration.
    pub fn duration_s(&self) -> f64 {
        self.segments
            .iter()
            .map(|s| s.start_s + s.scaling.duration_s())
            .fold(0.0, f64::max)
    }

    /// When each joined part starts, s from the start (the first at 0).
    pub fn part_starts_s(&self) -> &[f64] {
        &self.part_starts_s
    }

    /// When each joined part ends, s from the start.
    pub fn part_ends_s(&self) -> &[f64] {
        &self.part_ends_s
    }

    /// The first waypoint, if any segment exists.
    pub fn start(&self) -> Option<JointVector> {
        self.segments.first().and_then(|s| s.path.first().copied())
    }

    /// The final waypoint, if any segment exists.
    pub fn end(&self) -> Option<JointVector> {
        self.segments.last().and_then(|s| s.path.last().copied())
    }

    /// The desired state at `t_s` seconds from the start (held at the ends): the segment that
    /// started last, plus what earlier segments still running have left to go (blends add up).
    /// At rest points the state is exactly the waypoint.
    pub fn sample(&self, t_s: f64) -> Option<TrajectorySample> {
        let current = self
            .segments
            .iter()
            .rposition(|s| s.start_s <= t_s)
            .unwrap_or(0);
        let segment = self.segments.get(current)?;
        let mut sample = segment.state(t_s - segment.start_s)?;
        for earlier in &self.segments[..current] {
            earlier.add_remaining(t_s - earlier.start_s, &mut sample);
        }
        Some(sample)
    }
}

impl Segment {
    /// Where along its path the segment is at `t_s` from its own start: the path point, the
    /// rates, and the accelerations (the end point exactly once finished).
    fn state(&self, t_s: f64) -> Option<TrajectorySample> {
        let first = *self.path.first()?;
        let last = *self.path.last()?;
        let rest = |q| TrajectorySample {
            q,
            qd: [0.0; DOF],
            qdd: [0.0; DOF],
        };
        let pieces = self.path.len() - 1;
        if t_s <= 0.0 {
            return Some(rest(first));
        }
        if pieces == 0 || t_s >= self.scaling.duration_s() - END_TOLERANCE_S {
            return Some(rest(last));
        }
        let at = self.scaling.sample(t_s);
        let position = at.s * pieces as f64;
        let index = (position.floor() as usize).min(pieces - 1);
        let fraction = position - index as f64;
        let (a, b) = (self.path[index], self.path[index + 1]);
        let dq_ds: JointVector = std::array::from_fn(|j| (b[j] - a[j]) * pieces as f64);
        Some(TrajectorySample {
            q: std::array::from_fn(|j| a[j] + (b[j] - a[j]) * fraction),
            qd: std::array::from_fn(|j| dq_ds[j] * at.rate),
            qdd: std::array::from_fn(|j| dq_ds[j] * at.accel),
        })
    }

    /// Adds what this segment has still to go at `t_s` from its start (its state less its end
    /// point, with its rates), when it is running then.
    fn add_remaining(&self, t_s: f64, sample: &mut TrajectorySample) {
        if t_s <= 0.0 || t_s >= self.scaling.duration_s() - END_TOLERANCE_S {
            return;
        }
        let (Some(state), Some(last)) = (self.state(t_s), self.path.last()) else {
            return;
        };
        for (j, end) in last.iter().enumerate() {
            sample.q[j] += state.q[j] - end;
            sample.qd[j] += state.qd[j];
            sample.qdd[j] += state.qdd[j];
        }
    }
}

#[cfg(test)]
#[path = "trajectory_tests.rs"]
mod tests;
