//! What the photo-eye reports: the beam's truth, with a trial's planned lies laid over it (a
//! trigger with nothing in the beam, an item that crosses it unreported).

use super::PhotoEyeFaults;

/// How long a false trigger holds the output, s: one pulse, as a reflection or electrical
/// noise gives, long enough for any controller polling each tick to see it.
pub const FALSE_TRIGGER_PULSE_S: f64 = 0.05;

/// The photo-eye's output through a trial.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhotoEyeSignal {
    faults: PhotoEyeFaults,
    /// Crossings begun so far (the beam going from clear to broken).
    crossings: u32,
    was_broken: bool,
    /// When a false trigger was first reported with the beam clear, s.
    false_struck_s: Option<f64>,
    /// When an unreported crossing began, s.
    missed_struck_s: Option<f64>,
}

impl PhotoEyeSignal {
    /// A photo-eye with `faults` planned.
    pub fn new(faults: PhotoEyeFaults) -> Self {
        Self {
            faults,
            ..Self::default()
        }
    }

    /// What the eye reports at trial time `time_s` when its beam is truly `beam_broken`; call
    /// it once per tick, in order.
    pub fn read(&mut self, beam_broken: bool, time_s: f64) -> bool {
        if beam_broken && !self.was_broken {
            self.crossings += 1;
        }
        self.was_broken = beam_broken;
        let crossing = self.crossings.checked_sub(1);
        let missed = beam_broken && crossing.is_some() && crossing == self.faults.missed_crossing;
        let phantom = self
            .faults
            .false_trigger_at_s
            .is_some_and(|at| (at..at + FALSE_TRIGGER_PULSE_S).contains(&time_s));
        if missed {
            self.missed_struck_s.get_or_insert(time_s);
        }
        if phantom && !beam_broken {
            self.false_struck_s.get_or_insert(time_s);
        }
        (beam_broken && !missed) || phantom
    }

    /// When a false trigger was reported with the beam clear, if one was, s.
    pub fn false_trigger_struck_s(&self) -> Option<f64> {
        self.false_struck_s
    }

    /// When a crossing began that went unreported, if one did, s.
    pub fn missed_trigger_struck_s(&self) -> Option<f64> {
        self.missed_struck_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT_S: f64 = 1.0 / 240.0;

    /// The eye's output over a beam broken in the windows `broken` (s), for `seconds`.
    fn trace(signal: &mut PhotoEyeSignal, broken: &[(f64, f64)], seconds: f64) -> Vec<bool> {
        (0..(seconds / DT_S) as usize)
            .map(|k| {
                let t = k as f64 * DT_S;
                let beam = broken.iter().any(|&(a, b)| (a..b).contains(&t));
                signal.read(beam, t)
            })
            .collect()
    }

    fn rising_edges(trace: &[bool]) -> usize {
        trace.windows(2).filter(|w| !w[0] && w[1]).count() + usize::from(trace[0])
    }

    const CROSSINGS: [(f64, f64); 3] = [(0.5, 0.8), (1.5, 1.9), (2.5, 2.6)];

    #[test]
    fn a_faultless_eye_reports_the_beam() {
        let mut signal = PhotoEyeSignal::default();
        let out = trace(&mut signal, &CROSSINGS, 3.0);
        assert_eq!(rising_edges(&out), 3);
        assert!(
            signal.false_trigger_struck_s().is_none() && signal.missed_trigger_struck_s().is_none()
        );
    }

    #[test]
    fn a_missed_crossing_goes_unreported_and_the_others_are_seen() {
        for missed in 0..3u32 {
            let mut signal = PhotoEyeSignal::new(PhotoEyeFaults {
                false_trigger_at_s: None,
                missed_crossing: Some(missed),
            });
            let out = trace(&mut signal, &CROSSINGS, 3.0);
            assert_eq!(rising_edges(&out), 2, "crossing {missed}");
            let (a, b) = CROSSINGS[missed as usize];
            let k = ((a + b) / 2.0 / DT_S) as usize;
            assert!(!out[k], "crossing {missed} reported");
            let at = signal.missed_trigger_struck_s().expect("struck");
            assert!((at - a).abs() <= DT_S, "{at} {a}");
        }
    }

    #[test]
    fn a_false_trigger_is_one_pulse_with_the_beam_clear() {
        let mut signal = PhotoEyeSignal::new(PhotoEyeFaults {
            false_trigger_at_s: Some(0.2),
            missed_crossing: None,
        });
        let out = trace(&mut signal, &CROSSINGS, 3.0);
        assert_eq!(rising_edges(&out), 4);
        let pulse = out[..(0.5 / DT_S) as usize].iter().filter(|&&b| b).count();
        let expected = (FALSE_TRIGGER_PULSE_S / DT_S).round() as usize;
        assert!(pulse.abs_diff(expected) <= 1, "{pulse} ticks");
        let at = signal.false_trigger_struck_s().expect("struck");
        assert!((at - 0.2).abs() <= DT_S, "{at}");
        // A phantom that falls inside a true crossing changes nothing and strikes nothing.
        let mut hidden = PhotoEyeSignal::new(PhotoEyeFaults {
            false_trigger_at_s: Some(0.6),
            missed_crossing: None,
        });
        let out = trace(&mut hidden, &CROSSINGS, 3.0);
        assert_eq!(rising_edges(&out), 3);
        assert!(hidden.false_trigger_struck_s().is_none());
    }
}
