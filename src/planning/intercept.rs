//! Where along a moving belt the arm meets a part (conveyor tracking).
//!
//! The part rides the belt at a known speed from where the encoder has it now. The arm needs
//! some time to come over a place `x` along the belt, ready to go down (the planned motion's
//! time to its descent, from where the arm stands): `arrival(x)`, or `None` where no motion
//! reaches (outside the arm's reach or joint limits, or every grasp there collides). The meet
//! is the first place in the pick window that the arm reaches no later than the part does:
//! `x_now + speed * arrival(x) <= x`. There the arm waits for the part the difference, then goes
//! down with it. The window's end leaves room for the travel during descend, grasp and lift.
//!
//! The search walks the window at [`GRID_STEP_M`] from the part's place (or the window's start,
//! when the part has not yet reached it) to its end, and bisects the first step that crosses
//! from "the part gets there first" to "the arm does", so a window whose reachable stretch
//! starts late, or has holes, is still met at its first reachable place; a step in which the
//! reach ends is bisected for its end, where the arm may still be in time. Where the arm is no
//! slower than the belt the time the arm has to spare only grows along the belt until the reach
//! ends, and the search misses no meet; an arm slower than the belt may have a stretch of spare
//! time shorter than a step, which the walk can pass over.

/// Step of the walk along the window, m.
pub const GRID_STEP_M: f64 = 0.03;
/// Bisection steps on the crossing step: the meet is found to within 1 mm.
const BISECTIONS: u32 = 5;
/// Bisection steps on a step in which the reach ends: its end found to within 10 µm.
const BOUNDARY_BISECTIONS: u32 = 12;

/// A part on the moving belt and the stretch in which the arm may meet it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterceptProblem {
    /// The part's place along the belt now, m (world x: the belt runs along +x).
    pub part_now_m: f64,
    /// The belt's speed, m/s (> 0).
    pub speed_m_s: f64,
    /// The pick window along the belt, first and last place to meet the part, m.
    pub window_m: (f64, f64),
}

/// Where and when the arm meets the part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intercept {
    /// The place along the belt, m.
    pub at_m: f64,
    /// When the part gets there, s from now.
    pub meet_s: f64,
    /// When the arm gets there, s from now (no later than `meet_s`).
    pub arrival_s: f64,
}

impl InterceptProblem {
    /// When the part gets to `x`, s from now (negative: it is already past).
    pub fn part_at_s(&self, x_m: f64) -> f64 {
        (x_m - self.part_now_m) / self.speed_m_s
    }

    /// The first meet in the window, or `None` when the arm reaches no place in the window
    /// before the part has passed it. `arrival(x)` is the arm's time to be ready over `x`.
    pub fn solve(&self, mut arrival: impl FnMut(f64) -> Option<f64>) -> Option<Intercept> {
        let (start, end) = self.window_m;
        if self.speed_m_s.is_nan() || self.speed_m_s <= 0.0 || end < start {
            return None;
        }
        let from = start.max(self.part_now_m);
        if from > end {
            return None;
        }
        // Where the arm, arriving at `x`, is early (>= 0) or late (< 0).
        let mut slack = |x: f64| arrival(x).map(|t| (self.part_at_s(x) - t, t));
        let steps = ((end - from) / GRID_STEP_M).ceil().max(0.0) as usize;
        let mut before: Option<f64> = None;
        for k in 0..=steps {
            let x = (from + k as f64 * GRID_STEP_M).min(end);
            match slack(x) {
                Some((s, t)) if s >= 0.0 => {
                    let Some(mut late) = before else {
                        return Some(self.meet(x, t));
                    };
                    // Bisect between the late place and this one.
                    let (mut early, mut early_t) = (x, t);
                    for _ in 0..BISECTIONS {
                        let mid = 0.5 * (late + early);
                        match slack(mid) {
                            Some((s, t)) if s >= 0.0 => (early, early_t) = (mid, t),
                            _ => late = mid,
                        }
                    }
                    return Some(self.meet(early, early_t));
                }
                Some(_) => before = Some(x),
                None => {
                    // The reach ends within the step: the stretch from the late place to the
                    // reach's end may still hold a meet.
                    if let Some(late) = before
                        && let Some(meet) = self.meet_before_reach_ends(late, x, &mut slack)
                    {
                        return Some(meet);
                    }
                    before = None;
                }
            }
        }
        None
    }

