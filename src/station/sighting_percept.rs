//! From a camera's sighting to the planner's percept: the target part's type, place and bore,
//! and the bottles and other parts near it as obstacles.

use nalgebra::Point3;

use super::camera_percept::Sighting;
use super::percept::{Percept, bottle_obstacle, part_obstacle};
use super::silhouette::CutBox;
use crate::camera::CameraCalibration;
use crate::scenario::{BottleSection, Catalogue, PartTypeId};

/// Things on the belt within this distance of the part are obstacles to its pick, m.
pub const NEIGHBOURHOOD_M: f64 = 0.45;
/// How much a bottle seen by the camera is grown as an obstacle, for the uncertainty of a pose
/// fitted to its box, m.
const SEEN_BOTTLE_GROWTH_M: f64 = 0.004;

/// A detector box whose side lies within this share of the frame's side of the frame's edge is
/// cut by the image border (boxes are regressed, a cut one ends a few pixels short of the edge).
const BORDER_TOUCH_SHARE: f64 = 0.01;
/// A jog helps a cut part when the belt's motion carries its image inward from a border it
/// touches by at least this share of the motion (within 60° of the border's inward normal), and
/// outward from none by as much.
const INWARD_SHARE: f64 = 0.5;
/// A belt jog shorter than this would not move the part noticeably in the image, m.
const MIN_JOG_M: f64 = 0.002;

/// What the station knows of the cell to turn a sighting into a percept.
#[derive(Debug, Clone, Copy)]
pub struct StationModel<'a> {
    /// The scenario's part types.
    pub catalogue: &'a Catalogue,
    /// The foreign object's size.
    pub bottle: &'a BottleSection,
    /// Top of the belt, world z, m.
    pub belt_top_z: f64,
}

impl Sighting {
    /// The belt travel (m, downstream along +x) after which the camera should look again,
    /// when the target part is not seen whole: `None` when it is, or when nothing suggests that
    /// moving the belt would help. The belt runs one way, so only parts upstream of the view's
    /// centre can be brought to it.
    ///
    /// - The target's box touches the image border, its bore was not measured, and the belt's
    ///   motion carries the part's image inward from a border it touches and out of none: the
    ///   travel
    ///   that brings the part's place (its box centre on its end-face plane, `centre_in_world`)
    ///   to where the optical axis meets that plane. A cut box's centre lies short of the
    ///   part's, towards the view's centre, so the jog falls short rather than overshooting:
    ///   the caller looks again, and jogs again if the part is still cut.
    /// - No part was seen but a bottle was (the bottle stopped the belt, and the part behind it
    ///   is still upstream of the view): the travel from the view's upstream edge on the belt to
    ///   its centre, which brings what lay just upstream of the view to its middle.
    ///
    /// `calibration` is the frame's camera, `frame_px` its size (the boxes' pixels), and the
    /// belt's top is at `belt_top_z_m`.
    pub fn border_jog_m(
        &self,
        calibration: &CameraCalibration,
        frame_px: (u32, u32),
        belt_top_z_m: f64,
    ) -> Option<f64> {
        let (w, h) = (f64::from(frame_px.0), f64::from(frame_px.1));
        let (cx, cy) = (calibration.cx_px, calibration.cy_px);
        let jog = match &self.target {
            Some(target) => {
                if target.bore.is_some() {
                    return None;
                }
                let box_px = self.detections.get(target.detection)?.box_px.map(f64::from);
                let touched = touched_borders(&box_px, frame_px);
                if touched.is_empty() {
                    return None;
                }
                // The belt carries the part downstream (+x): that helps only if the part's
                // image moves away from a border it touches and towards none (a part cut at a
                // border along the belt's image stays cut however far it is carried).
                let p = target.centre_in_world;
                let from = calibration.project(&p)?;
                let to = calibration.project(&(p + nalgebra::Vector3::new(MIN_JOG_M, 0.0, 0.0)))?;
                let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
                let motion = dx.hypot(dy);
                let inward = |n: &[f64; 2]| (n[0] * dx + n[1] * dy) / motion;
                let helps = touched.iter().any(|n| inward(n) >= INWARD_SHARE);
                let worsens = touched.iter().any(|n| inward(n) < -INWARD_SHARE);
                if motion <= 0.0 || !helps || worsens {
                    return None;
                }
                let face = calibration.with_end_face_height(p.z);
                face.pixel_to_plane(cx, cy).ok()?.x - p.x
            }
            None if !self.bottles.is_empty() => {
                let belt = calibration.with_end_face_height(belt_top_z_m);
                let upstream_edge = [
                    [0.0, 0.0],
                    [w - 1.0, 0.0],
                    [0.0, h - 1.0],
                    [w - 1.0, h - 1.0],
                ]
                .iter()
                .filter_map(|p| belt.pixel_to_plane(p[0], p[1]).ok())
                .map(|p| p.x)
                .fold(f64::INFINITY, f64::min);
                belt.pixel_to_plane(cx, cy).ok()?.x - upstream_edge
            }
            None => return None,
        };
        (jog.is_finite() && jog >= MIN_JOG_M).then_some(jog)
    }

