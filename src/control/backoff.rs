//! When to ask a failing sensor again: after waits that grow by a factor from a first one, up
//! to a set number of retries, so a short dropout costs little and a long one is given up on.

/// A retry schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backoff {
    /// The wait before the first retry, s.
    pub first_wait_s: f64,
    /// Each wait is this many times the one before.
    pub factor: f64,
    /// Retries after the first attempt.
    pub retries: u32,
}

impl Backoff {
    /// The camera's: 0.25, 0.5, 1 and 2 s, so a dropout of up to 3.75 s is waited out.
    pub const CAMERA: Backoff = Backoff {
        first_wait_s: 0.25,
        factor: 2.0,
        retries: 4,
    };

    /// The wait before each retry, in order, s.
    pub fn waits_s(&self) -> impl Iterator<Item = f64> + '_ {
        (0..self.retries).map(|k| self.first_wait_s * self.factor.powi(k as i32))
    }

    /// The time all retries wait together, s: the longest dropout that is waited out.
    pub fn patience_s(&self) -> f64 {
        self.waits_s().sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_waits_grow_by_the_factor_and_add_up_to_the_patience() {
        let waits: Vec<f64> = Backoff::CAMERA.waits_s().collect();
        assert_eq!(waits, [0.25, 0.5, 1.0, 2.0]);
        assert_eq!(Backoff::CAMERA.patience_s(), 3.75);
        let none = Backoff {
            retries: 0,
            ..Backoff::CAMERA
        };
        assert_eq!(none.waits_s().count(), 0);
        assert_eq!(none.patience_s(), 0.0);
    }
}
