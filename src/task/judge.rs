//! Judging a pick cycle against the truth: which bin a part belongs in, whether the bin it
//! reached is right (with the metrology's uncertainty zone), and what the bottles say.

use crate::outcome::{Failure, FailureReason, PartRecord, Phase};
use crate::scenario::{BinId, Catalogue, PartTypeId, Scenario};
use crate::sim::PartInstance;

/// The name of `bin` for records (empty when there is none).
pub fn bin_name(catalogue: &Catalogue, bin: Option<BinId>) -> String {
    bin.map(|b| catalogue.bin_name(b).to_owned())
        .unwrap_or_default()
}

/// The truth about `part`: its true roundness and diameter, whether it conforms, whether it is
/// clear of the uncertainty zone, and the bin the truth calls for.
pub fn part_record(scenario: &Scenario, catalogue: &Catalogue, part: &PartInstance) -> PartRecord {
    let true_roundness_mm = part.bore.roundness_m() * 1000.0;
    let truly_acceptable = true_roundness_mm <= scenario.roundness_tolerance_mm;
    let clear_cut = (true_roundness_mm - scenario.roundness_tolerance_mm).abs()
        > scenario.roundness_uncertainty_mm;
    let correct = catalogue.bin_for(PartTypeId(part.type_index), truly_acceptable);
    PartRecord {
        part_type: part.type_name.clone(),
        true_roundness_mm,
        true_bore_diameter_mm: part.bore.mean_diameter_m() * 1000.0,
        truly_acceptable,
        clear_cut,
        correct_bin: bin_name(catalogue, correct),
    }
}

/// Whether `placed` is right for a part of type `part_type` judged `truth`: the bin its true
/// roundness calls for or, for a part inside the uncertainty zone (not clear-cut), either its
/// type's accept bin or the reject bin.
pub fn bin_is_right(
    catalogue: &Catalogue,
    part_type: PartTypeId,
    truth: &PartRecord,
    placed: Option<BinId>,
) -> bool {
    let Some(placed) = placed else {
        return false;
    };
    let bin_for = |accept| catalogue.bin_for(part_type, accept) == Some(placed);
    bin_for(truth.truly_acceptable) || (!truth.clear_cut && (bin_for(true) || bin_for(false)))
}

/// What was seen of the bottles and the part at the end of a pick cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleEvidence {
    /// The part's type.
    pub part_type: PartTypeId,
    /// The bin the part rests in, if any.
    pub placed_bin: Option<BinId>,
    /// Whether a bottle was lifted.
    pub bottle_lifted: bool,
    /// Whether the robot touched a bottle, and in which phase it first did.
    pub touch_phase: Option<Phase>,
    /// The largest move of a bottle since the belt stopped, m.
    pub bottle_displacement_m: f64,
}

impl CycleEvidence {
    /// Whether the bottles count as disturbed: touched by the robot, or moved beyond the
    /// scenario's tolerance.
    pub fn bottle_disturbed(&self, scenario: &Scenario) -> bool {
        self.touch_phase.is_some() || self.bottle_displacement_m > scenario.task.bottle_tolerance_m
    }
}

/// The failures every cycle is judged on first: the controller's own, then a lifted bottle.
fn controller_or_lift(
    controller: Result<(), Failure>,
    evidence: &CycleEvidence,
) -> Option<Failure> {
    if let Err(failure) = controller {
        return Some(failure);
    }
    evidence
        .bottle_lifted
        .then(|| Failure::new(FailureReason::DistractorPicked, "the bottle was lifted"))
}

/// The failure of a pick cycle on `part`, if any: the controller's own failure first, then a
/// lifted bottle, a disturbed one, and last the wrong bin.
pub fn judge_cycle(
    scenario: &Scenario,
    catalogue: &Catalogue,
    part: &PartRecord,
    controller: Result<(), Failure>,
    evidence: &CycleEvidence,
) -> Option<Failure> {
    if let Some(failure) = controller_or_lift(controller, evidence) {
        return Some(failure);
    }
    if evidence.bottle_disturbed(scenario) {
        let moved_mm = evidence.bottle_displacement_m * 1e3;
        let detail = match evidence.touch_phase {
            Some(phase) => {
                format!("robot touched the bottle during {phase}; it moved {moved_mm:.1} mm")
            }
            None => format!("bottle moved {moved_mm:.1} mm"),
        };
        return Some(Failure::new(FailureReason::DistractorTouched, detail));
    }
    if !bin_is_right(catalogue, evidence.part_type, part, evidence.placed_bin) {
        let placed = evidence
            .placed_bin
            .map_or("no bin", |b| catalogue.bin_name(b));
        return Some(Failure::new(
            FailureReason::WrongBin,
            format!("part in {placed}, belongs in {}", part.correct_bin),
        ));
    }
    None
}

