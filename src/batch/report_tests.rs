//! Unit tests of `report.json`'s statistics.

use super::report::*;
use super::*;
use crate::batch::{DecisionRecord, FailureReason, PartRecord};

fn close(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() < 5e-5 && (a[1] - b[1]).abs() < 5e-5
}

#[test]
fn wilson_matches_known_values() {
    let w = wilson_interval(49, 50, Z95);
    assert!(close(w, [0.8950, 0.9965]), "{w:?}");
    let w = wilson_interval(0, 10, Z95);
    assert!(close(w, [0.0, 0.2775]), "{w:?}");
    let w = wilson_interval(10, 10, Z95);
    assert!(close(w, [0.7225, 1.0]), "{w:?}");
    let w = wilson_interval(5, 10, Z95);
    assert!(close(w, [0.2366, 0.7634]), "{w:?}");
    assert_eq!(wilson_interval(0, 0, Z95), [0.0, 1.0]);
}

#[test]
fn percentile_is_nearest_rank() {
    let v: Vec<f64> = (1..=20).map(f64::from).collect();
    assert_eq!(percentile(&v, 0.95), Some(19.0));
    assert_eq!(percentile(&v, 0.5), Some(10.0));
    assert_eq!(percentile(&[3.0], 0.95), Some(3.0));
    assert_eq!(percentile(&[], 0.5), None);
}

fn record(trial: u32, ok: bool) -> TrialRecord {
    let mut r = if ok {
        let mut r = TrialRecord::failed(trial, 0, FailureReason::Timeout, "");
        r.outcome = Outcome::Success;
        r.failure = None;
        r.detail = None;
        r
    } else {
        TrialRecord::failed(trial, 0, FailureReason::Slipped, "slid")
    };
    r.part = Some(PartRecord {
        part_type: "a".into(),
        true_roundness_mm: 0.1,
        true_bore_diameter_mm: 20.0,
        truly_acceptable: true,
        clear_cut: true,
        correct_bin: "a".into(),
    });
    r.decision = Some(DecisionRecord {
        detected_type: if ok { "a" } else { "b" }.into(),
        measured_roundness_mm: Some(0.1 + 0.01 * f64::from(trial)),
        measured_bore_diameter_mm: None,
        accept: ok,
        bin: "a".into(),
        note: None,
    });
    r.cycle_time_s = 10.0;
    r
}

#[test]
fn report_counts_from_records() {
    let meta = ReportMeta {
        scenario: "s".into(),
        seed: 1,
        perception: Perception::Oracle,
        scenario_trials: 4,
        shard: None,
        interrupted: false,
        min_success: Some(0.8),
    };
    let records: Vec<_> = (0..4).map(|i| record(i, i != 2)).collect();
    let report = BatchReport::from_records(&meta, &records);
    assert_eq!((report.trials, report.successes), (4, 3));
    assert_eq!(report.failures.get("slipped"), Some(&1));
    assert_eq!(report.sorting.accept_reject.truly_accept.accept, 3);
    assert_eq!(report.sorting.accept_reject.truly_accept.reject, 1);
    assert_eq!(report.sorting.part_type["a"]["b"], 1);
    let roundness = report.metrology.roundness_error_mm.as_ref();
    assert!((roundness.map_or(0.0, |s| s.max_mm) - 0.03).abs() < 1e-12);
    assert!(report.metrology.bore_diameter_error_mm.is_none());
    // 3 parts over 40 s of cycle time.
    assert!((report.parts_per_minute.unwrap_or(0.0) - 4.5).abs() < 1e-12);
    assert_eq!(report.gate.as_ref().map(|g| g.passed), Some(false));
    assert_eq!(exit_code(&report), 1);
    let table = report.summary_table();
    assert!(table.contains("ORACLE"), "{table}");
    assert!(table.contains("slipped"), "{table}");
    let json = serde_json::to_value(&report).unwrap_or_default();
    assert_eq!(json["perception"], "oracle");
}

#[test]
fn unidentified_parts_are_counted_and_shown_apart_from_wrong_types() {
    let meta = ReportMeta {
        scenario: "s".into(),
        seed: 1,
        perception: Perception::Camera,
        scenario_trials: 3,
        shard: None,
        interrupted: false,
        min_success: None,
    };
    let mut records: Vec<_> = (0..3).map(|i| record(i, i == 0)).collect();
    if let Some(d) = records[2].decision.as_mut() {
        d.detected_type = crate::scenario::UNIDENTIFIED.into();
        d.note = Some("no type fits the end face".into());
    }
    let report = BatchReport::from_records(&meta, &records);
    assert_eq!(report.sorting.unidentified, 1);
    assert_eq!(report.sorting.part_type["a"]["unidentified"], 1);
    assert_eq!(report.listing.identified["a"]["unidentified"], 1);
    let table = report.summary_table();
    assert!(
        table.contains("1 parts of the wrong detected type, 1 unidentified"),
        "{table}"
    );
    let json = serde_json::to_value(&report).unwrap_or_default();
    assert_eq!(json["sorting"]["unidentified"], 1);
}

