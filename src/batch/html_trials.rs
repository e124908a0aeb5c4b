//! What `report.html` shows of its batches' trials beyond their headline rows: the sorter's
//! decisions against the truth (the confusion matrices and the roundness scatter) and a card for
//! every failed or misjudged trial, with its camera frame from `images/`; all read from the
//! batches' [`BatchReport`]s.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::fs;
use std::io;
use std::path::Path;

use base64::Engine as _;

use super::batch_listing::{BOTTLE, NOT_DETECTED};
use super::html::HtmlError;
use super::trial_images::trial_image_path;
use super::trial_summary::TrialSummary;
use super::{AcceptConfusion, BatchReport, Outcome, Perception, xml_escape};

/// The sorter's decisions against the truth, over every batch of a page.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PageSorting {
    /// True verdict vs decided verdict, every decided part.
    pub accept_reject: AcceptConfusion,
    /// Of those, the parts inside the uncertainty band (either verdict counts as right).
    pub in_band: u32,
    /// True item (part type or `bottle`) -> what perception took it for (a part type,
    /// `bottle`, or `not detected`) -> count.
    pub types: BTreeMap<String, BTreeMap<String, u32>>,
    /// `[true, measured]` roundness of every measured part, mm, with whether its verdict was
    /// the true one.
    pub roundness_mm: Vec<([f64; 2], bool)>,
}

impl PageSorting {
    /// Adds what `report` says: its accept/reject counts and band from `report.json`'s
    /// `sorting`, its identifications and measured parts from its listing.
    pub fn add(&mut self, report: &BatchReport) {
        let (sum, more) = (&mut self.accept_reject, &report.sorting.accept_reject);
        sum.truly_accept.accept += more.truly_accept.accept;
        sum.truly_accept.reject += more.truly_accept.reject;
        sum.truly_reject.accept += more.truly_reject.accept;
        sum.truly_reject.reject += more.truly_reject.reject;
        self.in_band += report.sorting.in_band.parts;
        for (truth, row) in &report.listing.identified {
            let ours = self.types.entry(truth.clone()).or_default();
            for (identified, n) in row {
                *ours.entry(identified.clone()).or_default() += n;
            }
        }
        self.roundness_mm
            .extend_from_slice(&report.listing.roundness_mm);
    }

    /// The accept/reject matrix as an HTML table.
    pub fn accept_reject_table(&self) -> String {
        let c = &self.accept_reject;
        let cells = [
            ("conforming", c.truly_accept.accept, c.truly_accept.reject),
            (
                "nonconforming",
                c.truly_reject.accept,
                c.truly_reject.reject,
            ),
        ];
        let most = cells
            .iter()
            .map(|(_, a, r)| (*a).max(*r))
            .max()
            .unwrap_or(0);
        let mut out = String::from(
            "<table class=\"cm\"><tr><th>truth \\ decision</th><th>accepted</th>\
             <th>rejected</th></tr>\n",
        );
        for (i, (label, accepted, rejected)) in cells.iter().enumerate() {
            let _ = writeln!(
                out,
                "<tr><th>{label}</th>{}{}</tr>",
                cell(*accepted, most, i == 0),
                cell(*rejected, most, i == 1)
            );
        }
        let _ = writeln!(
            out,
            "</table>\n<p class=\"small\">{} decided parts; {} of them inside the uncertainty \
             band about the tolerance, where either verdict counts as right.</p>",
            c.truly_accept.accept
                + c.truly_accept.reject
                + c.truly_reject.accept
                + c.truly_reject.reject,
            self.in_band
        );
        out
    }

    /// The type matrix (true item vs what perception took it for) as an HTML table.
    pub fn type_table(&self) -> String {
        if self.types.is_empty() {
            return "<p>No part or bottle was identified.</p>\n".to_owned();
        }
        let truths: Vec<&String> = self.types.keys().collect();
        let mut columns: BTreeSet<&str> = self
            .types
            .values()
            .flat_map(|row| row.keys().map(String::as_str))
            .collect();
        columns.extend(truths.iter().map(|t| t.as_str()));
        // Parts first, then the bottle and nothing, in that order.
        let mut columns: Vec<&str> = columns
            .into_iter()
            .filter(|c| *c != BOTTLE && *c != NOT_DETECTED)
            .collect();
        columns.extend([BOTTLE, NOT_DETECTED]);
        let most = self
            .types
            .values()
            .flat_map(|row| row.values().copied())
            .max()
            .unwrap_or(0);
        let mut out = String::from("<table class=\"cm\"><tr><th>truth \\ identified</th>");
        for c in &columns {
            let _ = write!(out, "<th>{}</th>", xml_escape(c));
        }
        out.push_str("</tr>\n");
        // Parts first, the bottle last.
        let (bottle, mut truths): (Vec<&String>, Vec<&String>) =
            truths.into_iter().partition(|t| *t == BOTTLE);
        truths.extend(bottle);
        for truth in truths {
            let _ = write!(out, "<tr><th>{}</th>", xml_escape(truth));
            let row = &self.types[truth];
            for c in &columns {
                let n = row.get(*c).copied().unwrap_or(0);
                out.push_str(&cell(n, most, *c == truth.as_str()));
            }
            out.push_str("</tr>\n");
        }
        out.push_str("</table>\n");
        out
    }
}

