//! `report.html`: one self-contained page (no scripts, no network) over one or more batches:
//! the summary table, success with its Wilson interval per batch, failures by reason, the
//! accept/reject and type confusion matrices, measured against true roundness, a histogram of
//! cycle times (the plots drawn by `plotters` into inline SVG), and every failed or misjudged
//! trial with its camera frame embedded.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use super::html_trials::{PageSorting, TrialCard, cards_html, read_records, trial_card};
use super::suite::BatchRow;
use super::{BatchReport, Outcome, Perception, xml_escape};
use crate::scenario::Scenario;

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

/// The roundness tolerance and the uncertainty band about it, as the scatter plot draws them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoundnessLimits {
    /// Parts with a true roundness up to this conform, mm.
    pub tolerance_mm: f64,
    /// Half-width of the band about the tolerance where either verdict counts as right, mm.
    pub uncertainty_mm: f64,
}

impl RoundnessLimits {
    /// The limits of `scenario`.
    pub fn of(scenario: &Scenario) -> Self {
        Self {
            tolerance_mm: scenario.roundness_tolerance_mm,
            uncertainty_mm: scenario.roundness_uncertainty_mm,
        }
    }

    /// The limits all `scenarios` share; `None` when they differ or there are none.
    pub fn shared<'a>(scenarios: impl IntoIterator<Item = &'a Scenario>) -> Option<Self> {
        let mut limits = scenarios.into_iter().map(Self::of);
        let first = limits.next()?;
        limits.all(|l| l == first).then_some(first)
    }
}

/// What a page shows: a title, a note on the perception mode, labelled batches, and what their
/// records say.
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
    /// Decisions against the truth over the batches.
    pub sorting: PageSorting,
    /// The tolerance and band the scatter plot draws, when the batches share them.
    pub roundness_limits: Option<RoundnessLimits>,
    /// Every failed or misjudged trial, batch by batch in trial order.
    pub cards: Vec<TrialCard>,
}

/// Simulated cycle times of the sorted parts in `dir/trials.jsonl` (each part's own, as in
/// `report.json`'s `cycle_time_s`), s.
pub fn successful_cycle_times(dir: &Path) -> Result<Vec<f64>, HtmlError> {
    Ok(read_records(dir)?
        .iter()
        .flat_map(sorted_cycle_times)
        .collect())
}

/// The pick cycles of `record`'s sorted parts, s.
fn sorted_cycle_times(record: &crate::outcome::TrialRecord) -> Vec<f64> {
    record
        .parts()
        .iter()
        .filter(|p| p.outcome == Outcome::Success)
        .map(|p| p.cycle_time_s)
        .collect()
}

impl HtmlPage {
    /// The page of one batch (`twincell run`) whose files are in `dir`.
    pub fn for_batch(report: &BatchReport, dir: &Path) -> Result<Self, HtmlError> {
        let title = format!("twincell run: {} (seed {})", report.scenario, report.seed);
        let rows = vec![(report.scenario.clone(), BatchRow::from_report(report, "."))];
        Ok(Self {
            note: report.perception_note.clone(),
            ..Self::for_rows(&title, report.perception, rows, dir)?
        })
    }

    /// The page of several batches run with `perception`, each row's files in
    /// `root/row.dir`.
    pub fn for_rows(
        title: &str,
        perception: Perception,
        rows: Vec<(String, BatchRow)>,
        root: &Path,
    ) -> Result<Self, HtmlError> {
        let mut cycle_times_s = Vec::new();
        let mut sorting = PageSorting::default();
        let mut cards = Vec::new();
        for (label, row) in &rows {
            let dir = root.join(&row.dir);
            for record in read_records(&dir)? {
                cycle_times_s.extend(sorted_cycle_times(&record));
                sorting.add(&record);
                cards.extend(trial_card(label, &dir, perception, &record)?);
            }
        }
        Ok(Self {
            title: title.to_owned(),
            note: perception.note().to_owned(),
            rows,
            cycle_times_s,
            sorting,
            roundness_limits: None,
            cards,
        })
    }

