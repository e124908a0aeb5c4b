//! One trial as `junit.xml` and `report.html` show it: a row kept with the batch's report, so
//! that neither reads the records again.

use std::fmt::Write as _;

use super::trial_images::{decision_misjudged, wants_image};
use super::{DecisionRecord, FailureReason, Outcome, PartRecord, TrialRecord};

/// One trial's outcome, wall time and, when it failed or was misjudged, its part in words.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialSummary {
    /// Trial index.
    pub trial: u32,
    /// The trial's seed.
    pub seed: u64,
    /// Success or failure.
    pub outcome: Outcome,
    /// Why it failed, when it did.
    pub failure: Option<FailureReason>,
    /// The record's detail.
    pub detail: Option<String>,
    /// The trial's wall time, ms (not deterministic).
    pub wall_ms: f64,
    /// Truth and decision, in words, of the part the report page shows the trial for; `None`
    /// when the trial neither failed nor had a decision against the truth.
    pub judgement: Option<String>,
}

impl TrialSummary {
    /// The summary of `record`.
    pub fn of(record: &TrialRecord) -> Self {
        Self {
            trial: record.trial,
            seed: record.seed,
            outcome: record.outcome,
            failure: record.failure,
            detail: record.detail.clone(),
            wall_ms: record.timing.wall_ms,
            judgement: wants_image(record).then(|| shown_part(record)),
        }
    }

    /// The failure reason as reports name it (`unspecified` for a failure without one);
    /// `None` for a success.
    pub fn failure_reason(&self) -> Option<&'static str> {
        (self.outcome == Outcome::Failure)
            .then(|| self.failure.map_or("unspecified", |f| f.as_str()))
    }
}

/// The part a failed or misjudged `record` is shown for, in words: a stream's first failed or
/// misjudged part, a single-part trial's one part.
fn shown_part(record: &TrialRecord) -> String {
    let parts = record.parts();
    let shown = match &record.stream {
        Some(_) => parts.iter().find(|p| {
            p.outcome == Outcome::Failure
                || p.decision.is_some_and(|d| decision_misjudged(p.part, d))
        }),
        None => parts.first(),
    };
    let Some(p) = shown else {
        return "no part reached the pick station".to_owned();
    };
    let judged = judgement(p.part, p.decision, p.placed_bin);
    match &record.stream {
        Some(_) => format!("part {}: {judged}", p.index),
        None => judged,
    }
}

/// Truth and decision of `part` in words.
fn judgement(part: &PartRecord, decision: Option<&DecisionRecord>, placed: Option<&str>) -> String {
    let verdict = |accept: bool| if accept { "accept" } else { "reject" };
    let mut text = format!(
        "truth: {} roundness {:.3} mm ({}), bore {:.2} mm, belongs in {}",
        part.part_type,
        part.true_roundness_mm,
        verdict(part.truly_acceptable),
        part.true_bore_diameter_mm,
        part.correct_bin
    );
    match decision {
        Some(d) => {
            let measured = d
                .measured_roundness_mm
                .map_or("not measured".to_owned(), |r| {
                    format!("roundness {r:.3} mm")
                });
            let bore = d
                .measured_bore_diameter_mm
                .map_or(String::new(), |b| format!(", bore {b:.2} mm"));
            let misjudged = if decision_misjudged(part, d) {
                " (misjudged)"
            } else {
                ""
            };
            let _ = write!(
                text,
                "; decided: {} {measured}{bore} -> {}{misjudged}",
                d.detected_type,
                verdict(d.accept)
            );
        }
        None => text.push_str("; no decision"),
    }
    let _ = write!(text, "; placed in {}", placed.unwrap_or("no bin"));
    text
}
