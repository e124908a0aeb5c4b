//! The target part's area of interest: its detector box widened and read again at the sensor's
//! full pitch, where its bore is found and measured on the end-face plane.

use image::GrayImage;
use nalgebra::Point3;

use crate::camera::CameraCalibration;
use crate::perception::calibration::{MeasureOnPlane, PlaneBore};
use crate::perception::roundness::DEFAULT_MAX_UPR;
use crate::perception::{Bore, BoreDetector};
use crate::render::SensorWindow;
use crate::scenario::PartType;

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

/// The end-face centre of an upright tube of `radius_m` and `height_m` standing on the belt's
/// top at `belt_z_m` whose silhouette's box is centred where `box_px`'s is, in `calibration`'s
/// frame; `None` when the view does not reach the belt there.
///
/// A part whose bore was not measured is placed from its box. The box spans the end face and
/// the side wall the camera sees, so its centre is about the projection of the axis half way
/// up; cast onto the end-face plane it lies off the end face's centre by half the height times
/// the tangent of the view's angle (23 mm for an 80 mm tube seen 30° off vertical), enough for
/// the jaws to close beside the part. Here the tube is moved on the belt until its projected
/// box's centre meets the detected one.
pub fn tube_from_box(
    calibration: &CameraCalibration,
    box_px: &[f64; 4],
    belt_z_m: f64,
    radius_m: f64,
    height_m: f64,
) -> Option<Point3<f64>> {
    let [x0, y0, x1, y1] = *box_px;
    let target = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
    let mid_z = belt_z_m + height_m / 2.0;
    let mut axis = calibration
        .pixel_to_height(target[0], target[1], mid_z)
        .ok()?;
    for _ in 0..6 {
        let face = Point3::new(axis.x, axis.y, belt_z_m + height_m);
        let bounds = tube_box(calibration, &face, radius_m, height_m)?;
        let predicted = [(bounds[0] + bounds[2]) / 2.0, (bounds[1] + bounds[3]) / 2.0];
        let (du, dv) = (target[0] - predicted[0], target[1] - predicted[1]);
        if du.hypot(dv) < 0.05 {
            break;
        }
        let from = calibration
            .pixel_to_height(predicted[0], predicted[1], mid_z)
            .ok()?;
        let to = calibration
            .pixel_to_height(predicted[0] + du, predicted[1] + dv, mid_z)
            .ok()?;
        axis += to - from;
    }
    Some(Point3::new(axis.x, axis.y, belt_z_m + height_m))
}

/// The silhouette box of an upright tube of `radius_m` and `height_m` whose end face's centre
/// is `face`, from 32 points round each of its ends; `None` when one does not project.
fn tube_box(
    calibration: &CameraCalibration,
    face: &Point3<f64>,
    radius_m: f64,
    height_m: f64,
) -> Option<[f64; 4]> {
    let mut bounds = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for k in 0..32 {
        let t = std::f64::consts::TAU * f64::from(k) / 32.0;
        for z in [face.z - height_m, face.z] {
            let point = Point3::new(face.x + radius_m * t.cos(), face.y + radius_m * t.sin(), z);
            let [u, v] = calibration.project(&point)?;
            bounds = [
                bounds[0].min(u),
                bounds[1].min(v),
                bounds[2].max(u),
                bounds[3].max(v),
            ];
        }
    }
    Some(bounds)
}

