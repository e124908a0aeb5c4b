//! One bottle seen in several detector boxes: the sightings of a frame merged, each explained
//! box's best reading kept ([`BottleFitter::merge_sightings`]).

use nalgebra::{Point3, Vector3};

use super::bottle_fit::{BottleFitter, BottlePose};
use super::camera_percept::BottleSighting;

/// Two poses of one bottle whose axes' ends lie this near are one reading, m.
const SAME_READING_M: f64 = 0.01;

impl BottleFitter {
    /// The bottle's axis in the world, base to top.
    fn axis_segment(&self, pose: &BottlePose) -> (Point3<f64>, Point3<f64>) {
        let w = &pose.world_from_bottle;
        (
            w * Point3::origin(),
            w * Point3::new(0.0, 0.0, self.height_m),
        )
    }

    /// Whether two poses are one reading: their axes' ends lie within [`SAME_READING_M`] of
    /// each other's.
    fn coincide(&self, a: &BottlePose, b: &BottlePose) -> bool {
        let (a0, a1) = self.axis_segment(a);
        let (b0, b1) = self.axis_segment(b);
        (a0 - b0).norm() < SAME_READING_M && (a1 - b1).norm() < SAME_READING_M
    }

    /// Whether two poses' bodies would pass through each other: their axes come nearer than a
    /// radius.
    pub(super) fn interpenetrate(&self, a: &BottlePose, b: &BottlePose) -> bool {
        let (a0, a1) = self.axis_segment(a);
        let (b0, b1) = self.axis_segment(b);
        segments_distance(&a0, &a1, &b0, &b1) < self.radius_m
    }

    /// The sightings of one frame from its fitted boxes: `fitted[k]` is box `boxes[k]`'s poses
    /// (best first) and whether they explain the box. Explained boxes come first, then the rest,
    /// each in the detector's order (its confidence). A box whose best pose passes through a
    /// pose of a sighting already made is taken for that bottle: when its fit explained it, that
    /// best pose joins the sighting's poses as a further reading (after them: the sighting's
    /// first stays its best), so that a second bottle standing where one reading of the first
    /// lies is still kept clear of; a box no pose explains (a fragment of a bottle) adds
    /// nothing. Returns the sightings and, per box, the index of the sighting that holds it.
    pub(super) fn merge_sightings(
        &self,
        boxes: &[(usize, [f64; 4])],
        fitted: &[(usize, Vec<BottlePose>, bool)],
    ) -> (Vec<BottleSighting>, Vec<usize>) {
        // Explained boxes first, then the rest, each in the detector's order (its confidence).
        let mut order: Vec<usize> = (0..fitted.len()).collect();
        order.sort_by_key(|&k| !fitted[k].2);
        let mut sightings: Vec<BottleSighting> = Vec::new();
        let mut holder = vec![0usize; boxes.len()];
        for k in order {
            let (_, poses, explained) = &fitted[k];
            let same = poses.first().and_then(|p| {
                sightings
                    .iter()
                    .position(|s| s.poses.iter().any(|q| self.interpenetrate(p, q)))
            });
            match same {
                // Taken for a bottle already seen: an explained box's best pose joins that
                // sighting's poses as a further reading, unless the sighting holds it already.
                Some(s) => {
                    holder[k] = s;
                    for p in poses.iter().take(usize::from(*explained)) {
                        let known = sightings[s]
                            .poses
                            .iter()
                            .any(|q| q.lying == p.lying && self.coincide(p, q));
                        if !known {
                            sightings[s].poses.push(*p);
                        }
                    }
                }
                None => {
                    holder[k] = sightings.len();
                    sightings.push(BottleSighting {
                        detection: boxes[k].0,
                        poses: poses.clone(),
                    });
                }
            }
        }
        (sightings, holder)
    }
}

/// Distance between the segments `a0`-`a1` and `b0`-`b1`, m.
fn segments_distance(
    a0: &Point3<f64>,
    a1: &Point3<f64>,
    b0: &Point3<f64>,
    b1: &Point3<f64>,
) -> f64 {
    // Sampled finely enough for a decision at a bottle's radius.
    let steps = 40;
    let at = |p: &Point3<f64>, q: &Point3<f64>, t: f64| p + (q - p) * t;
    let mut best = f64::INFINITY;
    for i in 0..=steps {
        let p = at(a0, a1, f64::from(i) / f64::from(steps));
        let d: Vector3<f64> = b1 - b0;
        let l2 = d.norm_squared();
        let t = if l2 > 0.0 {
            ((p - b0).dot(&d) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        best = best.min((p - at(b0, b1, t)).norm());
    }
    best
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    use super::super::bottle_fit::BottlePose;
    use super::super::bottle_fit::tests::{BELT_TOP_Z, fitter};

    fn standing(x: f64, y: f64) -> BottlePose {
        BottlePose {
            world_from_bottle: Isometry3::from_parts(
                Translation3::new(x, y, BELT_TOP_Z),
                UnitQuaternion::identity(),
            ),
            lying: false,
            residual_px: 1.0,
        }
    }

    fn lying(x: f64, y: f64, yaw: f64, radius: f64) -> BottlePose {
        // The axis along the world's x turned by `yaw`, resting on the belt.
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw)
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2);
        BottlePose {
            world_from_bottle: Isometry3::from_parts(
                Translation3::new(x, y, BELT_TOP_Z + radius),
                rotation,
            ),
            lying: true,
            residual_px: 1.0,
        }
    }

    /// A lying reading of one box passes through a standing bottle another box explains: the
    /// second box is taken for the first bottle, and its standing reading is kept beside the
    /// first box's. The same standing reading twice is kept once; a box its fit does not explain
    /// adds nothing; a box clear of every sighting is a sighting of its own.
    #[test]
    fn a_box_taken_for_a_bottle_already_seen_keeps_its_reading() {
        let f = fitter();
        let r = f.radius_m;
        // Box 0: a bottle lying along x from (0, -0.45); its axis passes over (0.1, -0.45).
        let first = vec![lying(0.0, -0.45, 0.0, r), standing(0.02, -0.5)];
        let boxes: Vec<(usize, [f64; 4])> = (0..5).map(|k| (k, [0.0; 4])).collect();
        let fitted = vec![
            (0, first.clone(), true),
            // Box 1: a standing bottle where the lying reading of box 0 lies.
            (1, vec![standing(0.1, -0.45)], true),
            // Box 2: the same standing reading again, 2 mm away.
            (2, vec![standing(0.102, -0.45)], true),
            // Box 3: a fragment no pose explains, at the lying reading's far end.
            (3, vec![standing(0.19, -0.45)], false),
            // Box 4: a bottle 0.3 m away.
            (4, vec![standing(0.1, -0.15)], true),
        ];
        let (sightings, holder) = f.merge_sightings(&boxes, &fitted);
        assert_eq!(sightings.len(), 2, "{sightings:?}");
        assert_eq!(holder, vec![0, 0, 0, 0, 1]);
        // The first box's readings first, best first, then box 1's standing bottle.
        assert_eq!(sightings[0].poses.len(), 3, "{:?}", sightings[0].poses);
        assert_eq!(sightings[0].poses[..2], first[..]);
        assert_eq!(sightings[0].poses[2], standing(0.1, -0.45));
        assert_eq!(sightings[1].detection, 4);
    }
}
