//! A path parameter timed under a rate limit that varies along the path: the time-optimal
//! rest-to-rest profile on a grid of the path (the forward and backward passes of numerical
//! time-optimal path parameterization, with constant bounds on the parameter's acceleration and
//! deceleration). Between grid nodes the squared rate is linear in the parameter, so the
//! parameter's acceleration is constant within a cell and within the bounds.
//!
//! What it is for: a carry capped by the tool's speed. A joint-space move's tool speed varies
//! along the path (the arm reaches out and tucks in), and a trapezoidal profile capped at the
//! path's peak crawls where the tool is slow; this profile runs each stretch as fast as the tool
//! cap and the joints allow.

use super::ScalingSample;

/// A profile of the path parameter from 0 to 1 under a rate limit per grid node.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RateTable {
    /// The rate limit at each node (node `i` at `i / n`), 1/s.
    limit: Vec<f64>,
    accel: f64,
    decel: f64,
    /// The rate at each node, 1/s.
    rate: Vec<f64>,
    /// The time at each node, s.
    time: Vec<f64>,
}

impl RateTable {
    /// The fastest profile under `limit` (one rate limit per node, at least three nodes) and
    /// the acceleration and deceleration limits (1/s^2), at rest at both ends.
    pub(super) fn new(limit: Vec<f64>, accel: f64, decel: f64) -> Self {
        let mut limit = limit;
        while limit.len() < 3 {
            limit.push(limit.last().copied().unwrap_or(1.0));
        }
        for l in &mut limit {
            *l = l.max(1e-9);
        }
        let (accel, decel) = (accel.max(1e-9), decel.max(1e-9));
        let n = limit.len() - 1;
        let ds = 1.0 / n as f64;
        let mut rate = vec![0.0; n + 1];
        for i in 0..n {
            rate[i + 1] = limit[i + 1].min((rate[i] * rate[i] + 2.0 * accel * ds).sqrt());
        }
        rate[n] = 0.0;
        for i in (0..n).rev() {
            rate[i] = rate[i].min((rate[i + 1] * rate[i + 1] + 2.0 * decel * ds).sqrt());
        }
        rate[0] = 0.0;
        let mut time = vec![0.0; n + 1];
        for i in 0..n {
            time[i + 1] = time[i] + 2.0 * ds / (rate[i] + rate[i + 1]).max(1e-12);
        }
        Self {
            limit,
            accel,
            decel,
            rate,
            time,
        }
    }

    fn cells(&self) -> usize {
        self.rate.len() - 1
    }

    /// The parameter's acceleration in cell `i`, 1/s^2.
    fn cell_accel(&self, i: usize) -> f64 {
        let ds = 1.0 / self.cells() as f64;
        (self.rate[i + 1] * self.rate[i + 1] - self.rate[i] * self.rate[i]) / (2.0 * ds)
    }

    /// Total duration, s.
    pub(super) fn duration_s(&self) -> f64 {
        self.time[self.cells()]
    }

    /// Time from the start while the rate only rises, s.
    pub(super) fn accel_s(&self) -> f64 {
        let tiny = 1e-9 * self.accel;
        let end = (0..self.cells())
            .find(|&i| self.cell_accel(i) <= tiny)
            .unwrap_or(self.cells());
        self.time[end]
    }

    /// Time before the end while the rate only falls, s.
    pub(super) fn decel_s(&self) -> f64 {
        let tiny = 1e-9 * self.decel;
        let start = (0..self.cells())
            .rev()
            .find(|&i| self.cell_accel(i) >= -tiny)
            .map_or(0, |i| i + 1);
        self.duration_s() - self.time[start]
    }

    /// The same path `factor` times slower throughout.
    pub(super) fn stretched(&self, factor: f64) -> Self {
        let k = factor.max(1e-9);
        Self::new(
            self.limit.iter().map(|l| l / k).collect(),
            self.accel / (k * k),
            self.decel / (k * k),
        )
    }

    /// The profile with its acceleration and deceleration limits multiplied by the factors.
    pub(super) fn with_ramps(&self, accel_factor: f64, decel_factor: f64) -> Self {
        Self::new(
            self.limit.clone(),
            self.accel * accel_factor,
            self.decel * decel_factor,
        )
    }