    /// Between `late` (reachable, the arm late) and `gone` (unreachable): the last reachable
    /// place, found by bisection, and the first meet before it, when the arm is in time there.
    fn meet_before_reach_ends(
        &self,
        late: f64,
        gone: f64,
        slack: &mut impl FnMut(f64) -> Option<(f64, f64)>,
    ) -> Option<Intercept> {
        let (mut reach, mut beyond) = (late, gone);
        for _ in 0..BOUNDARY_BISECTIONS {
            let mid = 0.5 * (reach + beyond);
            match slack(mid) {
                Some(_) => reach = mid,
                None => beyond = mid,
            }
        }
        let (s, t) = slack(reach)?;
        if s < 0.0 {
            return None;
        }
        let (mut late, mut early, mut early_t) = (late, reach, t);
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (late + early);
            match slack(mid) {
                Some((s, t)) if s >= 0.0 => (early, early_t) = (mid, t),
                _ => late = mid,
            }
        }
        Some(self.meet(early, early_t))
    }

    fn meet(&self, x_m: f64, arrival_s: f64) -> Intercept {
        Intercept {
            at_m: x_m,
            meet_s: self.part_at_s(x_m),
            arrival_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;

    /// An arm at `base` that moves at `arm_speed` with a fixed `overhead`, reaching `reach`.
    fn arm(
        base: f64,
        arm_speed: f64,
        overhead: f64,
        reach: (f64, f64),
    ) -> impl Fn(f64) -> Option<f64> {
        move |x| {
            (reach.0..=reach.1)
                .contains(&x)
                .then(|| overhead + (x - base).abs() / arm_speed)
        }
    }

    #[test]
    fn meets_are_in_the_window_reachable_and_in_time_over_drawn_belts() {
        let mut rng = SimRng::new(26);
        let mut met = 0;
        for _ in 0..2000 {
            let speed = 0.05 + 0.55 * rng.uniform();
            let part_now = -0.3 + 0.6 * rng.uniform();
            let window = (-0.1 + 0.2 * rng.uniform(), 0.3 + 0.5 * rng.uniform());
            let reach = (-0.2 + 0.4 * rng.uniform(), 0.2 + 0.6 * rng.uniform());
            let base = 0.3 * rng.uniform();
            let (arm_speed, overhead) = (0.3 + 1.2 * rng.uniform(), 0.3 + rng.uniform());
            let arrival = arm(base, arm_speed, overhead, reach);
            let problem = InterceptProblem {
                part_now_m: part_now,
                speed_m_s: speed,
                window_m: window,
            };
            match problem.solve(&arrival) {
                Some(m) => {
                    met += 1;
                    assert!(m.at_m >= window.0 - 1e-12 && m.at_m <= window.1 + 1e-12);
                    assert!(m.at_m >= part_now - 1e-12, "met behind the part");
                    let t = arrival(m.at_m).expect("met where the arm cannot reach");
                    assert!((t - m.arrival_s).abs() < 1e-12);
                    assert!(m.arrival_s <= m.meet_s + 1e-12, "the arm comes late");
                    assert!((part_now + speed * m.meet_s - m.at_m).abs() < 1e-9);
                    // No place a grid step or more earlier would have done.
                    let mut x = m.at_m - GRID_STEP_M;
                    while x >= window.0.max(part_now) {
                        let early = arrival(x).is_some_and(|t| t <= problem.part_at_s(x));
                        assert!(!early, "a reachable earlier meet at {x} before {}", m.at_m);
                        x -= GRID_STEP_M;
                    }
                }
                None => {
                    // Nowhere along the window is the arm in time: sampled finely where the
                    // arm is faster than the belt, at the walk's places otherwise.
                    let from = window.0.max(part_now);
                    let step = if arm_speed > speed {
                        0.001
                    } else {
                        GRID_STEP_M
                    };
                    let mut x = from;
                    while x <= window.1 {
                        let in_time = arrival(x).is_some_and(|t| t <= problem.part_at_s(x));
                        assert!(!in_time, "missed a meet at {x}");
                        x += step;
                    }
                }
            }
        }
        assert!(met > 500, "only {met} of 2000 drawn belts met");
    }

    #[test]
    fn a_part_past_the_window_or_a_stopped_belt_is_not_met() {
        let arrival = |_| Some(0.5);
        let past = InterceptProblem {
            part_now_m: 0.9,
            speed_m_s: 0.25,
            window_m: (0.0, 0.8),
        };
        assert_eq!(past.solve(arrival), None);
        let stopped = InterceptProblem {
            speed_m_s: 0.0,
            part_now_m: 0.1,
            ..past
        };
        assert_eq!(stopped.solve(arrival), None);
    }

    #[test]
    fn the_meet_is_where_the_part_catches_up_with_the_arm() {
        // The arm is ready anywhere in 1 s; a part at 0 on a 0.25 m/s belt is met at 0.25 m.
        let problem = InterceptProblem {
            part_now_m: 0.0,
            speed_m_s: 0.25,
            window_m: (-0.2, 0.8),
        };
        let Some(m) = problem.solve(|_| Some(1.0)) else {
            panic!("no meet");
        };
        assert!((m.at_m - 0.25).abs() < 0.001 + 1e-9, "{m:?}");
        assert!((m.meet_s - 1.0).abs() < 0.004 + 1e-9);
    }
}
