//! Trapezoidal time scaling of a path parameter from 0 to 1: the fastest rest-to-rest motion
//! under a speed limit and separate acceleration and deceleration limits.

/// `s(t)` rising from 0 to 1 at rest at both ends: constant acceleration, cruise at the speed
/// limit (when the path is long enough to reach it), constant deceleration. With a bound on
/// `|ds/dt|` and on `|d2s/dt2|` this is the time-optimal rest-to-rest profile (bang-coast-bang).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeScaling {
    /// Speed limit, 1/s.
    pub max_rate: f64,
    /// Acceleration limit while speeding up, 1/s^2.
    pub accel: f64,
    /// Deceleration limit while slowing down, 1/s^2.
    pub decel: f64,
    /// Peak speed reached, 1/s.
    peak_rate: f64,
    accel_s: f64,
    cruise_s: f64,
    decel_s: f64,
}

/// Position, rate and acceleration of the path parameter at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalingSample {
    /// Path parameter, 0 to 1.
    pub s: f64,
    /// `ds/dt`.
    pub rate: f64,
    /// `d2s/dt2`.
    pub accel: f64,
}

impl TimeScaling {
    /// The fastest profile under `max_rate`, `accel` and `decel` (each clamped to a tiny
    /// positive value so that a degenerate limit gives a slow motion, not a division by zero).
    pub fn new(max_rate: f64, accel: f64, decel: f64) -> Self {
        let (max_rate, accel, decel) = (max_rate.max(1e-9), accel.max(1e-9), decel.max(1e-9));
        // Distance to reach max_rate and stop again.
        let ramps = max_rate * max_rate * (0.5 / accel + 0.5 / decel);
        let peak_rate = if ramps <= 1.0 {
            max_rate
        } else {
            (2.0 / (1.0 / accel + 1.0 / decel)).sqrt()
        };
        let accel_s = peak_rate / accel;
        let decel_s = peak_rate / decel;
        let covered = 0.5 * peak_rate * (accel_s + decel_s);
        let cruise_s = ((1.0 - covered) / peak_rate).max(0.0);
        Self {
            max_rate,
            accel,
            decel,
            peak_rate,
            accel_s,
            cruise_s,
            decel_s,
        }
    }

    /// Total duration, s.
    pub fn duration_s(&self) -> f64 {
        self.accel_s + self.cruise_s + self.decel_s
    }

    /// Time spent speeding up, s.
    pub fn accel_s(&self) -> f64 {
        self.accel_s
    }

    /// Time spent slowing down, s.
    pub fn decel_s(&self) -> f64 {
        self.decel_s
    }

    /// The same profile slowed down by `factor` (> 1 is slower): every instant of the path is
    /// reached `factor` times later, rates divide by `factor` and accelerations by its square.
    pub fn stretched(&self, factor: f64) -> Self {
        let k = factor.max(1e-9);
        Self::new(
            self.max_rate / k,
            self.accel / (k * k),
            self.decel / (k * k),
        )
    }

    /// The profile with its acceleration and deceleration limits multiplied by `accel_factor`
    /// and `decel_factor`.
    pub fn with_ramps(&self, accel_factor: f64, decel_factor: f64) -> Self {
        Self::new(
            self.max_rate,
            self.accel * accel_factor,
            self.decel * decel_factor,
        )
    }

    /// The path parameter at `t_s` (held at 0 before the start and at 1 after the end).
    pub fn sample(&self, t_s: f64) -> ScalingSample {
        let rest = |s| ScalingSample {
            s,
            rate: 0.0,
            accel: 0.0,
        };
        if t_s <= 0.0 {
            return rest(0.0);
        }
        let total = self.duration_s();
        if t_s >= total {
            return rest(1.0);
        }
        let v = self.peak_rate;
        if t_s < self.accel_s {
            return ScalingSample {
                s: 0.5 * self.accel * t_s * t_s,
                rate: self.accel * t_s,
                accel: self.accel,
            };
        }
        let reached = 0.5 * v * self.accel_s;
        if t_s < self.accel_s + self.cruise_s {
            return ScalingSample {
                s: reached + v * (t_s - self.accel_s),
                rate: v,
                accel: 0.0,
            };
        }
        let left = total - t_s;
        ScalingSample {
            s: (1.0 - 0.5 * self.decel * left * left).clamp(0.0, 1.0),
            rate: self.decel * left,
            accel: -self.decel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;

    /// Integrates the sampled rate and checks limits, continuity and the end points.
    fn check(profile: &TimeScaling) {
        let total = profile.duration_s();
        let n = 4000;
        let dt = total / f64::from(n);
        let mut previous = profile.sample(0.0);
        assert_eq!(previous.s, 0.0);
        for i in 1..=n {
            let now = profile.sample(dt * f64::from(i));
            assert!(now.rate <= profile.max_rate * (1.0 + 1e-9), "{now:?}");
            assert!(now.accel <= profile.accel + 1e-9 && -now.accel <= profile.decel + 1e-9);
            // Position and rate are continuous: each step changes them by at most the limits.
            let max_accel = profile.accel.max(profile.decel);
            assert!((now.rate - previous.rate).abs() <= max_accel * dt * (1.0 + 1e-6) + 1e-12);
            let mean_rate = 0.5 * (now.rate + previous.rate);
            assert!((now.s - previous.s - mean_rate * dt).abs() <= max_accel * dt * dt + 1e-12);
            previous = now;
        }
        let end = profile.sample(total);
        assert_eq!((end.s, end.rate), (1.0, 0.0));
    }

    #[test]
    fn random_limits_give_continuous_profiles_within_them() {
        let mut rng = SimRng::new(7);
        for _ in 0..300 {
            let profile = TimeScaling::new(
                rng.range(0.05, 20.0),
                rng.range(0.1, 200.0),
                rng.range(0.1, 200.0),
            );
            check(&profile);
        }
    }

    #[test]
    fn the_profile_is_time_optimal_for_its_limits() {
        // A triangle: 1 = a t^2 with a = 4 gives t = 0.5 s each way.
        let triangle = TimeScaling::new(100.0, 4.0, 4.0);
        assert!((triangle.duration_s() - 1.0).abs() < 1e-12);
        // A trapezoid: ramps of 0.5 s cover 0.5; the other 0.5 at rate 1 takes 0.5 s.
        let trapezoid = TimeScaling::new(1.0, 2.0, 2.0);
        assert!((trapezoid.duration_s() - 1.5).abs() < 1e-12);
        let slower = trapezoid.stretched(2.0);
        assert!((slower.duration_s() - 3.0).abs() < 1e-12);
        let a = trapezoid.sample(0.3);
        let b = slower.sample(0.6);
        assert!((a.s - b.s).abs() < 1e-12 && (a.rate - 2.0 * b.rate).abs() < 1e-12);
    }
}
