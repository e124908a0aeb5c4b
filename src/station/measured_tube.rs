//! Tubes whose place the metrology measured, as evidence against bottle poses: a bottle cannot
//! stand or lie where a tube stands.
//!
//! From 30-35° a standing bottle behind the part (its base hidden by the tube, or its cap cut
//! by the frame's border) can project much as a lying one would, reaching from where the
//! standing bottle is towards the camera, through the part. The part's bore places it within a
//! millimetre or so, so a bottle pose that runs through it is impossible and is dropped before
//! the outline chooses among the rest.

use nalgebra::{Isometry3, Point3};

use super::bottle_fit::{BottleFitter, BottlePose};
use super::bottle_unboxed::BeltBand;
use super::camera_percept::PartSighting;
use crate::scenario::Scenario;

/// The tube's radius is taken this much smaller, m: a pose is impossible only when a point
/// well inside the bottle's body (`BottleFitter::body_points`, at 0.6 of the local radius)
/// lies this far inside the tube, which leaves room for the poses' errors.
const TUBE_SLACK_M: f64 = 0.003;

/// A tube standing on the belt, placed by its measured bore.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredTube {
    /// The tube's axis, world x and y, m.
    pub axis_xy: [f64; 2],
    /// Outer radius, m.
    pub radius_m: f64,
    /// Its end face, world z, m.
    pub top_z_m: f64,
}

impl MeasuredTube {
    /// The tube of `sighting` when its bore was measured and its type named (and agreed with),
    /// with that type's outer radius from `scenario`; `None` otherwise.
    pub fn of_sighting(sighting: &PartSighting, scenario: &Scenario) -> Option<Self> {
        let (_, plane) = sighting.bore.as_ref()?;
        if sighting.unidentified.is_some() || sighting.inconsistency.is_some() {
            return None;
        }
        let kind = scenario.part_types.get(sighting.type_index)?;
        let centre = plane.centre_in_world;
        Some(Self {
            axis_xy: [centre.x, centre.y],
            radius_m: kind.outer_diameter_mm / 2e3,
            top_z_m: centre.z,
        })
    }
}

impl MeasuredTube {
    /// The tubes of those `sightings` that [`Self::of_sighting`] places.
    pub fn of_sightings<'s>(
        sightings: impl Iterator<Item = &'s PartSighting>,
        scenario: &Scenario,
    ) -> Vec<Self> {
        sightings
            .filter_map(|s| Self::of_sighting(s, scenario))
            .collect()
    }
}

/// The belt a look's bottles lie on: its top, the band the unboxed search reads (a single
/// part's look), and the tubes measured on it.
#[derive(Debug, Clone, Copy)]
pub struct BeltScene<'t> {
    /// Top of the belt, world z, m.
    pub top_z_m: f64,
    /// The belt's band, where bottles no box holds are looked for; `None` looks for none.
    pub band: Option<BeltBand>,
    /// Tubes whose bores were measured in the look.
    pub tubes: &'t [MeasuredTube],
}

impl<'t> BeltScene<'t> {
    /// The belt of `scenario` (its top at `top_z_m`) with `tubes` measured on it; with its band
    /// when the look is a single part's (`single_part`), whose bottles the detector missed are
    /// looked for on the belt.
    pub fn of_look(
        scenario: &Scenario,
        top_z_m: f64,
        single_part: bool,
        tubes: &'t [MeasuredTube],
    ) -> Self {
        Self {
            top_z_m,
            band: single_part.then(|| BeltBand::of(&scenario.conveyor)),
            tubes,
        }
    }
}

impl BottleFitter {
    /// Whether the bottle at `world_from_bottle` would pass through `tube` standing on a belt
    /// whose top is at `belt_top_z_m`.
    pub fn passes_through(
        &self,
        world_from_bottle: &Isometry3<f64>,
        tube: &MeasuredTube,
        belt_top_z_m: f64,
    ) -> bool {
        let inner_m = tube.radius_m - TUBE_SLACK_M;
        self.body_points.iter().any(|p: &Point3<f64>| {
            let w = world_from_bottle * p;
            let off_m = (w.x - tube.axis_xy[0]).hypot(w.y - tube.axis_xy[1]);
            off_m < inner_m && (belt_top_z_m..=tube.top_z_m).contains(&w.z)
        })
    }

