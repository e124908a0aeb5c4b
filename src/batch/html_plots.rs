//! The plots of `report.html`, drawn by `plotters`' SVG backend into strings.

use std::collections::BTreeMap;

use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::html::{HtmlError, HtmlPage};

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

impl HtmlPage {
    /// Short x labels: the rows' labels when they are short, else their numbers.
    pub(super) fn x_label(&self, i: usize) -> String {
        let long = self.rows.iter().any(|b| b.label.len() > 22);
        match self.rows.get(i) {
            Some(b) if !long => b.label.clone(),
            Some(_) => format!("#{i}"),
            None => String::new(),
        }
    }

    pub(super) fn success_svg(&self) -> Result<String, HtmlError> {
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
                .map(|(i, b)| (at(i), b.report.wilson95[1]))
                .chain(
                    self.rows
                        .iter()
                        .enumerate()
                        .rev()
                        .map(|(i, b)| (at(i), b.report.wilson95[0])),
                )
                .collect();
            chart
                .draw_series(std::iter::once(Polygon::new(band, BLUE.mix(0.15))))
                .map_err(&err)?;
            let line: Vec<_> = self
                .rows
                .iter()
                .enumerate()
                .map(|(i, b)| (at(i), b.report.success_rate))
                .collect();
            chart
                .draw_series(std::iter::once(PathElement::new(
                    line,
                    BLUE.stroke_width(2),
                )))
                .map_err(&err)?;
            chart
                .draw_series(self.rows.iter().enumerate().map(|(i, b)| {
                    let r = &b.report;
                    PathElement::new(
                        vec![(at(i), r.wilson95[0]), (at(i), r.wilson95[1])],
                        BLACK.stroke_width(1),
                    )
                }))
                .map_err(&err)?;
            chart
                .draw_series(
                    self.rows.iter().enumerate().map(|(i, b)| {
                        Circle::new((at(i), b.report.success_rate), 4, BLUE.filled())
                    }),
                )
                .map_err(&err)?;
            root.present().map_err(&err)?;
        }
        Ok(svg)
    }

    pub(super) fn failures_svg(&self) -> Result<String, HtmlError> {
        let err = plot_error("failures");
        let mut totals: BTreeMap<&str, u32> = BTreeMap::new();
        for batch in &self.rows {
            for (reason, n) in &batch.report.failures {
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

    pub(super) fn cycle_svg(&self) -> Result<String, HtmlError> {
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
                    "no sorted part"
                } else {
                    "simulated pick cycle, s"
                })
                .y_desc("sorted parts")
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

    /// Measured against true roundness, one point per measured part (blue: the true verdict,
    /// red: the other), with the line y = x and, when known, the tolerance (dashed) and the
    /// uncertainty band about it (grey) where either verdict counts as right.
    pub(super) fn roundness_svg(&self) -> Result<String, HtmlError> {
        let err = plot_error("roundness");
        let points = &self.sorting.roundness_mm;
        let data_max = points
            .iter()
            .flat_map(|(p, _)| p.iter().copied())
            .fold(0.0f64, f64::max);
        let limit_max = self
            .roundness_limits
            .map_or(0.0, |l| l.tolerance_mm + l.uncertainty_mm);
        let top = (data_max.max(limit_max) * 1.08).max(0.1);
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (560, 480)).into_drawing_area();
            root.fill(&WHITE).map_err(&err)?;
            let mut chart = ChartBuilder::on(&root)
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(56)
                .build_cartesian_2d(0f64..top, 0f64..top)
                .map_err(&err)?;
            chart
                .configure_mesh()
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 14))
                .x_desc(if points.is_empty() {
                    "no part measured"
                } else {
                    "true roundness, mm"
                })
                .y_desc("measured roundness, mm")
                .draw()
                .map_err(&err)?;
            if let Some(limits) = self.roundness_limits {
                let (low, high) = (
                    (limits.tolerance_mm - limits.uncertainty_mm).max(0.0),
                    limits.tolerance_mm + limits.uncertainty_mm,
                );
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(low, 0.0), (high, top)],
                        BLACK.mix(0.08).filled(),
                    )))
                    .map_err(&err)?;
                let t = limits.tolerance_mm;
                let dashed = |from: (f64, f64), to: (f64, f64)| {
                    DashedPathElement::new(vec![from, to], 6, 4, BLACK.mix(0.6).stroke_width(1))
                };
                chart
                    .draw_series([dashed((t, 0.0), (t, top)), dashed((0.0, t), (top, t))])
                    .map_err(&err)?;
            }
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(0.0, 0.0), (top, top)],
                    BLACK.stroke_width(1),
                )))
                .map_err(&err)?;
            chart
                .draw_series(points.iter().map(|([truth, measured], right)| {
                    let colour = if *right { BLUE.mix(0.7) } else { RED.mix(0.9) };
                    Circle::new((*truth, *measured), 3, colour.filled())
                }))
                .map_err(&err)?;
            root.present().map_err(&err)?;
        }
        Ok(svg)
    }
}
