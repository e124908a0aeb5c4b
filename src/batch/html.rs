//! `report.html`: one self-contained page (no scripts, no network) over one or more batches,
//! rendered from their [`BatchReport`]s alone (the records are not read again; the camera
//! frames are read from each batch's `images/`): the summary table, success with its Wilson interval per batch, failures by reason, the
//! accept/reject and type confusion matrices, measured against true roundness, a histogram of
//! the sorted parts' cycle times (the plots drawn by `plotters` into inline SVG), and every failed or misjudged
//! trial with its camera frame embedded.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use super::html_trials::{PageSorting, TrialCard, cards_html, trial_card};
use super::{BatchReport, Perception, xml_escape};
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
    /// A saved camera frame could not be read.
    #[error("cannot read a camera frame: {reason}: {}", path.display())]
    Image {
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

/// One batch of a page: its label, its output directory (for the camera frames) and its report.
#[derive(Debug, Clone)]
pub struct PageBatch {
    /// The batch's label on the page (scenario or grid point).
    pub label: String,
    /// The batch's output directory.
    pub dir: PathBuf,
    /// The batch's report, as built from its records.
    pub report: BatchReport,
}

/// What a page shows: a title, a note on the perception mode, labelled batches, and what their
/// reports say.
#[derive(Debug, Clone)]
pub struct HtmlPage {
    /// Page title.
    pub title: String,
    /// The perception mode's note.
    pub note: String,
    /// One labelled batch per row (scenario or grid point).
    pub rows: Vec<PageBatch>,
    /// The pick cycles of every sorted part over the batches, s.
    pub cycle_times_s: Vec<f64>,
    /// Decisions against the truth over the batches.
    pub sorting: PageSorting,
    /// The tolerance and band the scatter plot draws, when the batches share them.
    pub roundness_limits: Option<RoundnessLimits>,
    /// Every failed or misjudged trial, batch by batch in trial order.
    pub cards: Vec<TrialCard>,
}

impl HtmlPage {
    /// The page of one batch (`twincell run`, `twincell merge`) whose files are in `dir`.
    pub fn for_batch(report: &BatchReport, dir: &Path) -> Result<Self, HtmlError> {
        let title = format!("twincell run: {} (seed {})", report.scenario, report.seed);
        let batch = PageBatch {
            label: report.scenario.clone(),
            dir: dir.to_path_buf(),
            report: report.clone(),
        };
        Ok(Self {
            note: report.perception_note.clone(),
            ..Self::for_batches(&title, report.perception, vec![batch])?
        })
    }

    /// The page of several batches run with `perception`.
    pub fn for_batches(
        title: &str,
        perception: Perception,
        rows: Vec<PageBatch>,
    ) -> Result<Self, HtmlError> {
        let mut cycle_times_s = Vec::new();
        let mut sorting = PageSorting::default();
        let mut cards = Vec::new();
        for batch in &rows {
            let listing = &batch.report.listing;
            cycle_times_s.extend_from_slice(&listing.sorted_cycle_times_s);
            sorting.add(&batch.report);
            for trial in &listing.trials {
                cards.extend(trial_card(&batch.label, &batch.dir, perception, trial)?);
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
        let faults: Vec<_> = self
            .rows
            .iter()
            .map(|b| (b.label.as_str(), &b.report.faults))
            .collect();
        html.push_str(&super::html_faults::faults_table(&faults));
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
        html.push_str("</figure>\n<h2>Cycle time of the sorted parts</h2>\n<figure>");
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
             <th>Wilson 95 %</th><th>strict</th><th>passed</th><th>safe</th><th>removals</th><th>mean cycle, s</th><th>failures</th>\
             <th>gate</th></tr>\n",
        );
        for (
            i,
            PageBatch {
                label, report: row, ..
            },
        ) in self.rows.iter().enumerate()
        {
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
                 <td class=\"n\">{}</td><td class=\"n\">{:.3}</td><td class=\"n\">{}</td>\
                 <td class=\"n\">{cycle}</td><td>{}</td><td>{gate}</td></tr>",
                xml_escape(label),
                row.successes,
                row.trials,
                row.success_rate,
                row.wilson95[0],
                row.wilson95[1],
                row.strict_successes,
                row.passed,
                row.safe_rate,
                row.removals,
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
        DecisionRecord, Misidentification, PartRecord, ReportMeta, StreamPartRecord, StreamRecord,
        TrialRecord, trial_image_path,
    };
    use super::*;
    use crate::outcome::{FailureReason, Outcome};

    fn meta(perception: Perception, trials: u32) -> ReportMeta {
        ReportMeta {
            scenario: "s<&>".into(),
            seed: 1,
            perception,
            scenario_trials: trials,
            shard: None,
            interrupted: false,
            min_success: Some(0.9),
        }
    }

    fn row(label: &str, successes: u32, failures: u32) -> PageBatch {
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
        let meta = meta(Perception::Oracle, successes + failures);
        PageBatch {
            label: label.into(),
            dir: PathBuf::from("d"),
            report: BatchReport::from_records(&meta, &records),
        }
    }

    fn page(rows: Vec<PageBatch>, cycle_times_s: Vec<f64>) -> HtmlPage {
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
            vec![row("a<b", 9, 1), row("c", 3, 3)],
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
        let page = page(vec![row("none", 0, 0)], Vec::new());
        let html = page.render().expect("page");
        assert_eq!(html.matches("<svg").count(), 4);
        assert!(html.contains("no failures") && html.contains("no sorted part"));
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

    fn decision(detected: &str, measured_mm: f64) -> DecisionRecord {
        let accept = measured_mm <= 0.5;
        DecisionRecord {
            detected_type: detected.into(),
            measured_roundness_mm: Some(measured_mm),
            measured_bore_diameter_mm: Some(28.1),
            accept,
            bin: if accept { "group_b" } else { "reject" }.into(),
            note: None,
        }
    }

    fn decided(i: u32, part: PartRecord, detected: &str, measured_mm: f64) -> TrialRecord {
        let mut r = TrialRecord::failed(i, u64::from(i) + 100, FailureReason::WrongBin, "w");
        let decision = decision(detected, measured_mm);
        r.placed_bin = Some(decision.bin.clone());
        if decision.accept == part.truly_acceptable || !part.clear_cut {
            r.outcome = Outcome::Success;
            r.failure = None;
            r.detail = None;
            r.cycle_time_s = 18.0;
        }
        r.decision = Some(decision);
        r.part = Some(part);
        r
    }

    /// Records of every kind the page shows, and a batch directory with one camera frame.
    fn batch(name: &str) -> (PathBuf, Vec<TrialRecord>) {
        let dir = std::env::temp_dir().join(format!("twincell-html-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("dir");
        // A stream that sorted one part before it took a bottle for a part and halted.
        let mut stream = TrialRecord::failed(4, 104, FailureReason::Misidentified, "took it");
        stream.cycle_time_s = 30.0;
        let sorted = part("axle_a20", 0.1);
        stream.stream = Some(StreamRecord {
            parts_planned: 3,
            parts_sorted: 1,
            bottles_passed: 2,
            belt_stops: 3,
            parts: vec![StreamPartRecord {
                index: 0,
                outcome: Outcome::Success,
                failure: None,
                detail: None,
                placed_bin: Some(sorted.correct_bin.clone()),
                part: sorted,
                decision: Some(decision("axle_a20", 0.11)),
                cycle_time_s: 7.5,
                grasp: None,
                track: Some(0),
                tracking: None,
            }],
            misidentified: Some(Misidentification {
                truth: "bottle".into(),
                identified: "axle_b28".into(),
                track: Some(2),
            }),
            tracks_opened: 3,
            passed_tracks: vec![1],
            collected: Vec::new(),
            tracking: false,
        });
        let mut missed = TrialRecord::failed(5, 105, FailureReason::NotDetected, "nothing");
        missed.part = Some(part("axle_b32", 0.1));
        let records = vec![
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
        let image = image::RgbImage::from_pixel(32, 24, image::Rgb([200, 10, 10]));
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new(&mut jpeg)
            .encode_image(&image)
            .expect("jpeg");
        let path = trial_image_path(&dir, 1);
        fs::create_dir_all(path.parent().expect("parent")).expect("images dir");
        fs::write(path, jpeg).expect("image");
        (dir, records)
    }

    #[test]
    fn the_page_shows_what_the_report_of_the_records_says() {
        let (dir, records) = batch("camera");
        let report = BatchReport::from_records(&meta(Perception::Camera, 6), &records);
        let page = HtmlPage::for_batch(&report, &dir)
            .expect("page")
            .with_roundness_limits(Some(RoundnessLimits {
                tolerance_mm: 0.5,
                uncertainty_mm: 0.05,
            }));
        // The figures report.json holds, read from the same report.
        assert_eq!(page.sorting.accept_reject, report.sorting.accept_reject);
        assert_eq!(page.sorting.in_band, report.sorting.in_band.parts);
        let c = &page.sorting.accept_reject;
        assert_eq!((c.truly_accept.accept, c.truly_accept.reject), (3, 1));
        assert_eq!((c.truly_reject.accept, c.truly_reject.reject), (1, 0));
        assert_eq!(page.sorting.in_band, 1);
        // The histogram counts each sorted part's pick cycle, as report.json's cycle_time_s
        // does: the stream's sorted part too, though its trial failed.
        let mut cycles = page.cycle_times_s.clone();
        cycles.sort_by(f64::total_cmp);
        assert_eq!(cycles, [7.5, 18.0, 18.0, 18.0]);
        let cycle = report.cycle_time_s.as_ref().expect("sorted parts");
        assert_eq!(cycle.count as usize, cycles.len());
        assert_eq!(cycle.mean, cycles.iter().sum::<f64>() / 4.0);
        let types = &page.sorting.types;
        assert_eq!(types["axle_a20"]["axle_a20"], 1);
        assert_eq!(types["axle_b28"]["axle_b28"], 3);
        assert_eq!(types["axle_b32"]["axle_b28"], 1);
        assert_eq!(types["axle_b32"]["not detected"], 1);
        assert_eq!(types["bottle"]["bottle"], 2);
        assert_eq!(types["bottle"]["axle_b28"], 1);
        // The decided parts' types are report.json's part_type matrix.
        for (truth, row) in &report.sorting.part_type {
            for (detected, n) in row {
                assert_eq!(types[truth][detected], *n, "{truth} {detected}");
            }
        }
        assert_eq!(page.sorting.roundness_mm.len(), 5);
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
        // Another directory has no frames: the cards say so.
        let elsewhere = HtmlPage::for_batch(&report, &dir.join("nowhere")).expect("page");
        assert!(
            elsewhere
                .cards
                .iter()
                .all(|c| c.image == CardImage::Missing)
        );
        let oracle = HtmlPage::for_batches(
            "t",
            Perception::Oracle,
            vec![PageBatch {
                label: "b".into(),
                dir: dir.clone(),
                report,
            }],
        )
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