    /// The path parameter at `t_s` (held at 0 before the start and at 1 after the end).
    pub(super) fn sample(&self, t_s: f64) -> ScalingSample {
        let rest = |s| ScalingSample {
            s,
            rate: 0.0,
            accel: 0.0,
        };
        if t_s <= 0.0 {
            return rest(0.0);
        }
        if t_s >= self.duration_s() {
            return rest(1.0);
        }
        let n = self.cells();
        let i = (self.time.partition_point(|&t| t <= t_s) - 1).min(n - 1);
        let tau = t_s - self.time[i];
        let accel = self.cell_accel(i);
        let ds = 1.0 / n as f64;
        let s = i as f64 * ds + self.rate[i] * tau + 0.5 * accel * tau * tau;
        ScalingSample {
            s: s.clamp(i as f64 * ds, (i + 1) as f64 * ds),
            rate: (self.rate[i] + accel * tau).max(0.0),
            accel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::TimeScaling;
    use crate::rng::SimRng;

    #[test]
    fn drawn_limits_are_kept_and_the_path_is_covered_continuously() {
        let mut rng = SimRng::new(26);
        for _ in 0..200 {
            let n = 3 + (rng.next_u64() % 200) as usize;
            let limit: Vec<f64> = (0..=n).map(|_| rng.range(0.05, 5.0)).collect();
            let (accel, decel) = (rng.range(0.1, 50.0), rng.range(0.1, 50.0));
            let table = RateTable::new(limit.clone(), accel, decel);
            let total = table.duration_s();
            assert!(total.is_finite() && total > 0.0);
            let steps = 5000;
            let dt = total / f64::from(steps);
            let mut previous = table.sample(0.0);
            for k in 1..=steps {
                let now = table.sample(dt * f64::from(k));
                assert!(now.accel <= accel * (1.0 + 1e-9) && -now.accel <= decel * (1.0 + 1e-9));
                assert!(now.s >= previous.s - 1e-12, "the path runs backwards");
                let jump = (now.rate - previous.rate).abs();
                assert!(jump <= accel.max(decel) * dt * (1.0 + 1e-6) + 1e-9);
                let mean = 0.5 * (now.rate + previous.rate);
                assert!(
                    (now.s - previous.s - mean * dt).abs() <= accel.max(decel) * dt * dt + 1e-9
                );
                // The rate keeps to the limit at the nodes on either side.
                let cell = ((now.s * n as f64).floor() as usize).min(n - 1);
                let bound = limit[cell].max(limit[cell + 1]);
                assert!(now.rate <= bound * (1.0 + 1e-9), "{now:?} over {bound}");
                previous = now;
            }
            let end = table.sample(total);
            assert_eq!((end.s, end.rate), (1.0, 0.0));
            let (a, d) = (table.accel_s(), table.decel_s());
            assert!(a > 0.0 && d > 0.0 && a <= total && d <= total);
        }
    }

    #[test]
    fn a_flat_limit_gives_the_trapezoid_and_a_higher_limit_is_never_slower() {
        let mut rng = SimRng::new(5);
        for _ in 0..100 {
            let (rate, accel, decel) = (
                rng.range(0.1, 5.0),
                rng.range(0.5, 50.0),
                rng.range(0.5, 50.0),
            );
            let table = RateTable::new(vec![rate; 2001], accel, decel);
            let trapezoid = TimeScaling::new(rate, accel, decel);
            let (a, b) = (table.duration_s(), trapezoid.duration_s());
            assert!((a - b).abs() <= 0.01 * b, "table {a} trapezoid {b}");
            // Raising the limit over part of the path never makes the profile slower.
            let mut raised = vec![rate; 2001];
            let from = (rng.next_u64() % 2000) as usize;
            for l in &mut raised[from..] {
                *l *= 2.0;
            }
            let faster = RateTable::new(raised, accel, decel).duration_s();
            assert!(faster <= a * (1.0 + 1e-12));
        }
    }
}
