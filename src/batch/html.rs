//! `report.html`: one self-contained page (no scripts, no network) over one or more batches:
//! the summary table, success with its Wilson interval per batch, failures by reason and a
//! histogram of cycle times, the plots drawn by `plotters` into inline SVG.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::suite::BatchRow;
use super::{BatchReport, Outcome, TRIALS_FILE, TrialRecord, xml_escape};

/// File name of the page.
pub const HTML_FILE: &str = "report.html";

/// Why the page could not be made.
#[derive(Debug, thiserror::Error)]
pub enum HtmlError {
    /// A plot could not be drawn.
    #[error("cannot draw the {plot} plot: {reason}")]
    Plot {
        /// Which plot.
        plot: &'static str,
        /// What went wrong.
        reason: String,
    },
    /// A batch's trial records could not be read.
    #[error("cannot read trial records: {reason}: {}", path.display())]
    Records {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// The page could not be written.
    #[error("cannot write: {source}: {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

fn plot_error<E: std::fmt::Display>(plot: &'static str) -> impl Fn(E) -> HtmlError {
    move |e| HtmlError::Plot {
        plot,
        reason: e.to_string(),
    }
}

/// The upper end of a segmented range of `count` rows. Such a range holds both its ends, so
/// `count - 1` leaves no empty slot; but plotters labels no segment of a one-value range, which
/// one row therefore shares with an empty slot.
fn last_segment(count: u32) -> u32 {
    if count > 1 { count - 1 } else { 1 }
}

/// What a page shows: a title, a note on the perception mode, and labelled batches.
#[derive(Debug, Clone)]
pub struct HtmlPage {
    /// Page title.
    pub title: String,
    /// The perception mode's note.
    pub note: String,
    /// One labelled row per batch (scenario or grid point).
    pub rows: Vec<(String, BatchRow)>,
    /// Cycle times of every successful trial over the batches, s.
    pub cycle_times_s: Vec<f64>,
}

/// Simulated cycle times of the successful trials in `dir/trials.jsonl`, s.
pub fn successful_cycle_times(dir: &Path) -> Result<Vec<f64>, HtmlError> {
    let path = dir.join(TRIALS_FILE);
    let text = fs::read_to_string(&path).map_err(|e| HtmlError::Records {
        path: path.clone(),
        reason: e.to_string(),
    })?;
    let mut times = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let record: TrialRecord = serde_json::from_str(line).map_err(|e| HtmlError::Records {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        if record.outcome == Outcome::Success {
            times.push(record.cycle_time_s);
        }
    }
    Ok(times)
}

impl HtmlPage {
    /// The page of one batch (`twincell run`) whose files are in `dir`.
    pub fn for_batch(report: &BatchReport, dir: &Path) -> Result<Self, HtmlError> {
        Ok(Self {
            title: format!("twincell run: {} (seed {})", report.scenario, report.seed),
            note: report.perception_note.clone(),
            rows: vec![(report.scenario.clone(), BatchRow::from_report(report, "."))],
            cycle_times_s: successful_cycle_times(dir)?,
        })
    }

    /// The page of several batches, each row's files in `root/row.dir`.
    pub fn for_rows(
        title: &str,
        note: &str,
        rows: Vec<(String, BatchRow)>,
        root: &Path,
    ) -> Result<Self, HtmlError> {
        let mut cycle_times_s = Vec::new();
        for (_, row) in &rows {
            cycle_times_s.extend(successful_cycle_times(&root.join(&row.dir))?);
        }
        Ok(Self {
            title: title.to_owned(),
            note: note.to_owned(),
            rows,
            cycle_times_s,
        })
    }

    /// The page as HTML.
    pub fn render(&self) -> Result<String, HtmlError> {
        let mut html = String::new();
        let _ = write!(
            html,
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
             <title>{title}</title><style>\
             body{{font-family:sans-serif;margin:1.5em;color:#222}}\
             table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:3px 8px}}\
             td.n{{text-align:right}}.fail{{color:#b00;font-weight:bold}}\
             figure{{margin:1em 0}}</style></head><body>\n<h1>{title}</h1>\n<p>{note}</p>\n",
            title = xml_escape(&self.title),
            note = xml_escape(&self.note)
        );
        html.push_str(&self.summary_table());
        html.push_str("<h2>Success with its Wilson 95 % interval</h2>\n<figure>");
        html.push_str(&self.success_svg()?);
        html.push_str("</figure>\n<h2>Failures by reason</h2>\n<figure>");
        html.push_str(&self.failures_svg()?);
        html.push_str("</figure>\n<h2>Cycle time of the successful trials</h2>\n<figure>");
        html.push_str(&self.cycle_svg()?);
        html.push_str("</figure>\n</body></html>\n");
        Ok(html)
    }

    /// Writes the page to `dir/report.html`; returns the path.
    pub fn write(&self, dir: &Path) -> Result<PathBuf, HtmlError> {
        let path = dir.join(HTML_FILE);
        let html = self.render()?;
        fs::write(&path, html).map_err(|source| HtmlError::Write {
            path: path.clone(),
            source,
        })?;
        Ok(path)
    }

    fn summary_table(&self) -> String {
        let mut out = String::from(
            "<table><tr><th>#</th><th>batch</th><th>successes</th><th>rate</th>\
             <th>Wilson 95 %</th><th>strict</th><th>mean cycle, s</th><th>failures</th>\
             <th>gate</th></tr>\n",
        );
        for (i, (label, row)) in self.rows.iter().enumerate() {
            let failures: Vec<String> = row
                .failures
                .iter()
                .map(|(reason, n)| format!("{reason} {n}"))
                .collect();
            let cycle = row
                .cycle_time_s
                .as_ref()
                .map_or("-".to_owned(), |c| format!("{:.2}", c.mean));
            let gate = match (&row.gate, row.interrupted) {
                (_, true) => "<span class=\"fail\">interrupted</span>".to_owned(),
                (Some(g), false) if g.passed => format!("&ge; {} passed", g.min_success),
                (Some(g), false) => {
                    format!("<span class=\"fail\">&lt; {} FAILED</span>", g.min_success)
                }
                (None, false) => "-".to_owned(),
            };
            let _ = writeln!(
                out,
                "<tr><td class=\"n\">{i}</td><td>{}</td><td class=\"n\">{}/{}</td>\
                 <td class=\"n\">{:.3}</td><td>[{:.3}, {:.3}]</td><td class=\"n\">{}</td>\
                 <td class=\"n\">{cycle}</td><td>{}</td><td>{gate}</td></tr>",
                xml_escape(label),
                row.successes,
                row.trials,
                row.success_rate,
                row.wilson95[0],
                row.wilson95[1],
                row.strict_successes,
                xml_escape(&failures.join(", ")),
            );
        }
        out.push_str("</table>\n");
        out
    }

    /// Short x labels: the rows' labels when they are short, else their numbers.
    fn x_label(&self, i: usize) -> String {
        let long = self.rows.iter().any(|(label, _)| label.len() > 22);
        match self.rows.get(i) {
            Some((label, _)) if !long => label.clone(),
            Some(_) => format!("#{i}"),
            None => String::new(),
        }
    }

    fn success_svg(&self) -> Result<String, HtmlError> {
        let err = plot_error("success");
        let n = u32::try_from(self.rows.len()).unwrap_or(u32::MAX).max(1);
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (760, 340)).into_drawing_area();
            root.fill(&WHITE).map_err(&err)?;
            let mut chart = ChartBuilder::on(&root)
                .margin(12)
                .x_label_area_size(36)
                .y_label_area_size(52)
                .build_cartesian_2d((0..last_segment(n)).into_segmented(), 0f64..1.02)
                .map_err(&err)?;
            chart
                .configure_mesh()
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 14))
                .disable_x_mesh()
                .y_desc("success rate")
                .x_labels(self.rows.len().max(1))
                .x_label_formatter(&|v| match v {
                    SegmentValue::CenterOf(i) => self.x_label(*i as usize),
                    _ => String::new(),
                })
                .draw()
                .map_err(&err)?;
            let at = |i: usize| SegmentValue::CenterOf(u32::try_from(i).unwrap_or(u32::MAX));
            let band: Vec<_> = self
                .rows
                .iter()
                .enumerate()
                .map(|(i, (_, r))| (at(i), r.wilson95[1]))
                .chain(
                    self.rows
                        .iter()
                        .enumerate()
                        .rev()
                        .map(|(i, (_, r))| (at(i), r.wilson95[0])),
                )
                .collect();
            chart
                .draw_series(std::iter::once(Polygon::new(band, BLUE.mix(0.15))))
                .map_err(&err)?;
            let line: Vec<_> = self
                .rows
                .iter()
                .enumerate()
                .map(|(i, (_, r))| (at(i), r.success_rate))
                .collect();
            chart
                .draw_series(std::iter::once(PathElement::new(
                    line,
                    BLUE.stroke_width(2),
                )))
                .map_err(&err)?;
            chart
                .draw_series(self.rows.iter().enumerate().map(|(i, (_, r))| {
                    PathElement::new(
                        vec![(at(i), r.wilson95[0]), (at(i), r.wilson95[1])],
                        BLACK.stroke_width(1),
                    )
                }))
                .map_err(&err)?;
            chart
                .draw_series(
                    self.rows
                        .iter()
                        .enumerate()
                        .map(|(i, (_, r))| Circle::new((at(i), r.success_rate), 4, BLUE.filled())),
                )
                .map_err(&err)?;
            root.present().map_err(&err)?;
        }
        Ok(svg)
    }

    fn failures_svg(&self) -> Result<String, HtmlError> {
        let err = plot_error("failures");
        let mut totals: BTreeMap<&str, u32> = BTreeMap::new();
        for (_, row) in &self.rows {
            for (reason, n) in &row.failures {
                *totals.entry(reason.as_str()).or_default() += n;
            }
        }
        let reasons: Vec<(&str, u32)> = totals.into_iter().collect();
        let k = u32::try_from(reasons.len()).unwrap_or(u32::MAX).max(1);
        let most = reasons.iter().map(|(_, n)| *n).max().unwrap_or(0).max(1);
        let mut svg = String::new();
        {
            let height = 80 + 28 * k;
            let root = SVGBackend::with_string(&mut svg, (760, height)).into_drawing_area();
            root.fill(&WHITE).map_err(&err)?;
            let mut chart = ChartBuilder::on(&root)
                .margin(12)
                .x_label_area_size(36)
                .y_label_area_size(170)
                .build_cartesian_2d(0u32..most + 1, (0..last_segment(k)).into_segmented())
                .map_err(&err)?;
            chart
                .configure_mesh()
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 14))
                .disable_y_mesh()
                .x_desc(if reasons.is_empty() {
                    "no failures"
                } else {
                    "trials failed, all batches"
                })
                .y_labels(reasons.len().max(1))
                .y_label_formatter(&|v| match v {
                    SegmentValue::CenterOf(i) => reasons
                        .get(*i as usize)
                        .map_or(String::new(), |(r, _)| (*r).to_owned()),
                    _ => String::new(),
                })
                .draw()
                .map_err(&err)?;
            chart
                .draw_series(reasons.iter().zip(0u32..).map(|((_, n), i)| {
                    let mut bar = Rectangle::new(
                        [
                            (0, SegmentValue::Exact(i)),
                            (*n, SegmentValue::Exact(i + 1)),
                        ],
                        RED.mix(0.6).filled(),
                    );
                    bar.set_margin(3, 3, 0, 0);
                    bar
                }))
                .map_err(&err)?;
            root.present().map_err(&err)?;
        }
        Ok(svg)
    }

    fn cycle_svg(&self) -> Result<String, HtmlError> {
        let err = plot_error("cycle time");
        let times = &self.cycle_times_s;
        let low = times.iter().copied().fold(f64::INFINITY, f64::min);
        let high = times.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let (low, high) = if low.is_finite() && high.is_finite() {
            (low, high)
        } else {
            (0.0, 1.0)
        };
        let width = ((high - low) / 20.0).max(0.1);
        let bins = ((high - low) / width).floor() as usize + 1;
        let mut counts = vec![0u32; bins];
        for t in times {
            let bin = (((t - low) / width).floor() as usize).min(bins - 1);
            counts[bin] += 1;
        }
        let most = counts.iter().copied().max().unwrap_or(0).max(1);
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (760, 300)).into_drawing_area();
            root.fill(&WHITE).map_err(&err)?;
            let x_end = low + width * bins as f64;
            let mut chart = ChartBuilder::on(&root)
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(52)
                .build_cartesian_2d(low..x_end, 0u32..most + 1)
                .map_err(&err)?;
            chart
                .configure_mesh()
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 14))
                .x_desc(if times.is_empty() {
                    "no successful trial"
                } else {
                    "simulated cycle time, s"
                })
                .y_desc("trials")
                .draw()
                .map_err(&err)?;
            chart
                .draw_series(counts.iter().enumerate().map(|(i, &c)| {
                    let x0 = low + width * i as f64;
                    Rectangle::new([(x0, 0), (x0 + width, c)], GREEN.mix(0.6).filled())
                }))
                .map_err(&err)?;
            root.present().map_err(&err)?;
        }
        Ok(svg)
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Perception, ReportMeta};
    use super::*;
    use crate::outcome::FailureReason;

    fn row(successes: u32, failures: u32) -> BatchRow {
        let records: Vec<TrialRecord> = (0..successes + failures)
            .map(|i| {
                let mut r = TrialRecord::failed(i, u64::from(i), FailureReason::Collision, "x");
                if i < successes {
                    r.outcome = Outcome::Success;
                    r.failure = None;
                    r.cycle_time_s = 17.0 + f64::from(i) * 0.1;
                }
                r
            })
            .collect();
        let meta = ReportMeta {
            scenario: "s<&>".into(),
            seed: 1,
            perception: Perception::Oracle,
            scenario_trials: successes + failures,
            shard: None,
            interrupted: false,
            min_success: Some(0.9),
        };
        BatchRow::from_report(&BatchReport::from_records(&meta, &records), "d")
    }

    #[test]
    fn the_page_holds_the_table_and_three_plots_and_nothing_external() {
        let page = HtmlPage {
            title: "t & t".into(),
            note: "oracle".into(),
            rows: vec![("a<b".into(), row(9, 1)), ("c".into(), row(3, 3))],
            cycle_times_s: vec![17.0, 17.4, 18.2, 18.25],
        };
        let html = page.render().expect("page");
        assert_eq!(html.matches("<svg").count(), 3, "{html}");
        assert!(html.contains("a&lt;b") && !html.contains("a<b"));
        assert!(html.contains("collision 1") && html.contains("collision 3"));
        assert!(html.contains("FAILED"), "the second row misses its gate");
        for external in ["http://", "https://", "<script", "src="] {
            let outside_svg_namespace = html.replace("http://www.w3.org/2000/svg", "");
            assert!(!outside_svg_namespace.contains(external), "{external}");
        }
        // Every failure reason is a label of the failures plot.
        assert!(html.contains("\ncollision\n</text>"), "{html}");
    }

    #[test]
    fn an_empty_page_still_draws() {
        let page = HtmlPage {
            title: "empty".into(),
            note: String::new(),
            rows: vec![("none".into(), row(0, 0))],
            cycle_times_s: Vec::new(),
        };
        let html = page.render().expect("page");
        assert_eq!(html.matches("<svg").count(), 3);
        assert!(html.contains("no failures") && html.contains("no successful trial"));
    }
}