/// Of the catalogue's tubes `part_types`, the one whose silhouette, placed by
/// [`tube_from_box`], fills `box_px` best (least summed difference of width and height, px),
/// with its end-face centre. A part whose bore was not measured is handled as it: the jaws
/// close at its height. `None` when no tube places.
pub fn tube_type_from_box(
    calibration: &CameraCalibration,
    box_px: &[f64; 4],
    belt_z_m: f64,
    part_types: &[PartType],
) -> Option<(usize, Point3<f64>)> {
    let (w, h) = (box_px[2] - box_px[0], box_px[3] - box_px[1]);
    part_types
        .iter()
        .map(|t| (t.outer_diameter_mm / 2e3, t.height_mm / 1e3))
        .enumerate()
        .filter_map(|(i, (radius, height))| {
            let face = tube_from_box(calibration, box_px, belt_z_m, radius, height)?;
            let b = tube_box(calibration, &face, radius, height)?;
            let misfit = ((b[2] - b[0]) - w).abs() + ((b[3] - b[1]) - h).abs();
            Some((misfit, i, face))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, i, face)| (i, face))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;
    use std::f64::consts::TAU;

    #[test]
    fn boxes_of_one_part_merge_and_a_neighbour_s_do_not() {
        let mut rng = SimRng::new(24);
        for _ in 0..200 {
            let [x, y] = [rng.range(0.0, 1000.0), rng.range(0.0, 800.0)];
            let [w, h] = [rng.range(40.0, 300.0), rng.range(40.0, 300.0)];
            let whole = [x, y, x + w, y + h];
            // A box on most of the same part (its end face, or its wall): merged.
            let (fw, fh) = (rng.range(0.6, 1.0), rng.range(0.6, 1.0));
            let (ox, oy) = (rng.range(0.0, 1.0 - fw), rng.range(0.0, 1.0 - fh));
            let inner = [x + ox * w, y + oy * h, x + (ox + fw) * w, y + (oy + fh) * h];
            assert_eq!(union_of_overlapping(&inner, &[inner, whole]), Some(whole));
            assert_eq!(union_of_overlapping(&whole, &[whole, inner]), Some(whole));
            // A neighbour touching it over less than a third of its width: kept apart.
            let shift = w * rng.range(0.7, 1.5);
            let neighbour = [x + shift, y, x + shift + w, y + h];
            assert_eq!(union_of_overlapping(&whole, &[whole, neighbour]), None);
            assert_eq!(union_of_overlapping(&whole, &[whole]), None);
        }
    }

    /// The silhouette box of an upright tube, from dense rim points of its two ends.
    fn silhouette_box(
        calibration: &CameraCalibration,
        axis: [f64; 2],
        belt_z: f64,
        radius: f64,
        height: f64,
    ) -> Option<[f64; 4]> {
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for k in 0..720 {
            let t = std::f64::consts::TAU * f64::from(k) / 720.0;
            for z in [belt_z, belt_z + height] {
                let p = Point3::new(axis[0] + radius * t.cos(), axis[1] + radius * t.sin(), z);
                let [u, v] = calibration.project(&p)?;
                b = [b[0].min(u), b[1].min(v), b[2].max(u), b[3].max(v)];
            }
        }
        Some(b)
    }

    #[test]
    fn a_tube_is_placed_from_its_silhouette_box_under_cameras_over_the_envelope() {
        let mut rng = SimRng::new(2424);
        let belt_z = 0.70;
        let (mut worst, mut worst_box_centre) = (0.0f64, 0.0f64);
        for _ in 0..200 {
            // A camera 0.35-1.2 m from a station, up to 35° off vertical in any direction, any
            // roll, 35-80° wide; a tube 15-120 mm wide and 30-120 mm tall in its view.
            let station = Point3::new(rng.range(-0.2, 0.2), rng.range(-0.6, -0.3), belt_z);
            let (tilt, azimuth) = (rng.range(0.0, 35f64).to_radians(), rng.range(0.0, TAU));
            let distance = rng.range(0.35, 1.2);
            let eye = station
                + distance
                    * nalgebra::Vector3::new(
                        tilt.sin() * azimuth.cos(),
                        tilt.sin() * azimuth.sin(),
                        tilt.cos(),
                    );
            let roll = rng.range(0.0, TAU);
            let right = nalgebra::Vector3::new(roll.cos(), roll.sin(), 0.0);
            let Some(pose) = CameraCalibration::look_at(&eye, &station, &right) else {
                continue;
            };
            let fov = rng.range(35f64, 80.0).to_radians();
            let calibration = CameraCalibration::from_fov(1280, 960, fov, pose, belt_z);
            let (radius, height) = (rng.range(0.0075, 0.06), rng.range(0.03, 0.12));
            let reach = 0.25 * distance;
            let axis = [
                station.x + rng.range(-reach, reach),
                station.y + rng.range(-reach, reach),
            ];
            let Some(box_px) = silhouette_box(&calibration, axis, belt_z, radius, height) else {
                continue;
            };
            let Some(face) = tube_from_box(&calibration, &box_px, belt_z, radius, height) else {
                panic!("no place for a tube in view");
            };
            let error = (face.x - axis[0]).hypot(face.y - axis[1]);
            assert!((face.z - (belt_z + height)).abs() < 1e-12);
            worst = worst.max(error);
            // The box centre cast onto the end-face plane, as the cell placed such parts before.
            let centre = [(box_px[0] + box_px[2]) / 2.0, (box_px[1] + box_px[3]) / 2.0];
            if let Ok(p) = calibration.pixel_to_height(centre[0], centre[1], belt_z + height) {
                worst_box_centre = worst_box_centre.max((p.x - axis[0]).hypot(p.y - axis[1]));
            }
        }
        eprintln!(
            "largest error placing a tube from its box: {:.3} mm (box centre on the end face: \
             {:.1} mm)",
            worst * 1e3,
            worst_box_centre * 1e3
        );
        assert!(worst < 2e-4, "a tube placed {:.3} mm off", worst * 1e3);
    }
}
