//! The summary table a run prints at its end.

use std::fmt::Write as _;

use super::{BatchReport, Perception};
use crate::scenario::UNIDENTIFIED;

impl BatchReport {
    /// A fixed-width plain-text summary for the end of a run.
    pub fn summary_table(&self) -> String {
        let mut out = String::new();
        // Writing to a String cannot fail; the results are ignored on purpose.
        let _ = writeln!(
            out,
            "scenario {:?}  seed {}  perception {}",
            self.scenario,
            self.seed,
            self.perception.as_str()
        );
        if self.perception == Perception::Oracle {
            let _ = writeln!(out, "  ** {} **", self.perception_note);
        }
        let scope = match self.shard {
            Some(shard) => format!("shard {shard} of {} trials", self.scenario_trials),
            None => format!("of {} planned", self.scenario_trials),
        };
        let stopped = if self.interrupted {
            "  INTERRUPTED"
        } else {
            ""
        };
        let _ = writeln!(
            out,
            "{:<22}{:>8}  ({scope}){stopped}",
            "trials", self.trials
        );
        let _ = writeln!(
            out,
            "{:<22}{:>8}  strict {} (every part in the bin its truth calls for, no band)",
            "successes", self.successes, self.strict_successes
        );
        let _ = writeln!(
            out,
            "{:<22}{:>7.1}%  Wilson 95% [{:.1}%, {:.1}%]",
            "success rate",
            100.0 * self.success_rate,
            100.0 * self.wilson95[0],
            100.0 * self.wilson95[1]
        );
        let _ = writeln!(
            out,
            "{:<22}{:>8}  {:.1}% let through as unpickable; removals {}",
            "passed",
            self.passed,
            100.0 * self.passed_rate,
            self.removals
        );
        let _ = writeln!(
            out,
            "{:<22}{:>7.1}%  ({} sorted or passed, no bottle touched)",
            "safe rate",
            100.0 * self.safe_rate,
            self.safe
        );
        let _ = writeln!(out, "failures by reason");
        if self.failures.is_empty() {
            let _ = writeln!(out, "  {:<20}{:>8}", "(none)", 0);
        }
        for (reason, n) in &self.failures {
            let _ = writeln!(out, "  {reason:<20}{n:>8}");
        }
        let _ = writeln!(
            out,
            "{:<22}picks {}  touches {}  max displacement {:.2} mm",
            "distractor",
            self.distractor_picks,
            self.distractor_touches,
            self.distractor_max_displacement_mm
        );
        let _ = writeln!(
            out,
            "{:<22}{:>8}{:>10}{:>10}{:>10}",
            "metrology |error| mm", "n", "mean", "p95", "max"
        );
        for (name, stats) in [
            ("roundness", &self.metrology.roundness_error_mm),
            ("bore diameter", &self.metrology.bore_diameter_error_mm),
        ] {
            match stats {
                Some(s) => {
                    let _ = writeln!(
                        out,
                        "  {name:<20}{:>8}{:>10.4}{:>10.4}{:>10.4}",
                        s.count, s.mean_mm, s.p95_mm, s.max_mm
                    );
                }
                None => {
                    let _ = writeln!(out, "  {name:<20}{:>8}{:>10}{:>10}{:>10}", 0, "-", "-", "-");
                }
            }
        }
        let verdicts = &self.sorting.accept_reject;
        let _ = writeln!(
            out,
            "{:<22}true accept -> {} accepted {} rejected; true reject -> {} accepted {} rejected",
            "sorting",
            verdicts.truly_accept.accept,
            verdicts.truly_accept.reject,
            verdicts.truly_reject.accept,
            verdicts.truly_reject.reject
        );
        let type_errors: u32 = self
            .sorting
            .part_type
            .iter()
            .flat_map(|(truth, detected)| {
                detected
                    .iter()
                    .filter(move |(name, _)| *name != truth && *name != UNIDENTIFIED)
                    .map(|(_, n)| *n)
            })
            .sum();
        let _ = writeln!(
            out,
            "  {:<20}{} of {} clear-cut parts misjudged; {} parts of the wrong detected type, {} unidentified",
            "",
            self.sorting.clear_cut_misjudged,
            self.sorting.clear_cut,
            type_errors,
            self.sorting.unidentified
        );
        let band = &self.sorting.in_band;
        let _ = writeln!(
            out,
            "  {:<20}{} parts inside the uncertainty band ({} truly within tolerance): {} accepted, {} rejected",
            "", band.parts, band.truly_acceptable, band.accepted, band.rejected
        );
        let _ = writeln!(
            out,
            "{:<22}{:>8}{:>10}{:>10}{:>10}",
            "cycle time s", "n", "mean", "p50", "p95"
        );
        match &self.cycle_time_s {
            Some(c) => {
                let _ = writeln!(
                    out,
                    "  {:<20}{:>8}{:>10.3}{:>10.3}{:>10.3}",
                    "successful", c.count, c.mean, c.p50, c.p95
                );
            }
            None => {
                let _ = writeln!(
                    out,
                    "  {:<20}{:>8}{:>10}{:>10}{:>10}",
                    "successful", 0, "-", "-", "-"
                );
            }
        }
        if let Some(stream) = &self.stream {
            let _ = writeln!(
                out,
                "{:<22}{:>8}  of {} reached, {} fed; {} bottles passed, {} belt stops",
                "stream parts sorted",
                stream.parts_sorted,
                stream.parts_reached,
                stream.parts_planned,
                stream.bottles_passed,
                stream.belt_stops
            );
            for (reason, n) in &stream.part_failures {
                let _ = writeln!(out, "  {reason:<20}{n:>8}");
            }
            if let Some(t) = &stream.tracking {
                let _ = writeln!(
                    out,
                    "{:<22}{:>8.3}  {} unpicked; latch-to-grasp {:.2} s (max {:.2}), tracking \
                     error {:.1} mm (max {:.1}), jaw drift max {:.2} mm, joint margin {:.3} rad",
                    "tracking sorted share",
                    t.sorted_share,
                    t.parts_unpicked,
                    t.latch_to_grasp_s.mean,
                    t.latch_to_grasp_s.max,
                    t.tracking_error_mm.mean,
                    t.tracking_error_mm.max,
                    t.jaw_drift_mm.max,
                    t.joint_limit_margin_rad
                );
            }
        }
        let ppm = self
            .parts_per_minute
            .map_or_else(|| "-".to_owned(), |p| format!("{p:.2}"));
        let _ = writeln!(out, "{:<22}{:>8}", "parts per minute", ppm);
        let _ = writeln!(out, "{:<22}{:>8}{:>10}", "wall time", "total s", "mean ms");
        let stages = &self.timing.stages;
        for (name, s) in [
            ("trial", &stages.trial),
            ("physics", &stages.physics),
            ("render", &stages.render),
            ("detect", &stages.detect),
            ("metrology", &stages.metrology),
            ("planning", &stages.planning),
        ] {
            let _ = writeln!(out, "  {name:<20}{:>8.2}{:>10.2}", s.total_s, s.mean_ms);
        }
        if let (Some(wall), Some(jobs)) = (self.timing.batch_wall_s, self.timing.jobs) {
            let _ = writeln!(out, "{:<22}{wall:>8.2}  on {jobs} jobs", "batch wall s");
        }
        if let Some(gate) = &self.gate {
            let verdict = if gate.passed { "passed" } else { "FAILED" };
            let _ = writeln!(
                out,
                "{:<22}{:>7.1}%  {verdict}",
                "gate min success",
                100.0 * gate.min_success
            );
        }
        out
    }
}
