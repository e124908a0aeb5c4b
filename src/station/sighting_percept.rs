//! From a camera's sighting to the planner's percept: the target part's type, place and bore,
//! and the bottles and other parts near it as obstacles.

use nalgebra::Point3;

use super::bottle_unboxed::BeltBand;
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
/// The steps in which [`surroundings_travel_m`] tries belt travels (1 cm), m.
const SURROUND_STEP_M: f64 = 0.01;

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
                travel_to_axis_m(calibration, &p)?
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

    /// The belt travel (m, downstream along +x) that brings into view what stands around the
    /// measured target upstream of it ([`surroundings_travel_m`] with the target's place): the
    /// part was stopped near the view's upstream edge (a bottle ahead of it tripped the
    /// photo-eye), and what the camera cannot see there the planner cannot keep clear of.
    /// `None` when the target's bore was not measured: that is [`Self::border_jog_m`]'s case.
    pub fn surroundings_jog_m(
        &self,
        calibration: &CameraCalibration,
        frame_px: (u32, u32),
        surroundings: &Surroundings,
    ) -> Option<f64> {
        let target = self.target.as_ref()?;
        target.bore.as_ref()?;
        surroundings_travel_m(calibration, frame_px, &target.centre_in_world, surroundings)
    }

    /// The belt travel (m, downstream along +x) that brings the measured target to the optical
    /// axis when a bottle the frame's border cuts comes within `reach_m` of the target's axis
    /// upstream of it ([`cut_neighbour_travel_m`]): what of it lies beyond the border the fit
    /// can only guess, and the arm reaches beside it. Bottles are `bottle_length_m` long.
    pub fn cut_neighbour_jog_m(
        &self,
        calibration: &CameraCalibration,
        frame_px: (u32, u32),
        reach_m: f64,
        bottle_length_m: f64,
    ) -> Option<f64> {
        let target = self.target.as_ref()?;
        target.bore.as_ref()?;
        let axes: Vec<[Point3<f64>; 2]> = self
            .bottles
            .iter()
            .filter(|b| {
                self.detections.get(b.detection).is_some_and(|d| {
                    !touched_borders(&d.box_px.map(f64::from), frame_px).is_empty()
                })
            })
            .flat_map(|b| &b.poses)
            .map(|p| {
                let w = &p.world_from_bottle;
                [
                    w * Point3::origin(),
                    w * Point3::new(0.0, 0.0, bottle_length_m),
                ]
            })
            .collect();
        cut_neighbour_travel_m(calibration, &target.centre_in_world, &axes, reach_m)
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
            let other_type = station.catalogue.part(PartTypeId(other.type_index));
            // Two standing tubes never overlap: one whose axis stands inside the target's
            // footprint, or the target's inside its own, is the target boxed twice (the end
            // face and the whole tube, from a tilted camera), not a tube beside it. Tubes that
            // touch stand the sum of their radii apart, clear of this by the smaller radius.
            let apart = (p.x - centre.x).hypot(p.y - centre.y);
            if apart < kind.outer_radius_m().max(other_type.outer_radius_m()) {
                continue;
            }
            if near(p.x, p.y) {
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

/// The belt around a part that must be in view before the arm reaches for it.
#[derive(Debug, Clone, Copy)]
pub struct Surroundings {
    /// Distance from the part's axis, m.
    pub reach_m: f64,
    /// Top of the belt, world z, m: a bottle standing or lying there is seen when the belt
    /// under it is.
    pub belt_top_z_m: f64,
    /// The belt: nothing stands beyond its edges.
    pub belt: BeltBand,
}

/// The belt travel (m, downstream along +x) that brings `part` (a point on an end face) to
/// where `calibration`'s optical axis meets the plane at its height.
fn travel_to_axis_m(calibration: &CameraCalibration, part: &Point3<f64>) -> Option<f64> {
    let face = calibration.with_end_face_height(part.z);
    let axis = face
        .pixel_to_plane(calibration.cx_px, calibration.cy_px)
        .ok()?;
    Some(axis.x - part.x)
}

/// The belt travel (m, downstream along +x) after which `calibration`'s `frame_px` frame shows
/// all of the belt within the `surroundings` of the part whose end face is centred at `part`:
/// `None` when the part's upstream surroundings are in view already, or when no travel up to
/// the one that brings the part to where the optical axis meets its end-face plane shows all
/// of them; else the first travel, in steps of 1 cm, that does.
pub fn surroundings_travel_m(
    calibration: &CameraCalibration,
    frame_px: (u32, u32),
    part: &Point3<f64>,
    surroundings: &Surroundings,
) -> Option<f64> {
    let Surroundings {
        reach_m,
        belt_top_z_m,
        belt,
    } = *surroundings;
    let belt_y_m = (
        belt.centre_y_m - belt.half_width_m,
        belt.centre_y_m + belt.half_width_m,
    );
    let (w, h) = (f64::from(frame_px.0), f64::from(frame_px.1));
    let in_view = |q: &Point3<f64>| {
        calibration
            .project(q)
            .is_some_and(|[u, v]| (0.0..=w).contains(&u) && (0.0..=h).contains(&v))
    };
    // Points around the part's axis every 10 degrees, those beyond the belt's edges brought
    // in to them.
    let around = |travel_m: f64, upstream_only: bool| -> bool {
        (0..36).all(|k| {
            let a = std::f64::consts::TAU * f64::from(k) / 36.0;
            let (dx, dy) = (reach_m * a.cos(), reach_m * a.sin());
            if upstream_only && dx > -1e-9 {
                return true;
            }
            let y = (part.y + dy).clamp(belt_y_m.0, belt_y_m.1);
            in_view(&Point3::new(part.x + dx + travel_m, y, belt_top_z_m))
        })
    };
    if around(0.0, true) {
        return None;
    }
    let most_m = travel_to_axis_m(calibration, part)?;
    let mut travel_m = SURROUND_STEP_M;
    while travel_m <= most_m {
        if around(travel_m, false) {
            return Some(travel_m);
        }
        travel_m += SURROUND_STEP_M;
    }
    None
}

/// The belt travel (m, downstream along +x) that brings `part` (a point on an end face) to
/// where `calibration`'s optical axis meets its end-face plane, when one of the `cut_axes`
/// (bottles' axes, base to top, world, each the fit of a box the frame's border cuts) comes
/// within `reach_m` of the part's axis at a point upstream of it (the belt can only carry such
/// a bottle further into view); `None` when none does, or the part is at the axis already.
pub fn cut_neighbour_travel_m(
    calibration: &CameraCalibration,
    part: &Point3<f64>,
    cut_axes: &[[Point3<f64>; 2]],
    reach_m: f64,
) -> Option<f64> {
    let near_upstream = cut_axes.iter().any(|[a, b]| {
        // The point of the axis nearest the part's, in the belt's plane.
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let length_sq = dx * dx + dy * dy;
        let t = if length_sq > 0.0 {
            (((part.x - a.x) * dx + (part.y - a.y) * dy) / length_sq).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (x, y) = (a.x + t * dx, a.y + t * dy);
        x < part.x && (x - part.x).hypot(y - part.y) < reach_m
    });
    if !near_upstream {
        return None;
    }
    let travel_m = travel_to_axis_m(calibration, part)?;
    (travel_m >= MIN_JOG_M).then_some(travel_m)
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

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use nalgebra::{Point3, Vector3};

    use super::{BeltBand, MIN_JOG_M, Surroundings, cut_neighbour_travel_m, surroundings_travel_m};
    use crate::camera::CameraCalibration;
    use crate::rng::SimRng;

    /// A camera drawn over the envelope, looking at `station` (on the belt's top): optical
    /// axis up to 35 degrees from vertical in any direction, 0.35-1.2 m away, any roll, a
    /// 35-80 degree lens on one of three frame sizes (by `case`); with its frame and its eye.
    fn camera_over(
        rng: &mut SimRng,
        station: &Point3<f64>,
        case: usize,
    ) -> Option<(CameraCalibration, (u32, u32), Point3<f64>)> {
        let (tilt, heading) = (rng.range(0.0, 35f64.to_radians()), rng.range(-PI, PI));
        let up = Vector3::new(
            tilt.sin() * heading.cos(),
            tilt.sin() * heading.sin(),
            tilt.cos(),
        );
        let eye = station + up * rng.range(0.35, 1.2);
        let roll = rng.range(-PI, PI);
        let right = Vector3::new(roll.cos(), roll.sin(), 0.0);
        let pose = CameraCalibration::look_at(&eye, station, &right)?;
        let (w, h) = [(640, 480), (1280, 960), (2048, 1536)][case % 3];
        let fov = rng.range(35f64, 80.0).to_radians();
        let calibration = CameraCalibration::from_fov(w, h, fov, pose, station.z);
        Some((calibration, (w, h), eye))
    }

    /// Whether every point on the circle of `radius` around `part` (brought in to the belt's
    /// edges), carried `travel` downstream, at `upstream_only` its upstream half, is in view.
    fn circle_in_view(
        calibration: &CameraCalibration,
        frame: (f64, f64),
        part: &Point3<f64>,
        radius: f64,
        s: &Surroundings,
        (travel, upstream_only): (f64, bool),
    ) -> bool {
        (0..72).all(|k| {
            let a = 2.0 * PI * f64::from(k) / 72.0;
            let (dx, dy) = (radius * a.cos(), radius * a.sin());
            if upstream_only && dx >= 0.0 {
                return true;
            }
            let (centre, half) = (s.belt.centre_y_m, s.belt.half_width_m);
            let y = (part.y + dy).clamp(centre - half, centre + half);
            let q = Point3::new(part.x + dx + travel, y, s.belt_top_z_m);
            calibration
                .project(&q)
                .is_some_and(|[u, v]| (0.0..=frame.0).contains(&u) && (0.0..=frame.1).contains(&v))
        })
    }

    #[test]
    fn a_jog_brings_the_belt_around_the_part_into_view_over_the_camera_envelope() {
        let mut rng = SimRng::new(2424);
        let (mut jogged, mut in_view_already) = (0, 0);
        for case in 0..400 {
            // A belt along x, a camera anywhere in the envelope over its station.
            let belt_top = rng.range(0.5, 0.9);
            let (belt_y, half) = (rng.range(-0.6, -0.3), rng.range(0.12, 0.25));
            let station = Point3::new(rng.range(-0.1, 0.2), belt_y, belt_top);
            let Some((calibration, (w, h), _)) = camera_over(&mut rng, &station, case) else {
                continue;
            };
            let frame = (f64::from(w), f64::from(h));
            let s = Surroundings {
                reach_m: rng.range(0.06, 0.14),
                belt_top_z_m: belt_top,
                belt: BeltBand {
                    centre_y_m: belt_y,
                    half_width_m: half,
                },
            };
            // A part upstream of the station, well in view or near the view's edge.
            let part = Point3::new(
                station.x - rng.range(0.0, 0.35),
                belt_y + rng.range(-0.7, 0.7) * half,
                belt_top + rng.range(0.03, 0.12),
            );
            // The sampled polygon's inner circle, 0.99 of the reach, must be in view.
            let inner = 0.99 * s.reach_m;
            match surroundings_travel_m(&calibration, (w, h), &part, &s) {
                Some(travel) => {
                    jogged += 1;
                    let face = calibration.with_end_face_height(part.z);
                    let to_centre = face
                        .pixel_to_plane(calibration.cx_px, calibration.cy_px)
                        .map_or(f64::NAN, |p| p.x - part.x);
                    assert!(travel > 0.0 && travel <= to_centre + 1e-9, "case {case}");
                    assert!(
                        circle_in_view(&calibration, frame, &part, inner, &s, (travel, false)),
                        "case {case}: the part's surroundings are not in view after {travel} m"
                    );
                    assert!(
                        !circle_in_view(&calibration, frame, &part, s.reach_m, &s, (0.0, true)),
                        "case {case}: a jog where the upstream side was in view"
                    );
                }
                None => {
                    let upstream_seen =
                        circle_in_view(&calibration, frame, &part, inner, &s, (0.0, true));
                    in_view_already += usize::from(upstream_seen);
                }
            }
        }
        assert!(jogged >= 40, "only {jogged} of 400 parts were jogged");
        assert!(
            in_view_already >= 100,
            "only {in_view_already} already in view"
        );
    }

    /// Bottles cut by the frame's border, standing or lying at any yaw, near parts seen by
    /// cameras over the whole envelope: the belt is jogged exactly when a bottle's axis comes
    /// within the reach of the part's axis at a point upstream of it (the nearest of 400 points
    /// along the axis, brute force), by the travel that brings the part's end face to the
    /// optical axis.
    #[test]
    fn a_cut_bottle_upstream_within_reach_brings_the_part_to_the_optical_axis() {
        let mut rng = SimRng::new(2431);
        let (mut jogged, mut near_but_centred, mut left) = (0, 0, 0);
        for case in 0..600 {
            let belt_top = rng.range(0.5, 0.9);
            let station = Point3::new(rng.range(-0.1, 0.2), rng.range(-0.6, -0.3), belt_top);
            let Some((calibration, _, eye)) = camera_over(&mut rng, &station, case) else {
                continue;
            };
            let part = Point3::new(
                station.x + rng.range(-0.3, 0.1),
                station.y + rng.range(-0.1, 0.1),
                belt_top + rng.range(0.03, 0.12),
            );
            let reach = rng.range(0.06, 0.14);
            let length = rng.range(0.1, 0.25);
            let axes: Vec<[Point3<f64>; 2]> = (0..1 + rng.below(3))
                .map(|_| {
                    let (a, d) = (rng.range(-PI, PI), rng.range(0.0, 0.3));
                    let base = Point3::new(part.x + d * a.cos(), part.y + d * a.sin(), belt_top);
                    let top = if rng.uniform() < 0.5 {
                        base + Vector3::z() * length
                    } else {
                        let yaw = rng.range(-PI, PI);
                        base + Vector3::new(yaw.cos(), yaw.sin(), 0.0) * length
                    };
                    [base, top]
                })
                .collect();
            // The nearest of 400 points along each axis, in the belt's plane.
            let nearest: Vec<(f64, f64)> = axes
                .iter()
                .map(|[a, b]| {
                    (0..=400)
                        .map(|k| a + (b - a) * (f64::from(k) / 400.0))
                        .map(|q| ((q.x - part.x).hypot(q.y - part.y), q.x - part.x))
                        .fold((f64::INFINITY, 0.0), |m, v| if v.0 < m.0 { v } else { m })
                })
                .collect();
            // Too near a boundary for 400 samples to tell: drawn again.
            if nearest
                .iter()
                .any(|&(d, dx)| (d - reach).abs() < 2e-3 || dx.abs() < 2e-3)
            {
                continue;
            }
            let wanted = nearest.iter().any(|&(d, dx)| d < reach && dx < 0.0);
            // Where the line from the eye through the station (the optical axis) meets the
            // part's end-face plane.
            let forward = (station - eye).normalize();
            let meet = eye + forward * ((part.z - eye.z) / forward.z);
            let to_axis = meet.x - part.x;
            match cut_neighbour_travel_m(&calibration, &part, &axes, reach) {
                Some(travel) => {
                    jogged += 1;
                    assert!(wanted, "case {case}: jogged for no bottle near upstream");
                    assert!(
                        (part.x + travel - meet.x).abs() < 1e-6,
                        "case {case}: the part ends {} m from the axis",
                        part.x + travel - meet.x
                    );
                }
                None if wanted => {
                    assert!(to_axis < MIN_JOG_M, "case {case}: not jogged");
                    near_but_centred += 1;
                }
                None => left += 1,
            }
        }
        assert!(jogged >= 100, "only {jogged} jogged");
        assert!(
            near_but_centred >= 20,
            "only {near_but_centred} at the axis already"
        );
        assert!(left >= 100, "only {left} left alone");
    }
}

#[cfg(test)]
impl Sighting {
    /// A look that found `target` and `other_parts` in `detections` and nothing else (a blank
    /// image, no bottles, no timings), for tests of what follows from it.
    pub(super) fn of_parts(
        detections: Vec<crate::detect::Detection>,
        target: Option<super::PartSighting>,
        other_parts: Vec<super::PartSighting>,
    ) -> Self {
        Self {
            image: image::RgbImage::new(1, 1),
            detections,
            target,
            other_parts,
            bottles: Vec::new(),
            at_station: None,
            render_ms: 0.0,
            detect_ms: 0.0,
            metrology_ms: 0.0,
        }
    }
}

#[cfg(test)]
#[path = "duplicate_tube_tests.rs"]
mod duplicate_tube_tests;
