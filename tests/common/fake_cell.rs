//! A test double of the cell for the batch runner: each record is a function of its seed, so
//! batches are fast and their files are known without running physics or rendering.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use twincell::batch::{
    DecisionRecord, FailureReason, Outcome, PartRecord, TrialRecord, TrialRunner, TrialTiming,
};
use twincell::rng::SimRng;

/// A cell whose outcome is a function of the seed; optionally slow, panicky or cancelling.
#[derive(Default)]
pub struct FakeCell {
    /// Sleep a seed-dependent few ms, so trials finish out of index order.
    pub sleepy: bool,
    /// Panic in this trial.
    pub panic_on: Option<u32>,
    /// Set this flag when this trial ends (so `k` trials ran when the flag is `k - 1`).
    pub cancel_after: Option<(u32, Arc<AtomicBool>)>,
    /// Write floats from 1e-8 to 1e10 (true roundness, simulated time), so that a report
    /// computed from records read back from disk shows whether they round-trip exactly.
    pub wide_floats: bool,
}

const REASONS: [FailureReason; 4] = [
    FailureReason::Slipped,
    FailureReason::NotDetected,
    FailureReason::WrongBin,
    FailureReason::Timeout,
];

impl TrialRunner for FakeCell {
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord {
        let mut rng = SimRng::new(seed);
        if self.sleepy {
            std::thread::sleep(Duration::from_millis(rng.below(6)));
        }
        if self.panic_on == Some(index) {
            panic!("gripper <jammed> & \"stuck\" in trial {index}");
        }
        let success = rng.uniform() < 0.75;
        let reason = REASONS[rng.below(4) as usize];
        let mut record = if success {
            let mut r = TrialRecord::failed(index, seed, reason, "");
            r.outcome = Outcome::Success;
            r.failure = None;
            r.detail = None;
            r
        } else {
            TrialRecord::failed(index, seed, reason, format!("state <carry> & 'x' {seed}"))
        };
        let types = ["hub", "flange", "sleeve"];
        let true_type = types[rng.below(3) as usize];
        let mut true_roundness_mm = rng.range(0.0, 0.2);
        if self.wide_floats {
            true_roundness_mm *= 1e-6;
        }
        let truly_acceptable = true_roundness_mm < 0.1;
        record.part = Some(PartRecord {
            part_type: true_type.to_owned(),
            true_roundness_mm,
            true_bore_diameter_mm: rng.range(18.0, 30.0),
            truly_acceptable,
            clear_cut: true,
            correct_bin: true_type.to_owned(),
        });
        let measured_roundness = true_roundness_mm + 0.01 * rng.normal();
        record.decision = Some(DecisionRecord {
            detected_type: if rng.uniform() < 0.9 {
                true_type
            } else {
                "sleeve"
            }
            .to_owned(),
            measured_roundness_mm: Some(measured_roundness),
            measured_bore_diameter_mm: Some(20.0 + 0.02 * rng.normal()),
            accept: measured_roundness < 0.1,
            bin: true_type.to_owned(),
            note: None,
        });
        record.placed_bin = success.then(|| true_type.to_owned());
        record.distractor_touched = rng.uniform() < 0.1;
        record.distractor_displacement_mm = rng.range(0.0, 3.0);
        record.cycle_time_s = rng.range(6.0, 9.0);
        record.sim_time_s = record.cycle_time_s + 2.0;
        if self.wide_floats {
            record.sim_time_s *= 1e9;
        }
        record.timing = TrialTiming {
            wall_ms: 0.0,
            physics_ms: 1.5,
            render_ms: 0.5,
            detect_ms: 0.25,
            metrology_ms: 0.125,
            planning_ms: 0.75,
        };
        if let Some((after, flag)) = &self.cancel_after
            && *after == index
        {
            flag.store(true, Ordering::SeqCst);
        }
        record
    }
}