    /// `poses` without those that pass through one of `tubes`; all of them when every one does
    /// (the measured tubes then cannot decide).
    pub(super) fn clear_of_tubes(
        &self,
        poses: Vec<BottlePose>,
        tubes: &[MeasuredTube],
        belt_top_z_m: f64,
    ) -> Vec<BottlePose> {
        let possible: Vec<BottlePose> = poses
            .iter()
            .filter(|p| {
                !tubes
                    .iter()
                    .any(|t| self.passes_through(&p.world_from_bottle, t, belt_top_z_m))
            })
            .copied()
            .collect();
        if possible.is_empty() { poses } else { possible }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;
    use crate::station::bottle_fit::tests::{BELT_TOP_Z, fitter};

    fn lying(fitter: &BottleFitter, centre: [f64; 2], yaw_rad: f64) -> BottlePose {
        let r = fitter.radius_m;
        let world_from_bottle = Isometry3::from_parts(
            Translation3::new(centre[0], centre[1], BELT_TOP_Z + r),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad)
                * UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
        ) * Isometry3::translation(0.0, 0.0, -fitter.height_m / 2.0);
        BottlePose {
            world_from_bottle,
            lying: true,
            residual_px: 0.0,
        }
    }

    fn standing(centre: [f64; 2]) -> BottlePose {
        BottlePose {
            world_from_bottle: Isometry3::translation(centre[0], centre[1], BELT_TOP_Z),
            lying: false,
            residual_px: 0.0,
        }
    }

    #[test]
    fn a_bottle_through_the_tube_is_impossible_and_one_touching_it_is_not() {
        let f = fitter();
        let (rb, rt) = (f.radius_m, 0.031);
        let tube = MeasuredTube {
            axis_xy: [0.05, -0.45],
            radius_m: rt,
            top_z_m: BELT_TOP_Z + 0.09,
        };
        for k in 0..12 {
            let yaw = std::f64::consts::TAU * f64::from(k) / 12.0;
            let (c, s) = (yaw.cos(), yaw.sin());
            // Standing in contact, and 2 mm into the tube (a pose's error): possible.
            for gap_m in [0.0, -0.002] {
                let d = rb + rt + gap_m;
                let pose = standing([0.05 + d * c, -0.45 + d * s]);
                assert!(
                    !f.passes_through(&pose.world_from_bottle, &tube, BELT_TOP_Z),
                    "yaw {k}: {gap_m}"
                );
            }
            // Standing half way into the tube: impossible.
            let d = (rb + rt) / 2.0;
            let pose = standing([0.05 + d * c, -0.45 + d * s]);
            assert!(
                f.passes_through(&pose.world_from_bottle, &tube, BELT_TOP_Z),
                "yaw {k}"
            );
            // Lying with its side on the tube's, at any yaw of its axis: possible; its axis
            // across the tube's: impossible.
            let d = rb + rt + 0.001;
            let beside = lying(
                &f,
                [0.05 + d * c, -0.45 + d * s],
                yaw + std::f64::consts::FRAC_PI_2,
            );
            assert!(
                !f.passes_through(&beside.world_from_bottle, &tube, BELT_TOP_Z),
                "yaw {k}"
            );
            let across = lying(&f, [0.05 + 0.06 * c, -0.45 + 0.06 * s], yaw);
            assert!(
                f.passes_through(&across.world_from_bottle, &tube, BELT_TOP_Z),
                "yaw {k}"
            );
        }
        // Above a short tube, a lying bottle is no contradiction.
        let short = MeasuredTube {
            top_z_m: BELT_TOP_Z + 0.01,
            ..tube
        };
        let over = lying(&f, [0.05, -0.45], 0.3);
        assert!(f.passes_through(&over.world_from_bottle, &tube, BELT_TOP_Z));
        assert!(!f.passes_through(&over.world_from_bottle, &short, BELT_TOP_Z));
    }

    #[test]
    fn the_tubes_keep_the_possible_poses_or_all_when_none_is() {
        let f = fitter();
        let tube = MeasuredTube {
            axis_xy: [0.05, -0.45],
            radius_m: 0.031,
            top_z_m: BELT_TOP_Z + 0.09,
        };
        let through = standing([0.06, -0.45]);
        let clear = standing([0.2, -0.45]);
        let kept = f.clear_of_tubes(vec![through, clear], &[tube], BELT_TOP_Z);
        assert_eq!(kept, vec![clear]);
        let kept = f.clear_of_tubes(vec![through], &[tube], BELT_TOP_Z);
        assert_eq!(kept, vec![through]);
        let kept = f.clear_of_tubes(vec![through, clear], &[], BELT_TOP_Z);
        assert_eq!(kept, vec![through, clear]);
    }
}
