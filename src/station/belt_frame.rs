//! The belt's coordinates, and a look's items in them: what [`TrackSet`](super::TrackSet) works
//! on. The station (the photo-eye's beam on the belt's centre line, on its top) is the origin,
//! the belt's travel the first axis.

use nalgebra::{Point3, Unit, Vector3};

use super::camera_percept::Sighting;
use super::tracks::{BeltPoint, ItemKind, ItemSighting, ViewSpan};
use crate::camera::CameraCalibration;

/// A sighting whose box touches the frame's edge shows only part of its item: its vote on the
/// item's kind counts this share of the detector's confidence.
const EDGE_VOTE_SHARE: f64 = 0.5;
/// A box this close to the frame's edge touches it, px.
const EDGE_MARGIN_PX: f64 = 1.0;
/// Allowance on the longest footprint a standing tube of the catalogue can show (its box on the
/// belt's top, stretched by perspective): a share, and a length for the box's looseness, m.
const TUBE_LENGTH_ALLOWANCE: (f64, f64) = (1.25, 0.01);

/// The bulkiest tubes a catalogue holds: what bounds the footprint a part's box can show.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TubeEnvelope {
    /// The largest outer radius, m.
    pub outer_radius_m: f64,
    /// The greatest height, m.
    pub height_m: f64,
}

/// The belt's frame in the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeltFrame {
    /// The station: the photo-eye's beam on the belt's centre line, on its top.
    pub station_in_world: Point3<f64>,
    /// The direction the belt carries things, horizontal.
    pub travel: Unit<Vector3<f64>>,
}

/// Which of a look's items a sighting is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeenItem {
    /// The look's target part ([`Sighting::target`]).
    Target,
    /// [`Sighting::other_parts`]`[index]`.
    OtherPart(usize),
    /// [`Sighting::bottles`]`[index]`.
    Bottle(usize),
}

impl BeltFrame {
    /// The belt coordinates of `point_in_world` (its height dropped).
    pub fn belt_from_world(&self, point_in_world: &Point3<f64>) -> BeltPoint {
        let d = point_in_world - self.station_in_world;
        let across = Vector3::z().cross(&self.travel);
        BeltPoint {
            along_m: d.dot(&self.travel),
            across_m: d.dot(&across),
        }
    }

    /// The point on the belt's top at `point`.
    pub fn world_from_belt(&self, point: &BeltPoint) -> Point3<f64> {
        let across = Vector3::z().cross(&self.travel);
        self.station_in_world + self.travel.into_inner() * point.along_m + across * point.across_m
    }

    /// The stretch of the belt's centre line that a `width_px` by `height_px` frame of
    /// `calibration` shows: where its rows' rays meet the belt's top, across the whole frame.
    pub fn view_span(
        &self,
        calibration: &CameraCalibration,
        width_px: u32,
        height_px: u32,
    ) -> ViewSpan {
        let (w, h) = (f64::from(width_px), f64::from(height_px));
        let z = self.station_in_world.z;
        let alongs: Vec<f64> = [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]]
            .iter()
            .filter_map(|&[x, y]| calibration.pixel_to_height(x, y, z).ok())
            .map(|p| self.belt_from_world(&p).along_m)
            .collect();
        ViewSpan {
            from_m: alongs.iter().copied().fold(f64::INFINITY, f64::min),
            to_m: alongs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }

