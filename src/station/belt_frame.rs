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
    /// belt's top. `calibration` is the frame's, `frame_px` its size.
    pub fn items_of(
        &self,
        sighting: &Sighting,
        calibration: &CameraCalibration,
        frame_px: (u32, u32),
        bottle_height_m: f64,
    ) -> Vec<(SeenItem, ItemSighting)> {
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
            items.push((
                seen,
                ItemSighting {
                    kind: ItemKind::Part,
                    score: score(part.detection),
                    at: self.belt_from_world(&part.centre_in_world),
                    half_length_m: half_length_m(part.detection),
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