/// A count as a table cell shaded by its share of `most`: green on the diagonal (`right`),
/// red off it; empty cells stay white.
fn cell(n: u32, most: u32, right: bool) -> String {
    if n == 0 {
        return "<td class=\"n\">0</td>".to_owned();
    }
    let share = 0.15 + 0.6 * f64::from(n) / f64::from(most.max(1));
    let rgb = if right { "40,160,60" } else { "210,40,40" };
    format!("<td class=\"n\" style=\"background:rgba({rgb},{share:.2})\">{n}</td>")
}

/// The picture a card shows.
#[derive(Debug, Clone, PartialEq)]
pub enum CardImage {
    /// The trial's annotated camera frame, JPEG bytes.
    Jpeg(Vec<u8>),
    /// Oracle perception: there is no camera image.
    Oracle,
    /// Camera perception, but no frame was saved (the trial failed before the camera looked).
    Missing,
}

/// One failed or misjudged trial, as the page shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialCard {
    /// The batch's label.
    pub batch: String,
    /// Trial index.
    pub trial: u32,
    /// The trial's seed.
    pub seed: u64,
    /// The failure reason, `passed` for a part let through, or `misjudged` for a success with a
    /// decision against the truth.
    pub reason: String,
    /// The record's detail.
    pub detail: String,
    /// Truth and decision of the part concerned, in words.
    pub judgement: String,
    /// The camera frame.
    pub image: CardImage,
}

/// The card of `trial` (from batch `batch` in `dir`, run with `perception`), when it wants
/// one: when it failed or a decision in it went against the truth.
pub fn trial_card(
    batch: &str,
    dir: &Path,
    perception: Perception,
    trial: &TrialSummary,
) -> Result<Option<TrialCard>, HtmlError> {
    let Some(judgement) = &trial.judgement else {
        return Ok(None);
    };
    let reason = match trial.outcome {
        Outcome::Passed => "passed",
        _ => trial.failure_reason().unwrap_or("misjudged"),
    };
    let image = match perception {
        Perception::Oracle => CardImage::Oracle,
        Perception::Camera => {
            let path = trial_image_path(dir, trial.trial);
            match fs::read(&path) {
                Ok(bytes) => CardImage::Jpeg(bytes),
                Err(err) if err.kind() == io::ErrorKind::NotFound => CardImage::Missing,
                Err(err) => {
                    return Err(HtmlError::Image {
                        path,
                        reason: err.to_string(),
                    });
                }
            }
        }
    };
    Ok(Some(TrialCard {
        batch: batch.to_owned(),
        trial: trial.trial,
        seed: trial.seed,
        reason: reason.to_owned(),
        detail: trial.detail.clone().unwrap_or_default(),
        judgement: judgement.clone(),
        image,
    }))
}

/// The cards as an HTML section body.
pub fn cards_html(cards: &[TrialCard]) -> String {
    if cards.is_empty() {
        return "<p>No trial failed or was misjudged.</p>\n".to_owned();
    }
    let mut out = String::from("<div class=\"cards\">\n");
    for card in cards {
        let picture = match &card.image {
            CardImage::Jpeg(bytes) => format!(
                "<img width=\"320\" alt=\"camera frame of trial {}\" \
                 src=\"data:image/jpeg;base64,{}\">",
                card.trial,
                base64::engine::general_purpose::STANDARD.encode(bytes)
            ),
            CardImage::Oracle => "<div class=\"noimg\">oracle perception: no camera image (the \
                                  truth was read from the simulated world)</div>"
                .to_owned(),
            CardImage::Missing => "<div class=\"noimg\">no camera frame: the trial ended before \
                                   the camera looked</div>"
                .to_owned(),
        };
        let _ = writeln!(
            out,
            "<figure class=\"card\">{picture}<figcaption><b>{}</b> trial {} (seed {}): \
             <span class=\"fail\">{}</span><br>{}<br><span class=\"small\">{}</span>\
             </figcaption></figure>",
            xml_escape(&card.batch),
            card.trial,
            card.seed,
            xml_escape(&card.reason),
            xml_escape(&card.detail),
            xml_escape(&card.judgement)
        );
    }
    out.push_str("</div>\n");
    out
}