#[test]
fn faults_are_tallied_per_kind_and_absent_from_a_report_without_them() {
    use crate::outcome::{FaultAction, FaultKind, FaultRecord};
    let meta = ReportMeta {
        scenario: "f".into(),
        seed: 2,
        perception: Perception::Camera,
        scenario_trials: 4,
        shard: None,
        interrupted: false,
        min_success: None,
    };
    let mut records: Vec<_> = (0..4).map(|i| record(i, true)).collect();
    let plain =
        serde_json::to_value(BatchReport::from_records(&meta, &records)).unwrap_or_default();
    assert!(plain.get("faults").is_none(), "{plain}");
    let fault = |kind, recovered, lost_parts| FaultRecord {
        kind,
        at_s: 2.0,
        detail: "test".into(),
        actions: vec![FaultAction::SawDrop],
        recovered,
        lost_parts,
        saw_lying_part: None,
    };
    records[0].faults.push(fault(FaultKind::Gripper, true, 0));
    records[1].faults.push(fault(FaultKind::Gripper, false, 1));
    records[1].faults.push(fault(FaultKind::Camera, true, 0));
    let report = BatchReport::from_records(&meta, &records);
    let json = serde_json::to_value(&report).unwrap_or_default();
    assert_eq!(
        json["faults"]["gripper"],
        serde_json::json!({"injected": 2, "recovered": 1, "lost": 1})
    );
    assert_eq!(json["faults"]["camera"]["recovered"], 1);
    assert!(json["faults"].get("belt").is_none());
    let back: BatchReport = serde_json::from_value(json).expect("reads back");
    assert_eq!(back.faults, report.faults);
    // The page's table lists each kind that struck, and is left out when none did.
    let table = super::html_faults::faults_table(&[("f<1>", &report.faults)]);
    assert!(table.contains("<h2>Faults injected</h2>"), "{table}");
    assert!(
        table.contains(
            "<td>f&lt;1&gt;</td><td>gripper</td><td class=\"n\">2</td>\
             <td class=\"n\">1</td><td class=\"n\">0.500</td><td class=\"n\">1</td>"
        ),
        "{table}"
    );
    assert!(table.contains("<td>camera</td>") && !table.contains("<td>belt</td>"));
    let plain = BatchReport::from_records(&meta, &records[2..]);
    assert_eq!(
        super::html_faults::faults_table(&[("p", &plain.faults)]),
        ""
    );
    // Suite and sweep rows carry the tally too.
    assert_eq!(BatchRow::from_report(&report, ".").faults, report.faults);
}

#[test]
fn passed_and_removals_are_counted_apart_from_successes_and_failures() {
    let meta = ReportMeta {
        scenario: "s".into(),
        seed: 1,
        perception: Perception::Camera,
        scenario_trials: 5,
        shard: None,
        interrupted: false,
        min_success: Some(0.5),
    };
    let mut records: Vec<_> = (0..5).map(|i| record(i, i < 2)).collect();
    // Trial 1 sorted its part after removing two bottles.
    records[1].removals = 2;
    // Trials 2 and 3 let their part through; trial 3's robot touched a bottle on the way.
    for r in &mut records[2..4] {
        r.outcome = Outcome::Passed;
        r.failure = None;
        r.detail = Some("unpickable: no grasp clear".into());
    }
    records[3].distractor_touched = true;
    let report = BatchReport::from_records(&meta, &records);
    assert_eq!((report.trials, report.successes, report.passed), (5, 2, 2));
    assert!((report.passed_rate - 0.4).abs() < 1e-12);
    // Safe: the two sorted and the one passed untouched.
    assert_eq!(report.safe, 3);
    assert!((report.safe_rate - 0.6).abs() < 1e-12);
    assert_eq!(report.removals, 2);
    // Passed trials are not failures, and the gate stays on success.
    assert_eq!(report.failures.values().sum::<u32>(), 1);
    assert!((report.success_rate - 0.4).abs() < 1e-12);
    assert!(report.gate.as_ref().is_some_and(|g| !g.passed));
    let junit = super::junit::junit_xml(&report);
    assert!(
        junit.contains(r#"tests="5" failures="1" errors="0" skipped="2""#),
        "{junit}"
    );
    assert_eq!(junit.matches("<skipped message=\"passed\">").count(), 2);
    let json = serde_json::to_value(&report).expect("json");
    for key in ["passed", "passed_rate", "safe", "safe_rate", "removals"] {
        assert!(json.get(key).is_some(), "report.json lacks {key}");
    }
    let table = report.summary_table();
    assert!(table.contains("safe rate"), "{table}");
}