    /// What this sighting means for the pick, or `None` when it holds no target part.
    pub fn percept(&self, station: &StationModel<'_>) -> Option<Percept> {
        let target = self.target.as_ref()?;
        let part_type = PartTypeId(target.type_index);
        let kind = station.catalogue.part(part_type);
        let centre = target.centre_in_world;
        let near = |x: f64, y: f64| (x - centre.x).hypot(y - centre.y) < NEIGHBOURHOOD_M;
        let mut obstacles = Vec::new();
        for bottle in &self.bottles {
            for pose in &bottle.poses {
                let t = pose.world_from_bottle.translation.vector;
                if near(t.x, t.y) {
                    obstacles.push(bottle_obstacle(
                        station.bottle,
                        &pose.world_from_bottle,
                        pose.lying,
                        SEEN_BOTTLE_GROWTH_M,
                    ));
                }
            }
        }
        for other in &self.other_parts {
            let p = other.centre_in_world;
            if near(p.x, p.y) {
                let other_type = station.catalogue.part(PartTypeId(other.type_index));
                let height_m = other_type.height_m;
                obstacles.push(part_obstacle(
                    &Point3::new(p.x, p.y, station.belt_top_z + height_m / 2.0),
                    other_type.outer_radius_m(),
                    height_m,
                ));
            }
        }
        let (roundness_mm, bore_diameter_mm) = match &target.bore {
            Some((_, plane)) => (Some(plane.roundness_m * 1e3), Some(plane.diameter_m * 1e3)),
            None => (None, None),
        };
        Some(Percept {
            part_type,
            part_xy: [centre.x, centre.y],
            part_outer_radius_m: kind.outer_radius_m(),
            part_height_m: kind.height_m,
            roundness_mm,
            bore_diameter_mm,
            inconsistency: target.inconsistency.clone(),
            unidentified: target.unidentified.clone(),
            obstacles,
        })
    }
}

/// The borders of a `frame_px` large frame that `box_px` reaches within
/// [`BORDER_TOUCH_SHARE`] of (a box cut by the image's edge), as inward unit normals.
pub(super) fn touched_borders(box_px: &[f64; 4], frame_px: (u32, u32)) -> Vec<[f64; 2]> {
    let frame = (f64::from(frame_px.0), f64::from(frame_px.1));
    let Some(cut) = CutBox::of(box_px, frame, BORDER_TOUCH_SHARE) else {
        return Vec::new();
    };
    // Left, top, right, bottom, as `CutBox::cut` orders them.
    let inward = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]];
    cut.cut
        .into_iter()
        .zip(inward)
        .filter_map(|(touches, inward)| touches.then_some(inward))
        .collect()
}
