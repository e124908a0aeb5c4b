//! Where a bottle stands (or lies) on the belt, from the box a detector drew around it: the
//! bottle's mesh is projected through the calibrated camera in candidate poses and slid over the
//! belt until its box matches the detection.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use super::silhouette::{Silhouette, box_residual_px};
use crate::camera::CameraCalibration;
use crate::render::mesh::Mesh;
use crate::scenario::BottleSection;

/// Yaw steps of the lying-bottle search over a full turn.
const LYING_YAW_STEPS: usize = 180;
/// A hypothesis within this box residual of the best one is kept as well, pixels.
const AMBIGUITY_PX: f64 = 2.0;

/// One pose of the bottle that explains its detected box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BottlePose {
    /// The bottle's pose (origin at its base centre, its axis along local z).
    pub world_from_bottle: Isometry3<f64>,
    /// Lying on its side.
    pub lying: bool,
    /// RMS distance between the box this pose projects to and the detected box, pixels.
    pub residual_px: f64,
}

/// Fits bottle poses to detected boxes for one calibrated camera and one bottle model.
#[derive(Debug, Clone)]
pub struct BottleFitter {
    calibration: CameraCalibration,
    radius_m: f64,
    height_m: f64,
    /// The vertices of the bottle's mesh in its own frame.
    silhouette: Silhouette,
}

impl BottleFitter {
    /// A fitter for `bottle` seen by `calibration`.
    pub fn new(calibration: CameraCalibration, bottle: &BottleSection) -> Self {
        // The mesh repeats vertices per face; the silhouette keeps each point once.
        let mesh = Mesh::bottle(bottle.radius_m, bottle.height_m);
        Self {
            calibration,
            radius_m: bottle.radius_m,
            height_m: bottle.height_m,
            silhouette: Silhouette::of_points(mesh.vertices.iter().map(|v| v.position)),
        }
    }

    /// The box (`[x0, y0, x1, y1]`, pixels) the bottle at `world_from_bottle` projects to, or
    /// `None` when a point of it is not in front of the camera.
    pub fn projected_box(&self, world_from_bottle: &Isometry3<f64>) -> Option<[f64; 4]> {
        self.silhouette
            .projected_box(&self.calibration, world_from_bottle)
    }

    /// The pose of a bottle standing (`lying` false) or lying at `yaw_rad` with its middle over
    /// `(x, y)` on a belt whose top is at `belt_top_z_m`.
    fn pose_at(
        &self,
        lying: bool,
        yaw_rad: f64,
        x: f64,
        y: f64,
        belt_top_z_m: f64,
    ) -> Isometry3<f64> {
        if lying {
            Isometry3::from_parts(
                Translation3::new(x, y, belt_top_z_m + self.radius_m),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad)
                    * UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
            ) * Isometry3::translation(0.0, 0.0, -self.height_m / 2.0)
        } else {
            Isometry3::translation(x, y, belt_top_z_m)
        }
    }

    /// Poses (standing, or lying at any yaw) that explain `box_px`: each hypothesis is slid over
    /// the belt until its projected box is centred on the detection, then scored by the RMS
    /// difference of the four sides. The best pose and every distinct pose within
    /// `AMBIGUITY_PX` (2 px) of it are returned, best first: a lying bottle seen from above can look
    /// the same at mirrored yaws, and the planner must keep clear of each.
    pub fn fit(&self, box_px: &[f64; 4], belt_top_z_m: f64) -> Vec<BottlePose> {
        let centre = [(box_px[0] + box_px[2]) / 2.0, (box_px[1] + box_px[3]) / 2.0];
        let mut hypotheses = vec![(false, 0.0)];
        hypotheses.extend((0..LYING_YAW_STEPS).map(|k| {
            (
                true,
                std::f64::consts::TAU * k as f64 / LYING_YAW_STEPS as f64,
            )
        }));
        let mut poses: Vec<BottlePose> = Vec::new();
        for (lying, yaw) in hypotheses {
            let mid_z = belt_top_z_m
                + if lying {
                    self.radius_m
                } else {
                    self.height_m / 2.0
                };
            let pose_at = |x, y| self.pose_at(lying, yaw, x, y, belt_top_z_m);
            let Some(([x, y], b)) =
                self.silhouette
                    .slide_to_centre(&self.calibration, centre, mid_z, pose_at)
            else {
                continue;
            };
            let residual_px = box_residual_px(&b, box_px);
            poses.push(BottlePose {
                world_from_bottle: self.pose_at(lying, yaw, x, y, belt_top_z_m),
                lying,
                residual_px,
            });
        }
        poses.sort_by(|a, b| a.residual_px.total_cmp(&b.residual_px));
        let best = poses.first().map_or(0.0, |p| p.residual_px);
        let mut kept: Vec<BottlePose> = Vec::new();
        for pose in poses {
            if pose.residual_px > best + AMBIGUITY_PX {
                break;
            }
            if !kept.iter().any(|k| self.same_cylinder(k, &pose)) {
                kept.push(pose);
            }
        }
        kept
    }

    /// Whether two poses occupy nearly the same bounding cylinder (the planner's view of a
    /// bottle, the same whichever end is the base): axes within 10 degrees, middles within 1 cm.
    fn same_cylinder(&self, a: &BottlePose, b: &BottlePose) -> bool {
        let axis = |p: &BottlePose| p.world_from_bottle.rotation * Vector3::z();
        let middle =
            |p: &BottlePose| p.world_from_bottle * Point3::new(0.0, 0.0, self.height_m / 2.0);
        a.lying == b.lying
            && axis(a).dot(&axis(b)).abs() > 10f64.to_radians().cos()
            && (middle(a) - middle(b)).norm() < 0.01
    }
}