    /// The page with the scatter plot's tolerance and band.
    pub fn with_roundness_limits(mut self, limits: Option<RoundnessLimits>) -> Self {
        self.roundness_limits = limits;
        self
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
             figure{{margin:1em 0}}.small{{font-size:85%;color:#555}}\
             .cards{{display:flex;flex-wrap:wrap;gap:12px}}\
             .card{{width:320px;margin:0;border:1px solid #ccc;padding:4px;font-size:85%}}\
             .card img{{display:block;width:320px;height:auto}}\
             .noimg{{width:320px;height:60px;background:#eee;color:#555;padding:4px;\
             box-sizing:border-box}}</style></head><body>\n\
             <h1>{title}</h1>\n<p>{note}</p>\n",
            title = xml_escape(&self.title),
            note = xml_escape(&self.note)
        );
        html.push_str(&self.summary_table());
        html.push_str(&super::html_faults::faults_table(&self.rows));
        html.push_str("<h2>Success with its Wilson 95 % interval</h2>\n<figure>");
        html.push_str(&self.success_svg()?);
        html.push_str("</figure>\n<h2>Failures by reason</h2>\n<figure>");
        html.push_str(&self.failures_svg()?);
        html.push_str("</figure>\n<h2>Accept or reject against the truth</h2>\n");
        html.push_str(&self.sorting.accept_reject_table());
        html.push_str("<h2>Part type against the truth</h2>\n");
        html.push_str(&self.sorting.type_table());
        html.push_str("<h2>Measured against true roundness</h2>\n<figure>");
        html.push_str(&self.roundness_svg()?);
        html.push_str("</figure>\n<h2>Cycle time of the successful trials</h2>\n<figure>");
        html.push_str(&self.cycle_svg()?);
        let _ = write!(
            html,
            "</figure>\n<h2>Failed and misjudged trials ({})</h2>\n\
             <p class=\"small\">Camera frames with the detector's boxes (parts amber, bottles \
             magenta), the fitted bore (red) and its edge points (green).</p>\n",
            self.cards.len()
        );
        html.push_str(&cards_html(&self.cards));
        html.push_str("</body></html>\n");
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
}

#[cfg(test)]
mod tests {
    use super::super::html_trials::CardImage;
    use super::super::{
        DecisionRecord, Misidentification, PartRecord, ReportMeta, StreamRecord, TRIALS_FILE,
        TrialRecord, trial_image_path,
    };
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

    fn page(rows: Vec<(String, BatchRow)>, cycle_times_s: Vec<f64>) -> HtmlPage {
        HtmlPage {
            title: "t & t".into(),
            note: "oracle".into(),
            rows,
            cycle_times_s,
            sorting: PageSorting::default(),
            roundness_limits: None,
            cards: Vec::new(),
        }
    }

    #[test]
    fn the_page_holds_the_table_and_four_plots_and_nothing_external() {
        let page = page(
            vec![("a<b".into(), row(9, 1)), ("c".into(), row(3, 3))],
            vec![17.0, 17.4, 18.2, 18.25],
        );
        let html = page.render().expect("page");
        assert_eq!(html.matches("<svg").count(), 4, "{html}");
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
        let page = page(vec![("none".into(), row(0, 0))], Vec::new());
        let html = page.render().expect("page");
        assert_eq!(html.matches("<svg").count(), 4);
        assert!(html.contains("no failures") && html.contains("no successful trial"));
        assert!(html.contains("no part measured") && html.contains("No trial failed"));
    }

    fn part(part_type: &str, roundness_mm: f64) -> PartRecord {
        PartRecord {
            part_type: part_type.into(),
            true_roundness_mm: roundness_mm,
            true_bore_diameter_mm: 28.0,
            truly_acceptable: roundness_mm <= 0.5,
            clear_cut: (roundness_mm - 0.5).abs() > 0.05,
            correct_bin: if roundness_mm <= 0.5 {
                "group_b"
            } else {
                "reject"
            }
            .into(),
        }
    }

    fn decided(i: u32, part: PartRecord, detected: &str, measured_mm: f64) -> TrialRecord {
        let accept = measured_mm <= 0.5;
        let mut r = TrialRecord::failed(i, u64::from(i) + 100, FailureReason::WrongBin, "w");
        r.decision = Some(DecisionRecord {
            detected_type: detected.into(),
            measured_roundness_mm: Some(measured_mm),
            measured_bore_diameter_mm: Some(28.1),
            accept,
            bin: if accept { "group_b" } else { "reject" }.into(),
            note: None,
        });
        r.placed_bin = Some(r.decision.as_ref().map_or(String::new(), |d| d.bin.clone()));
        if accept == part.truly_acceptable || !part.clear_cut {
            r.outcome = Outcome::Success;
            r.failure = None;
            r.detail = None;
            r.cycle_time_s = 18.0;
        }
        r.part = Some(part);
        r
    }

    /// A batch directory with records of every kind the page reads, and one camera frame.
    fn batch_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("twincell-html-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("dir");
        let mut stream = TrialRecord::failed(4, 104, FailureReason::Misidentified, "took it");
        stream.stream = Some(StreamRecord {
            parts_planned: 3,
            parts_sorted: 0,
            bottles_passed: 2,
            belt_stops: 3,
            parts: Vec::new(),
            misidentified: Some(Misidentification {
                truth: "bottle".into(),
                identified: "axle_b28".into(),
            }),
        });
        let mut missed = TrialRecord::failed(5, 105, FailureReason::NotDetected, "nothing");
        missed.part = Some(part("axle_b32", 0.1));
        let records = [
            decided(0, part("axle_b28", 0.2), "axle_b28", 0.21),
            // Wrong verdict, clear-cut: a failure.
            decided(1, part("axle_b28", 0.8), "axle_b28", 0.45),
            // Inside the band, rejected while conforming: a misjudged success.
            decided(2, part("axle_b28", 0.48), "axle_b28", 0.52),
            // Right verdict on the wrong type.
            decided(3, part("axle_b32", 0.1), "axle_b28", 0.12),
            stream,
            missed,
        ];
        let text: String = records
            .iter()
            .map(|r| serde_json::to_string(r).expect("json") + "\n")
            .collect();
        fs::write(dir.join(TRIALS_FILE), text).expect("records");
        let image = image::RgbImage::from_pixel(32, 24, image::Rgb([200, 10, 10]));
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new(&mut jpeg)
            .encode_image(&image)
            .expect("jpeg");
        let path = trial_image_path(&dir, 1);
        fs::create_dir_all(path.parent().expect("parent")).expect("images dir");
        fs::write(path, jpeg).expect("image");
        dir
    }

    #[test]
    fn the_page_reads_decisions_and_frames_from_the_records() {
        let dir = batch_dir("camera");
        let page = HtmlPage::for_rows("t", Perception::Camera, vec![("b".into(), row(1, 0))], &dir)
            .map(|p| {
                p.with_roundness_limits(Some(RoundnessLimits {
                    tolerance_mm: 0.5,
                    uncertainty_mm: 0.05,
                }))
            });
        // The row's dir is "d", which does not exist: the records are read from there.
        assert!(page.is_err());
        let mut only = row(1, 0);
        only.dir = ".".into();
        let page = HtmlPage::for_rows("t", Perception::Camera, vec![("b".into(), only)], &dir)
            .expect("page")
            .with_roundness_limits(Some(RoundnessLimits {
                tolerance_mm: 0.5,
                uncertainty_mm: 0.05,
            }));
        let c = &page.sorting.accept_reject;
        assert_eq!((c.truly_accept.accept, c.truly_accept.reject), (2, 1));
        assert_eq!((c.truly_reject.accept, c.truly_reject.reject), (1, 0));
        assert_eq!(page.sorting.in_band, 1);
        let types = &page.sorting.types;
        assert_eq!(types["axle_b28"]["axle_b28"], 3);
        assert_eq!(types["axle_b32"]["axle_b28"], 1);
        assert_eq!(types["axle_b32"]["not detected"], 1);
        assert_eq!(types["bottle"]["bottle"], 2);
        assert_eq!(types["bottle"]["axle_b28"], 1);
        assert_eq!(page.sorting.roundness_mm.len(), 4);
        // Failed (1, 4, 5) and misjudged (2, 3) trials get cards, in trial order; only trial 1
        // has a frame on disk.
        let cards: Vec<(u32, &str)> = page
            .cards
            .iter()
            .map(|c| (c.trial, c.reason.as_str()))
            .collect();
        assert_eq!(
            cards,
            [
                (1, "wrong_bin"),
                (2, "misjudged"),
                (3, "misjudged"),
                (4, "misidentified"),
                (5, "not_detected")
            ]
        );
        assert!(matches!(page.cards[0].image, CardImage::Jpeg(_)));
        assert!(
            page.cards[1..]
                .iter()
                .all(|c| c.image == CardImage::Missing)
        );
        assert!(
            page.cards[1].judgement.contains("(misjudged)"),
            "{:?}",
            page.cards[1]
        );
        let html = page.render().expect("render");
        assert_eq!(html.matches("<svg").count(), 4);
        assert_eq!(html.matches("src=\"data:image/jpeg;base64,").count(), 1);
        assert_eq!(html.matches("no camera frame").count(), 4);
        assert_eq!(html.matches("<table class=\"cm\">").count(), 2);
        assert!(html.contains("<th>not detected</th>") && html.contains("<th>bottle</th>"));
        let oracle = HtmlPage::for_rows("t", Perception::Oracle, page.rows.clone(), &dir)
            .expect("page")
            .render()
            .expect("render");
        assert_eq!(
            oracle.matches("oracle perception: no camera image").count(),
            5
        );
        assert!(!oracle.contains("data:image"));
        let _ = fs::remove_dir_all(&dir);
    }
}
