//! What the jaws carry, and how hard the arm may accelerate it before the friction-only grip
//! lets go.

use super::ToolLimits;

/// Standard gravity, m/s^2.
const GRAVITY_M_S2: f64 = 9.81;
/// The grip's friction must hold this many times the load it carries: pad friction varies
/// with wear and contamination, the squeeze force of a real drive with its current, and a tube
/// held off its centre of mass also sees a turning moment in the jaws that the linear balance
/// below leaves out. The slip monitor checks the result in every simulated carry.
pub const GRIP_SAFETY_FACTOR: f64 = 3.0;
/// Fastest TCP speed while carrying, m/s: a held part's drift along the pads grows steeply with
/// the carry speed, well inside the grip's friction margin (the measurements: docs/motion.md).
const CARRY_SPEED_M_S: f64 = 0.75;

/// A part held between two flat pads by friction alone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Payload {
    /// The part's mass, kg.
    pub mass_kg: f64,
    /// Squeeze force of each jaw, N.
    pub grip_force_n: f64,
    /// Friction coefficient between a pad and the part.
    pub pad_friction: f64,
}

impl Payload {
    /// The largest TCP acceleration the grip holds with [`GRIP_SAFETY_FACTOR`] to spare, m/s^2.
    /// Two contacts hold at most `2 mu F` along the jaw faces; the part needs
    /// `m |g + a| <= m (g + |a|)` of it, so `|a| <= 2 mu F / (S m) - g`. `None` when the grip
    /// cannot hold the part with that margin even at rest.
    pub fn max_accel_m_s2(&self) -> Option<f64> {
        let holding_n = 2.0 * self.pad_friction * self.grip_force_n;
        let accel = holding_n / (GRIP_SAFETY_FACTOR * self.mass_kg.max(1e-6)) - GRAVITY_M_S2;
        (accel > 0.0).then_some(accel)
    }

    /// The TCP limits for carrying this part: the grip's acceleration (a tenth of gravity when
    /// the grip has no margin at all, so that the move is gentle and the slip monitor judges).
    pub fn tool_limits(&self) -> ToolLimits {
        ToolLimits {
            speed_m_s: CARRY_SPEED_M_S,
            accel_m_s2: self.max_accel_m_s2().unwrap_or(0.1 * GRAVITY_M_S2),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;

    #[test]
    fn the_limit_balances_friction_against_weight_and_inertia() {
        let mut rng = SimRng::new(3);
        for _ in 0..200 {
            let payload = Payload {
                mass_kg: rng.range(0.05, 5.0),
                grip_force_n: rng.range(5.0, 200.0),
                pad_friction: rng.range(0.2, 1.5),
            };
            let holding = 2.0 * payload.pad_friction * payload.grip_force_n;
            match payload.max_accel_m_s2() {
                Some(a) => {
                    // At the limit the grip holds exactly the safety factor times the load.
                    let load = payload.mass_kg * (GRAVITY_M_S2 + a);
                    assert!((holding - GRIP_SAFETY_FACTOR * load).abs() < 1e-9 * holding);
                    assert_eq!(payload.tool_limits().accel_m_s2, a);
                }
                None => {
                    assert!(holding <= GRIP_SAFETY_FACTOR * payload.mass_kg * GRAVITY_M_S2);
                    assert!(payload.tool_limits().accel_m_s2 < GRAVITY_M_S2);
                }
            }
        }
        // Heavier parts and weaker grips give lower limits.
        let base = Payload {
            mass_kg: 1.0,
            grip_force_n: 100.0,
            pad_friction: 1.0,
        };
        let heavier = Payload {
            mass_kg: 2.0,
            ..base
        };
        assert!(heavier.max_accel_m_s2() < base.max_accel_m_s2());
    }
}