/// The failure of a cycle whose part was let through to the collector, if any: the
/// controller's own failure, a lifted bottle, or the robot's touch on one. Bottles the belt
/// carried on with the part do not count as disturbed.
pub fn judge_pass(controller: Result<(), Failure>, evidence: &CycleEvidence) -> Option<Failure> {
    if let Some(failure) = controller_or_lift(controller, evidence) {
        return Some(failure);
    }
    evidence.touch_phase.map(|phase| {
        Failure::new(
            FailureReason::DistractorTouched,
            format!("robot touched the bottle during {phase}"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::BoreForm;

    fn paper(uncertainty_mm: f64) -> Scenario {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper_50.toml");
        let Ok(mut scenario) = Scenario::load(&path) else {
            panic!("paper_50.toml does not load");
        };
        scenario.roundness_uncertainty_mm = uncertainty_mm;
        scenario
    }

    /// The bin named `name` in paper_50.
    fn bin(name: &str) -> Option<BinId> {
        let scenario = paper(0.05);
        scenario.bins.iter().position(|b| b.name == name).map(BinId)
    }

    /// A part of `type_name` whose bore is an ellipse out of round by `roundness_mm`.
    fn part(type_name: &str, roundness_mm: f64) -> PartInstance {
        let scenario = paper(0.05);
        let Some(type_index) = scenario.part_types.iter().position(|t| t.name == type_name) else {
            panic!("no type {type_name}");
        };
        PartInstance {
            type_index,
            type_name: type_name.into(),
            outer_radius_m: 0.015,
            height_m: 0.05,
            mass_kg: 0.3,
            bore: BoreForm::Ellipse {
                a_m: 0.010 + roundness_mm * 1e-3,
                b_m: 0.010,
                angle_rad: 0.3,
            },
        }
    }

    fn clean(part: &PartInstance, placed_bin: Option<&str>) -> CycleEvidence {
        CycleEvidence {
            part_type: PartTypeId(part.type_index),
            placed_bin: placed_bin.and_then(bin),
            bottle_lifted: false,
            touch_phase: None,
            bottle_displacement_m: 0.0,
        }
    }

    #[test]
    fn the_truth_names_the_accept_or_reject_bin() {
        let scenario = paper(0.05);
        let catalogue = Catalogue::of(&scenario);
        let good = part_record(&scenario, &catalogue, &part("axle_b28", 0.2));
        assert!(good.truly_acceptable && good.clear_cut);
        assert_eq!(good.correct_bin, "group_b");
        assert!((good.true_roundness_mm - 0.2).abs() < 1e-9);
        let bad = part_record(&scenario, &catalogue, &part("axle_c44", 0.8));
        assert!(!bad.truly_acceptable && bad.clear_cut);
        assert_eq!(bad.correct_bin, "reject");
    }

    #[test]
    fn a_clear_cut_part_must_reach_its_own_bin() {
        let scenario = paper(0.05);
        let catalogue = Catalogue::of(&scenario);
        let a20 = part("axle_a20", 0.3);
        let id = PartTypeId(a20.type_index);
        let good = part_record(&scenario, &catalogue, &a20);
        assert!(bin_is_right(&catalogue, id, &good, bin("group_a")));
        assert!(!bin_is_right(&catalogue, id, &good, bin("reject")));
        assert!(!bin_is_right(&catalogue, id, &good, bin("group_b")));
        assert!(!bin_is_right(&catalogue, id, &good, None));
        let in_reject = clean(&a20, Some("reject"));
        let failure = judge_cycle(&scenario, &catalogue, &good, Ok(()), &in_reject);
        let Some(failure) = failure else {
            panic!("a conforming part in the reject bin passed");
        };
        assert_eq!(failure.reason, FailureReason::WrongBin);
        assert_eq!(failure.detail, "part in reject, belongs in group_a");
        let in_own = clean(&a20, Some("group_a"));
        assert_eq!(
            judge_cycle(&scenario, &catalogue, &good, Ok(()), &in_own),
            None
        );
    }

    #[test]
    fn inside_the_uncertainty_band_either_verdict_is_right() {
        let scenario = paper(0.05);
        let catalogue = Catalogue::of(&scenario);
        // 0.47 and 0.53 mm lie within 0.05 mm of the 0.5 mm tolerance.
        for roundness_mm in [0.47, 0.53] {
            let b32 = part("axle_b32", roundness_mm);
            let id = PartTypeId(b32.type_index);
            let record = part_record(&scenario, &catalogue, &b32);
            assert!(!record.clear_cut, "{roundness_mm}");
            assert!(bin_is_right(&catalogue, id, &record, bin("group_b")));
            assert!(bin_is_right(&catalogue, id, &record, bin("reject")));
            // Another type's accept bin is never right.
            assert!(!bin_is_right(&catalogue, id, &record, bin("group_a")));
        }
        // The band is the scenario's: with a narrower one the same part is clear-cut.
        let narrow = paper(0.02);
        let b32 = part("axle_b32", 0.47);
        let record = part_record(&narrow, &catalogue, &b32);
        assert!(record.clear_cut && record.truly_acceptable);
        let id = PartTypeId(b32.type_index);
        assert!(!bin_is_right(&catalogue, id, &record, bin("reject")));
    }

    #[test]
    fn bottles_are_judged_before_the_bin() {
        let scenario = paper(0.05);
        let catalogue = Catalogue::of(&scenario);
        let a24 = part("axle_a24", 0.1);
        let record = part_record(&scenario, &catalogue, &a24);
        let judge = |evidence: &CycleEvidence| {
            judge_cycle(&scenario, &catalogue, &record, Ok(()), evidence)
        };
        let lifted = CycleEvidence {
            bottle_lifted: true,
            ..clean(&a24, Some("group_a"))
        };
        let Some(failure) = judge(&lifted) else {
            panic!("a lifted bottle passed");
        };
        assert_eq!(failure.reason, FailureReason::DistractorPicked);
        let touched = CycleEvidence {
            touch_phase: Some(Phase::Descend),
            bottle_displacement_m: 0.0002,
            ..clean(&a24, Some("group_a"))
        };
        let Some(failure) = judge(&touched) else {
            panic!("a touched bottle passed");
        };
        assert_eq!(failure.reason, FailureReason::DistractorTouched);
        assert!(
            failure.detail.contains("during descend"),
            "{}",
            failure.detail
        );
        // Pushed past the tolerance without a recorded touch (by the part, say).
        let pushed = CycleEvidence {
            bottle_displacement_m: scenario.task.bottle_tolerance_m + 0.001,
            ..clean(&a24, Some("group_a"))
        };
        assert!(pushed.bottle_disturbed(&scenario));
        let Some(failure) = judge(&pushed) else {
            panic!("a pushed bottle passed");
        };
        assert_eq!(failure.reason, FailureReason::DistractorTouched);
        // Moved within the tolerance: not disturbed.
        let nudged = CycleEvidence {
            bottle_displacement_m: scenario.task.bottle_tolerance_m / 2.0,
            ..clean(&a24, Some("group_a"))
        };
        assert_eq!(judge(&nudged), None);
    }

    #[test]
    fn the_controllers_own_failure_comes_first() {
        let scenario = paper(0.05);
        let catalogue = Catalogue::of(&scenario);
        let a24 = part("axle_a24", 0.1);
        let record = part_record(&scenario, &catalogue, &a24);
        let slipped = Failure::new(FailureReason::Slipped, "part slid");
        let lifted = CycleEvidence {
            bottle_lifted: true,
            ..clean(&a24, None)
        };
        let failure = judge_cycle(&scenario, &catalogue, &record, Err(slipped), &lifted);
        let Some(failure) = failure else {
            panic!("a failed cycle passed");
        };
        assert_eq!(failure.reason, FailureReason::Slipped);
    }

    #[test]
    fn a_part_let_through_fails_only_on_the_robots_own_touch() {
        let a24 = part("axle_a24", 0.1);
        // The belt carried the bottles far with the part: not a disturbance.
        let carried = CycleEvidence {
            bottle_displacement_m: 1.2,
            ..clean(&a24, Some("reject"))
        };
        assert_eq!(judge_pass(Ok(()), &carried), None);
        let touched = CycleEvidence {
            touch_phase: Some(Phase::Plan),
            ..carried.clone()
        };
        let failure = judge_pass(Ok(()), &touched).map(|f| f.reason);
        assert_eq!(failure, Some(FailureReason::DistractorTouched));
        let lifted = CycleEvidence {
            bottle_lifted: true,
            ..carried.clone()
        };
        let failure = judge_pass(Ok(()), &lifted).map(|f| f.reason);
        assert_eq!(failure, Some(FailureReason::DistractorPicked));
        let dropped = Failure::new(FailureReason::Dropped, "not in the collector");
        let failure = judge_pass(Err(dropped), &carried).map(|f| f.reason);
        assert_eq!(failure, Some(FailureReason::Dropped));
    }
}
