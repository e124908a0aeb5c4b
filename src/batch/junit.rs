//! `junit.xml`: one test case per trial, so CI systems show trials the way they show tests.

use std::fmt::Write as _;

use super::{BatchReport, Outcome};

/// Text made safe for XML 1.0 content and attribute values.
///
/// Escapes the five markup characters and replaces characters XML 1.0 forbids (control
/// characters other than tab, newline and carriage return) with U+FFFD, so a panic message
/// holding arbitrary bytes still yields a well-formed document.
pub fn xml_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // Attribute values normalise raw whitespace; keep it by reference.
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            '\t' => out.push_str("&#9;"),
            c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => out.push('\u{FFFD}'),
            c => out.push(c),
        }
    }
    out
}

/// The test-case name of trial `index`: `trial_0007`.
pub fn testcase_name(index: u32) -> String {
    format!("trial_{index:04}")
}

/// `junit.xml` for `report`: its figures and its listed trials, in the listing's order.
///
/// One `<testsuite>` named after the scenario; each trial is a `<testcase>` whose `time` is its
/// wall-clock seconds; a failed trial carries `<failure message="reason" type="reason">detail`.
pub fn junit_xml(report: &BatchReport) -> String {
    let suite = xml_escape(&report.scenario);
    // A part let through as unpickable is neither sorted nor failed: JUnit's `skipped`.
    let skipped = report.passed;
    let failures = report.trials.saturating_sub(report.successes + skipped);
    let trials = &report.listing.trials;
    let total_s: f64 = trials.iter().map(|t| t.wall_ms).sum::<f64>() / 1000.0;
    let mut out = String::new();
    // Writing to a String cannot fail; the results are ignored on purpose.
    let _ = writeln!(out, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        out,
        r#"<testsuites name="twincell" tests="{}" failures="{failures}" errors="0" time="{total_s:.3}">"#,
        report.trials
    );
    let _ = writeln!(
        out,
        r#"  <testsuite name="{suite}" tests="{}" failures="{failures}" errors="0" skipped="{skipped}" time="{total_s:.3}">"#,
        report.trials
    );
    let _ = writeln!(out, "    <properties>");
    let mut properties = vec![
        ("seed", report.seed.to_string()),
        ("perception", report.perception.as_str().to_owned()),
        ("scenario_trials", report.scenario_trials.to_string()),
        ("interrupted", report.interrupted.to_string()),
    ];
    if let Some(shard) = report.shard {
        properties.push(("shard", shard.to_string()));
    }
    for (name, value) in properties {
        let _ = writeln!(
            out,
            r#"      <property name="{name}" value="{}"/>"#,
            xml_escape(&value)
        );
    }
    let _ = writeln!(out, "    </properties>");
    for trial in trials {
        let name = testcase_name(trial.trial);
        let time_s = trial.wall_ms / 1000.0;
        if trial.outcome == Outcome::Passed {
            let detail = xml_escape(trial.detail.as_deref().unwrap_or(""));
            let _ = writeln!(
                out,
                r#"    <testcase name="{name}" classname="{suite}" time="{time_s:.3}">"#
            );
            let _ = writeln!(out, r#"      <skipped message="passed">{detail}</skipped>"#);
            let _ = writeln!(out, "    </testcase>");
            continue;
        }
        let Some(reason) = trial.failure_reason() else {
            let _ = writeln!(
                out,
                r#"    <testcase name="{name}" classname="{suite}" time="{time_s:.3}"/>"#
            );
            continue;
        };
        let detail = xml_escape(trial.detail.as_deref().unwrap_or(""));
        let _ = writeln!(
            out,
            r#"    <testcase name="{name}" classname="{suite}" time="{time_s:.3}">"#
        );
        let _ = writeln!(
            out,
            r#"      <failure message="{reason}" type="{reason}">{detail}</failure>"#
        );
        let _ = writeln!(out, "    </testcase>");
    }
    let _ = writeln!(out, "  </testsuite>");
    let _ = writeln!(out, "</testsuites>");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_forbidden_characters() {
        assert_eq!(
            xml_escape("a<b & \"c\" 'd'>\u{1}\n"),
            "a&lt;b &amp; &quot;c&quot; &apos;d&apos;&gt;\u{FFFD}&#10;"
        );
        assert_eq!(testcase_name(7), "trial_0007");
        assert_eq!(testcase_name(12345), "trial_12345");
    }
}
