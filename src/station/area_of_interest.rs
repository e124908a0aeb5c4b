//! The target part's area of interest: its detector box widened and read again at the sensor's
//! full pitch, where its bore is found and measured on the end-face plane.

use image::GrayImage;

use crate::camera::CameraCalibration;
use crate::perception::calibration::{MeasureOnPlane, PlaneBore};
use crate::perception::roundness::DEFAULT_MAX_UPR;
use crate::perception::{Bore, BoreDetector};
use crate::render::SensorWindow;

/// Share of a part box's side added on every side before the metrology looks inside it.
const BOX_MARGIN: f64 = 0.15;

/// Least share of the smaller of two part boxes that must lie inside the other for both to be
/// taken as the same part seen twice ([`union_of_overlapping`]).
const SAME_PART_OVERLAP: f64 = 0.5;

/// The box covering `box_px` and every box of `boxes` (the look's part boxes, `box_px` among
/// them) that shares at least [`SAME_PART_OVERLAP`] of the smaller one's area with it; `None`
/// when no other box does.
pub(super) fn union_of_overlapping(box_px: &[f64; 4], boxes: &[[f64; 4]]) -> Option<[f64; 4]> {
    let area = |b: &[f64; 4]| (b[2] - b[0]).max(0.0) * (b[3] - b[1]).max(0.0);
    let mut union = *box_px;
    let mut merged = false;
    for other in boxes.iter().filter(|b| *b != box_px) {
        let inter = [
            box_px[0].max(other[0]),
            box_px[1].max(other[1]),
            box_px[2].min(other[2]),
            box_px[3].min(other[3]),
        ];
        let smaller = area(box_px).min(area(other));
        if smaller > 0.0 && area(&inter) >= SAME_PART_OVERLAP * smaller {
            union = [
                union[0].min(other[0]),
                union[1].min(other[1]),
                union[2].max(other[2]),
                union[3].max(other[3]),
            ];
            merged = true;
        }
    }
    merged.then_some(union)
}

/// The area of interest of a part's box in a `frame_px` large frame: the box widened by
/// `BOX_MARGIN` (15 %) a side, on a sensor with `roi_scale` pixels per frame pixel.
pub fn part_window(
    box_px: &[f64; 4],
    frame_px: (u32, u32),
    roi_scale: u32,
) -> Option<SensorWindow> {
    let [x0, y0, x1, y1] = *box_px;
    let (mx, my) = ((x1 - x0) * BOX_MARGIN, (y1 - y0) * BOX_MARGIN);
    SensorWindow::covering([x0 - mx, y0 - my, x1 + mx, y1 + my], frame_px, roi_scale)
}

/// Finds the bore in a part's area of interest (`gray`, read through `window`) and measures it
/// on the end-face plane of `calibration` (the frame's camera); the bore nearest the centre of
/// the part's box (frame pixels) wins. The bore comes back in frame pixels. `None` when there
/// is none.
pub fn measure_in_window(
    bore_detector: &BoreDetector,
    gray: &GrayImage,
    window: &SensorWindow,
    box_px: &[f64; 4],
    calibration: &CameraCalibration,
) -> Option<(Bore, PlaneBore)> {
    let bore = find_in_window(bore_detector, gray, window, box_px)?;
    measure_found(bore, window, calibration)
}

/// The bore in a part's area of interest (`gray`, read through `window`) nearest the centre of
/// the part's box (frame pixels), in the window's pixels.
pub fn find_in_window(
    bore_detector: &BoreDetector,
    gray: &GrayImage,
    window: &SensorWindow,
    box_px: &[f64; 4],
) -> Option<Bore> {
    let [x0, y0, x1, y1] = *box_px;
    let centre = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
    let in_box = |p: [f64; 2]| (x0..=x1).contains(&p[0]) && (y0..=y1).contains(&p[1]);
    let distance = |b: &Bore| {
        let [x, y] = window.to_frame(b.centre_px);
        (x - centre[0]).hypot(y - centre[1])
    };
    bore_detector
        .detect(gray)
        .ok()?
        .into_iter()
        .filter(|b| in_box(window.to_frame(b.centre_px)))
        .min_by(|a, b| distance(a).total_cmp(&distance(b)))
}

/// Measures `bore`, found in the area of interest `window`, on the end-face plane of
/// `calibration` (the frame's camera); the bore comes back in frame pixels.
pub fn measure_found(
    bore: Bore,
    window: &SensorWindow,
    calibration: &CameraCalibration,
) -> Option<(Bore, PlaneBore)> {
    let plane = window
        .calibration(calibration)
        .measure_on_plane(&bore, DEFAULT_MAX_UPR)
        .ok()?;
    let s = 1.0 / f64::from(window.scale);
    let [dx, dy] = window.to_frame([0.0, 0.0]);
    Some((bore.mapped(s, dx, dy), plane))
}
