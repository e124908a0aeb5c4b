//! The controller's watch over its own grip, from the gripper's sensors alone: the force the
//! jaws report against the force commanded, and the jaws' opening against the part's width.

/// A reading below this share of the commanded force counts as a weak grip.
pub const WEAK_FORCE_SHARE: f64 = 0.5;
/// Readings in a row below the share before the watch calls the grip weak: a held part that
/// rocks under the arm's acceleration unloads one jaw for a step or two, never for this long.
pub const WEAK_READINGS: u32 = 6;
/// How far the jaws may close past the part's width before the part counts as gone, m: the
/// grasp check's margin.
pub const JAWS_PAST_PART_M: f64 = 0.006;

/// What the gripper's sensors say about the grip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GripReading {
    /// The jaws push on the part with the force commanded.
    Holding,
    /// The jaws still stand on the part, but push with less than [`WEAK_FORCE_SHARE`] of the
    /// command: the force each jaw reports, N.
    Weak { force_n: f64 },
    /// The jaws have closed past the part's width: nothing is between them.
    Empty,
}

/// Watches a grip tick by tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripWatch {
    /// The part's width between the jaws, m.
    part_width_m: f64,
    /// Readings in a row below the share so far.
    low_run: u32,
}

impl GripWatch {
    /// A watch over jaws closed on a part `part_width_m` wide.
    pub fn new(part_width_m: f64) -> Self {
        Self {
            part_width_m,
            low_run: 0,
        }
    }

    /// Whether the last reading was low but not yet for long enough to call the grip weak.
    pub fn doubting(&self) -> bool {
        (1..WEAK_READINGS).contains(&self.low_run)
    }

    /// One reading: the pads' offsets from the centre line (m), the force each jaw reports (N)
    /// and the force per jaw commanded (N).
    pub fn read(
        &mut self,
        pads_m: [f64; 2],
        jaw_force_n: [f64; 2],
        commanded_n: f64,
    ) -> GripReading {
        if pads_m[0] + pads_m[1] < self.part_width_m - JAWS_PAST_PART_M {
            self.low_run = 0;
            return GripReading::Empty;
        }
        let force_n = (jaw_force_n[0] + jaw_force_n[1]) / 2.0;
        if force_n < WEAK_FORCE_SHARE * commanded_n {
            self.low_run += 1;
        } else {
            self.low_run = 0;
        }
        if self.low_run >= WEAK_READINGS {
            GripReading::Weak { force_n }
        } else {
            GripReading::Holding
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grip_at_its_force_holds_through_short_dips() {
        let mut watch = GripWatch::new(0.04);
        for step in 0..200 {
            // A jaw unloaded for a few steps now and then, as under a swing.
            let dip = step % 50 < WEAK_READINGS as usize - 1;
            let force = if dip { [2.0, 20.0] } else { [58.0, 61.0] };
            assert_eq!(
                watch.read([0.0199, 0.0199], force, 60.0),
                GripReading::Holding
            );
        }
    }

    #[test]
    fn a_fallen_force_is_weak_after_its_readings_and_closed_jaws_are_empty() {
        let mut watch = GripWatch::new(0.04);
        for _ in 1..WEAK_READINGS {
            assert_eq!(
                watch.read([0.02, 0.02], [3.0, 3.0], 60.0),
                GripReading::Holding
            );
        }
        assert_eq!(
            watch.read([0.02, 0.02], [2.0, 4.0], 60.0),
            GripReading::Weak { force_n: 3.0 }
        );
        assert_eq!(
            watch.read([0.016, 0.016], [0.0, 0.0], 60.0),
            GripReading::Empty
        );
        // Over a range of part widths and commands, the jaws just past the margin are empty
        // and just short of it are not.
        for k in 0..50 {
            let width = 0.02 + 0.001 * f64::from(k);
            let command = 20.0 + 2.0 * f64::from(k);
            let mut watch = GripWatch::new(width);
            let half = (width - JAWS_PAST_PART_M) / 2.0;
            let held = [command; 2];
            assert_eq!(
                watch.read([half + 1e-4; 2], held, command),
                GripReading::Holding
            );
            assert_eq!(
                watch.read([half - 1e-4; 2], held, command),
                GripReading::Empty
            );
        }
    }
}