    /// Every item of `sighting` in belt coordinates: parts at their end face's centre (the
    /// measured bore's, or the box's on the end-face plane), bottles at their fitted body's
    /// middle (a bottle `bottle_height_m` tall), or, unfitted, at their box's centre on the
    /// belt's top. `calibration` is the frame's, `frame_px` its size. A part whose box is longer
    /// along the belt than any tube within `tubes` could show from where it stands (a lying
    /// bottle the detector calls a tube) is seen as a bottle.
    pub fn items_of(
        &self,
        sighting: &Sighting,
        calibration: &CameraCalibration,
        frame_px: (u32, u32),
        bottle_height_m: f64,
        tubes: &TubeEnvelope,
    ) -> Vec<(SeenItem, ItemSighting)> {
        let eye = calibration.origin_in_world();
        let eye_height_m = eye.z - self.station_in_world.z;
        // A tube standing a horizontal distance rho from below the camera spans rho - R to
        // (rho + R) * k on the belt's top, k the perspective of its top face.
        let longest_half_m = |centre: &Point3<f64>| {
            let rho = (centre.x - eye.x).hypot(centre.y - eye.y);
            let r = tubes.outer_radius_m;
            let k = eye_height_m / (eye_height_m - tubes.height_m).max(1e-3);
            let (share, slack_m) = TUBE_LENGTH_ALLOWANCE;
            ((rho + r) * k - (rho - r)) / 2.0 * share + slack_m
        };
        let score = |detection: usize| {
            let Some(d) = sighting.detections.get(detection) else {
                return 0.0;
            };
            let [x0, y0, x1, y1] = d.box_px.map(f64::from);
            let (w, h) = (f64::from(frame_px.0), f64::from(frame_px.1));
            let m = EDGE_MARGIN_PX;
            let at_edge = x0 <= m || y0 <= m || x1 >= w - m || y1 >= h - m;
            f64::from(d.score) * if at_edge { EDGE_VOTE_SHARE } else { 1.0 }
        };
        let z = self.station_in_world.z;
        let half_length_m = |detection: usize| {
            let Some(d) = sighting.detections.get(detection) else {
                return 0.0;
            };
            let [x0, y0, x1, y1] = d.box_px.map(f64::from);
            let alongs: Vec<f64> = [[x0, y0], [x1, y0], [x0, y1], [x1, y1]]
                .iter()
                .filter_map(|&[x, y]| calibration.pixel_to_height(x, y, z).ok())
                .map(|p| self.belt_from_world(&p).along_m)
                .collect();
            let low = alongs.iter().copied().fold(f64::INFINITY, f64::min);
            let high = alongs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if high > low { (high - low) / 2.0 } else { 0.0 }
        };
        let mut items = Vec::new();
        let parts = sighting.target.iter().map(|t| (SeenItem::Target, t)).chain(
            sighting
                .other_parts
                .iter()
                .enumerate()
                .map(|(i, p)| (SeenItem::OtherPart(i), p)),
        );
        for (seen, part) in parts {
            let half_length_m = half_length_m(part.detection);
            let kind = if half_length_m > longest_half_m(&part.centre_in_world) {
                ItemKind::Bottle
            } else {
                ItemKind::Part
            };
            items.push((
                seen,
                ItemSighting {
                    kind,
                    score: score(part.detection),
                    at: self.belt_from_world(&part.centre_in_world),
                    half_length_m,
                },
            ));
        }
        for (i, bottle) in sighting.bottles.iter().enumerate() {
            let middle = match bottle.poses.first() {
                Some(pose) => {
                    Some(pose.world_from_bottle * Point3::new(0.0, 0.0, bottle_height_m / 2.0))
                }
                None => sighting.detections.get(bottle.detection).and_then(|d| {
                    let [x0, y0, x1, y1] = d.box_px.map(f64::from);
                    calibration
                        .pixel_to_height((x0 + x1) / 2.0, (y0 + y1) / 2.0, z)
                        .ok()
                }),
            };
            let Some(middle) = middle else {
                continue;
            };
            items.push((
                SeenItem::Bottle(i),
                ItemSighting {
                    kind: ItemKind::Bottle,
                    score: score(bottle.detection),
                    at: self.belt_from_world(&middle),
                    half_length_m: half_length_m(bottle.detection),
                },
            ));
        }
        items
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::Detection;
    use crate::station::PartSighting;

    const BELT_TOP_Z: f64 = 0.7;

    fn frame() -> BeltFrame {
        BeltFrame {
            station_in_world: Point3::new(0.05, -0.45, BELT_TOP_Z),
            travel: Vector3::x_axis(),
        }
    }

    /// The default camera: 0.58 m above the station, 44 degrees across 1280 x 960 pixels.
    fn camera() -> CameraCalibration {
        let eye = Point3::new(0.05, -0.45, BELT_TOP_Z + 0.58);
        let station = frame().station_in_world;
        let pose = CameraCalibration::look_at(&eye, &station, &Vector3::x()).expect("pose");
        CameraCalibration::from_fov(1280, 960, 44f64.to_radians(), pose, BELT_TOP_Z)
    }

    /// A look with one "tube" detection whose box is the image of a footprint from `x0` to
    /// `x1` (world, m) and 40 mm wide, its end face's centre over the footprint's middle.
    fn look_at_footprint(x0: f64, x1: f64) -> Sighting {
        let c = camera();
        let a = c
            .project(&Point3::new(x0, -0.47, BELT_TOP_Z))
            .expect("in view");
        let b = c
            .project(&Point3::new(x1, -0.43, BELT_TOP_Z))
            .expect("in view");
        let box_px = [
            a[0].min(b[0]),
            a[1].min(b[1]),
            a[0].max(b[0]),
            a[1].max(b[1]),
        ];
        Sighting::of_parts(
            vec![Detection {
                class_id: 0,
                class_name: "tube".into(),
                score: 0.9,
                box_px: box_px.map(|v| v as f32),
            }],
            Some(PartSighting {
                detection: 0,
                type_index: 0,
                centre_in_world: Point3::new((x0 + x1) / 2.0, -0.45, BELT_TOP_Z + 0.06),
                bore: None,
                inconsistency: None,
                unidentified: None,
            }),
            Vec::new(),
        )
    }

    #[test]
    fn belt_coordinates_round_trip_and_the_view_spans_the_frame() {
        let f = frame();
        let p = Point3::new(-0.1, -0.4, BELT_TOP_Z);
        let on_belt = f.belt_from_world(&p);
        assert!((on_belt.along_m + 0.15).abs() < 1e-12);
        assert!((on_belt.across_m - 0.05).abs() < 1e-12);
        assert!((f.world_from_belt(&on_belt) - p).norm() < 1e-12);
        // 0.58 m high, 44 degrees across: 0.234 m either side along the belt.
        let view = f.view_span(&camera(), 1280, 960);
        assert!((view.to_m - 0.234).abs() < 0.002, "{view:?}");
        assert!((view.from_m + 0.234).abs() < 0.002, "{view:?}");
    }

    #[test]
    fn a_tube_box_longer_than_any_catalogue_tube_can_show_is_seen_as_a_bottle() {
        let tubes = TubeEnvelope {
            outer_radius_m: 0.031,
            height_m: 0.09,
        };
        let f = frame();
        let c = camera();
        // Footprints drawn over the view: a standing tube's box (its top's perspective
        // included) stays a part, a lying bottle's 0.2 m does not.
        for centre in [-0.15f64, -0.08, 0.0, 0.06, 0.14] {
            let x = 0.05 + centre;
            let rho = centre.abs();
            // From the footprint's edge nearer the camera to its top's farther edge.
            let far = (rho + 0.031) * 0.58 / (0.58 - 0.09) - rho;
            let (near_x, far_x) = if centre >= 0.0 {
                (x - 0.031, x + far)
            } else {
                (x + 0.031, x - far)
            };
            let tube = look_at_footprint(near_x, far_x);
            let tube = f.items_of(&tube, &c, (1280, 960), 0.2, &tubes);
            assert_eq!(tube[0].1.kind, ItemKind::Part, "tube at {centre}");
            let bottle = look_at_footprint(x - 0.1, x + 0.1);
            let bottle = f.items_of(&bottle, &c, (1280, 960), 0.2, &tubes);
            assert_eq!(bottle[0].1.kind, ItemKind::Bottle, "bottle at {centre}");
            assert!((bottle[0].1.half_length_m - 0.1).abs() < 0.005);
        }
    }
}
