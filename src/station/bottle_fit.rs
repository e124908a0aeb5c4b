//! Where a bottle stands (or lies) on the belt, from the box a detector drew around it: the
//! bottle's mesh is projected through the calibrated camera in candidate poses and slid over the
//! belt until its box matches the detection.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::camera::CameraCalibration;
use crate::render::mesh::Mesh;
use crate::scenario::BottleSection;

/// Yaw steps of the lying-bottle search over a full turn.
const LYING_YAW_STEPS: usize = 180;
/// Fixed-point iterations that move a hypothesis until its box centre meets the detection.
const FIT_ITERATIONS: usize = 12;
/// A hypothesis whose last move was shorter than this has converged, m.
const CONVERGED_M: f64 = 1e-6;
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
    /// Vertices of the bottle's mesh in its own frame, each once (its silhouette model), as
    /// columns of x, y and z: the box is their projection's extent, taken in vector lanes.
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
}

impl BottleFitter {
    /// A fitter for `bottle` seen by `calibration`.
    pub fn new(calibration: CameraCalibration, bottle: &BottleSection) -> Self {
        // The mesh repeats vertices per face; the silhouette needs each point once.
        let mut points: Vec<Point3<f64>> = Mesh::bottle(bottle.radius_m, bottle.height_m)
            .vertices
            .iter()
            .map(|v| v.position)
            .collect();
        points.sort_by(|a, b| {
            (a.x, a.y, a.z)
                .partial_cmp(&(b.x, b.y, b.z))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        points.dedup();
        Self {
            calibration,
            radius_m: bottle.radius_m,
            height_m: bottle.height_m,
            xs: points.iter().map(|p| p.x).collect(),
            ys: points.iter().map(|p| p.y).collect(),
            zs: points.iter().map(|p| p.z).collect(),
        }
    }

    /// The box (`[x0, y0, x1, y1]`, pixels) the bottle at `world_from_bottle` projects to, or
    /// `None` when a point of it is not in front of the camera.
    ///
    /// The fit projects the mesh a few thousand times per detection, so the bottle-to-camera
    /// transform is composed once and applied as a matrix to every point.
    pub fn projected_box(&self, world_from_bottle: &Isometry3<f64>) -> Option<[f64; 4]> {
        let camera = &self.calibration;
        let camera_from_bottle = camera.world_from_camera.inverse() * world_from_bottle;
        let m = camera_from_bottle
            .rotation
            .to_rotation_matrix()
            .into_inner();
        let t = camera_from_bottle.translation.vector;
        let (fx, fy, cx, cy) = (camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px);
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut nearest_z = f64::INFINITY;
        for ((&x, &y), &z) in self.xs.iter().zip(&self.ys).zip(&self.zs) {
            let cz = m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)] * z + t.z;
            let cx_m = m[(0, 0)] * x + m[(0, 1)] * y + m[(0, 2)] * z + t.x;
            let cy_m = m[(1, 0)] * x + m[(1, 1)] * y + m[(1, 2)] * z + t.y;
            let u = fx * cx_m / cz + cx;
            let v = fy * cy_m / cz + cy;
            nearest_z = if cz < nearest_z { cz } else { nearest_z };
            b[0] = if u < b[0] { u } else { b[0] };
            b[1] = if v < b[1] { v } else { b[1] };
            b[2] = if u > b[2] { u } else { b[2] };
            b[3] = if v > b[3] { v } else { b[3] };
        }
        (nearest_z > 0.0).then_some(b)
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
            let on_mid_plane = |p: [f64; 2]| self.calibration.pixel_to_height(p[0], p[1], mid_z);
            let Ok(want) = on_mid_plane(centre) else {
                continue;
            };
            let (mut x, mut y) = (want.x, want.y);
            let mut fitted = None;
            for _ in 0..FIT_ITERATIONS {
                let Some(b) = self.projected_box(&self.pose_at(lying, yaw, x, y, belt_top_z_m))
                else {
                    break;
                };
                fitted = Some(b);
                // Move by the centre offset, measured on the plane through the bottle's middle.
                let Ok(at) = on_mid_plane([(b[0] + b[2]) / 2.0, (b[1] + b[3]) / 2.0]) else {
                    break;
                };
                let (dx, dy) = (want.x - at.x, want.y - at.y);
                x += dx;
                y += dy;
                if dx.hypot(dy) < CONVERGED_M {
                    break;
                }
            }
            let Some(b) = fitted else {
                continue;
            };
            let residual_px =
                ((0..4).map(|k| (b[k] - box_px[k]).powi(2)).sum::<f64>() / 4.0).sqrt();
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
