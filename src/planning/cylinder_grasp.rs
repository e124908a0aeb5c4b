//! Picks of a cylinder on the belt by its body, the jaws closing across its diameter from
//! above: one lying on its side is gripped with the jaws square to its axis anywhere along the
//! span the pads may close on; one standing is gripped as a tube is, as low as the gripper's
//! palm still clears its top. Candidates over the grip's place along the axis, its yaw, its lean
//! and every IK branch are scored by their smallest clearance to everything else along the
//! descent, grasp and lift, as the part's grasp search scores them. Written for any cylinder
//! (a foreign object cleared off the belt, a tube fallen over).

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rapier3d::geometry::SharedShape;

use super::grasp_search::{Approach, GraspPose, GraspRanking, ScoredGrasp};
use super::pick_planner::{
    APPROACH_M, FINGERTIP_BELOW_TCP_M, LINE_STEP_M, PART_OBSTACLE, PLANNING_MARGIN_M,
};
use super::{
    CLEARANCE_CAP_M, Carried, CollisionChecker, LinkMount, Obstacle, Payload, PickPlan,
    PickPlanner, straight_line,
};
use crate::kinematics::{DOF, IkSolver, JointVector};
use crate::math::pose_to_physics;
use crate::outcome::{Failure, FailureReason, fail};
use crate::station::PerceivedObstacle;

/// Spacing of the grip's places along a lying cylinder's axis, m.
const ALONG_STEP_M: f64 = 0.01;
/// Yaws of the jaw line from square to the axis (lying) or from the first try (standing), deg.
const LYING_YAWS_DEG: [f64; 10] = [
    0.0, 180.0, 15.0, -15.0, 195.0, 165.0, 30.0, -30.0, 210.0, 150.0,
];
/// Yaw step around a standing cylinder, deg.
const STANDING_YAW_STEP_DEG: f64 = 15.0;
/// Leans of the gripper about its jaw line, upright first, deg.
const TILTS_DEG: [f64; 5] = [0.0, 20.0, -20.0, 35.0, -35.0];
/// The pads' smallest overlap with the span they may close on, along the axis, m.
const PAD_MIN_OVERLAP_M: f64 = 0.015;
/// Clearance the open jaws keep to the cylinder itself on the way down (its own pose is fitted,
/// so the margin to everything else would forbid every grasp), m.
const TARGET_MARGIN_M: f64 = 0.002;
/// A cylinder on the belt to be picked by its body.
#[derive(Debug, Clone)]
pub struct GripCylinder {
    /// Middle of the cylinder, world, m.
    pub centre: Point3<f64>,
    /// Its axis, world, a unit vector (lying: near horizontal; standing: near vertical).
    pub axis: Vector3<f64>,
    /// Radius of the body the pads close on, m.
    pub radius_m: f64,
    /// Whole length along the axis, m.
    pub length_m: f64,
    /// The span along the axis the pads may close on, from the middle, m (the body, not a neck).
    pub grip_span_m: [f64; 2],
    /// Mass, kg.
    pub mass_kg: f64,
    /// Squeeze force of each jaw, N.
    pub grip_force_n: f64,
    /// The cylinder as the planner's obstacle (as perceived, grown for its uncertainty).
    pub obstacle: PerceivedObstacle,
}

impl GripCylinder {
    /// Whether it lies on its side rather than stands.
    pub fn lying(&self) -> bool {
        self.axis.z.abs() < std::f64::consts::FRAC_1_SQRT_2
    }

    /// The point `along_m` from the middle along the axis.
    fn at(&self, along_m: f64) -> Point3<f64> {
        self.centre + self.axis * along_m
    }
}

/// A planned pick of a cylinder: the motion, what the jaws then carry and how they hold it.
#[derive(Debug, Clone)]
pub struct CylinderPick {
    /// Down to the body and up with it.
    pub pick: PickPlan,
    /// The body as carried, in the TCP frame.
    pub carried: Carried,
    /// Each pad's distance from the centre line when closed on the body, m.
    pub grip_m: f64,
    /// Each pad's distance from the centre line when open, m.
    pub open_m: f64,
    /// What the grip holds.
    pub payload: Payload,
    /// The checker the pick was planned with (the cylinder itself as [`PART_OBSTACLE`]).
    pub checker: CollisionChecker,
}

/// One candidate grasp's TCP poses, world: above where the descent starts, at the grasp and
/// where the lift ends.
struct Candidate {
    pose: GraspPose,
    above: Isometry3<f64>,
    at: Isometry3<f64>,
    lifted: Isometry3<f64>,
}

impl PickPlanner {
    /// How far above the TCP the gripper's palm (the lowest face of the body the fingers hang
    /// from) sits along the tool axis, m.
    pub(super) fn palm_above_tcp_m(&self) -> f64 {
        let tcp_z = self.model.flange_from_tcp.translation.z;
        let palm_z = self
            .robot_shapes
            .iter()
            .filter(|s| matches!(s.mount, LinkMount::Dh(DOF)))
            .map(|s| {
                let aabb = s.shape.compute_aabb(&pose_to_physics(&s.mount_from_shape));
                f64::from(aabb.maxs.z)
            })
            .fold(f64::NEG_INFINITY, f64::max);
        if palm_z.is_finite() {
            tcp_z - palm_z
        } else {
            0.0
        }
    }

    /// The pick of `cylinder` with the most clearance from the arm at `q_now`, among
    /// `obstacles` (everything perceived on the belt but the cylinder) and the cell's scenery.
    pub fn plan_cylinder_pick(
        &self,
        cylinder: &GripCylinder,
        obstacles: &[PerceivedObstacle],
        q_now: &JointVector,
        pad_friction: f64,
    ) -> Result<CylinderPick, Failure> {
        let base_from_world = self.world_from_base.inverse();
        let as_obstacle = |o: &PerceivedObstacle, name: &str| Obstacle {
            name: name.to_owned(),
            base_from_shape: base_from_world * o.world_from_shape,
            shape: o.shape.clone(),
        };
        let checker_of = |obstacles: Vec<Obstacle>, margin_m: f64| {
            CollisionChecker::new(
                self.model.clone(),
                self.robot_shapes.clone(),
                self.finger_reference_m,
                obstacles,
                margin_m,
            )
        };
        let belt_top_in_base = (base_from_world * Point3::new(0.0, 0.0, self.belt_top_z)).z;
        let below_belt_top = |o: &Obstacle| {
            let aabb = o.shape.compute_aabb(&pose_to_physics(&o.base_from_shape));
            f64::from(aabb.maxs.z) <= belt_top_in_base + 1e-3
        };
        let (floor, scenery): (Vec<Obstacle>, Vec<Obstacle>) =
            self.obstacles.iter().cloned().partition(below_belt_top);
        let seen: Vec<Obstacle> = obstacles.iter().map(|o| as_obstacle(o, o.name)).collect();
        let target = as_obstacle(&cylinder.obstacle, PART_OBSTACLE);
        let scoring = checker_of(scenery.iter().cloned().chain(seen.clone()).collect(), 0.0);
        let floor_checker = checker_of(floor, PLANNING_MARGIN_M);
        let target_checker = checker_of(vec![target.clone()], TARGET_MARGIN_M);
        let mut checker = checker_of(self.obstacles.clone(), PLANNING_MARGIN_M);
        for obstacle in seen.into_iter().chain([target]) {
            checker.add_obstacle(obstacle);
        }
        // Open around the cylinder as perceived (grown for its fit's uncertainty).
        let seen_radius_m = cylinder
            .obstacle
            .shape
            .as_cylinder()
            .map_or(0.0, |c| f64::from(c.radius));
        let open_m = cylinder.radius_m.max(seen_radius_m) + self.open_clearance_m;
        let candidates = self.cylinder_candidates(cylinder, obstacles)?;
        let mut poses = Vec::new();
        for candidate in candidates {
            let at = base_from_world * candidate.at;
            let branches = self.ik.solve(&at).by_distance_from(q_now);
            let Some(first) = branches.first() else {
                continue;
            };
            let bound_m = scoring
                .tool_clearance(first, open_m, &[], CLEARANCE_CAP_M)
                .map_or(CLEARANCE_CAP_M, |c| c.distance_m);
            poses.push((candidate, branches, bound_m));
        }
        // Stable: among equal bounds the order of preference stands.
        poses.sort_by(|a, b| b.2.total_cmp(&a.2));
        let mut ranking = GraspRanking {
            candidates: poses.iter().map(|(_, b, _)| b.len()).sum(),
            ..GraspRanking::default()
        };
        let mut best_m = f64::NEG_INFINITY;
        'poses: for (candidate, branches, bound_m) in &poses {
            for q_at in branches {
                if *bound_m <= best_m {
                    break 'poses;
                }
                let (above, at, lifted) = (
                    base_from_world * candidate.above,
                    base_from_world * candidate.at,
                    base_from_world * candidate.lifted,
                );
                let ik = &self.ik;
                let (Some(rise), Some(up)) = (
                    straight_line(ik, &at, &above, q_at, LINE_STEP_M),
                    straight_line(ik, &at, &lifted, q_at, LINE_STEP_M),
                ) else {
                    continue;
                };
                ranking.scored += 1;
                ranking.reachable = true;
                // The open jaws must pass the cylinder itself on the way down: the palm above
                // a standing one, the fingers beside it.
                if rise.iter().any(|q| {
                    target_checker
                        .check_configuration(q, open_m, None, &[])
                        .is_some()
                }) {
                    continue;
                }
                let mut clearance_m = CLEARANCE_CAP_M;
                let mut nearest = None;
                for q in rise.iter().chain(up.iter().skip(1)) {
                    if let Some((link, obstacle)) =
                        floor_checker.check_configuration(q, open_m, None, &[])
                    {
                        clearance_m = 0.0;
                        nearest = Some(super::Clearance {
                            distance_m: 0.0,
                            link,
                            obstacle,
                        });
                        break;
                    }
                    if let Some(hit) = scoring.clearance(q, open_m, None, &[], clearance_m) {
                        clearance_m = hit.distance_m;
                        nearest = Some(hit);
                        if clearance_m <= best_m {
                            break;
                        }
                    }
                }
                if clearance_m > best_m {
                    best_m = clearance_m;
                    let mut down = rise;
                    down.reverse();
                    ranking.grasps.push(ScoredGrasp {
                        pose: candidate.pose,
                        approach: Approach::Vertical,
                        down,
                        up,
                        clearance_m,
                        nearest,
                    });
                }
            }
        }
        ranking.grasps.reverse();
        let pick = self
            .first_clear_pick(&ranking, &checker, open_m, q_now)
            .map_err(|failure| match failure.reason {
                FailureReason::Unreachable => Failure::new(
                    FailureReason::Unreachable,
                    format!(
                        "no IK solution to grasp the {} at ({:.3}, {:.3})",
                        cylinder.obstacle.name, cylinder.centre.x, cylinder.centre.y
                    ),
                ),
                _ => failure,
            })?;
        // What the jaws carry: the cylinder where it lay, seen from the TCP at the grasp.
        let Some(q_at) = pick.lift_path.first() else {
            return fail(FailureReason::Panic, "a pick without a grasp");
        };
        let base_from_tcp = crate::kinematics::tcp_pose(&self.model, q_at);
        let world_from_tcp = self.world_from_base * base_from_tcp;
        let carried = Carried {
            tcp_from_shape: world_from_tcp.inverse() * cylinder.obstacle.world_from_shape,
            shape: cylinder.obstacle.shape.clone(),
        };
        Ok(CylinderPick {
            pick,
            carried,
            grip_m: cylinder.radius_m,
            open_m,
            payload: Payload {
                mass_kg: cylinder.mass_kg,
                grip_force_n: cylinder.grip_force_n,
                pad_friction,
            },
            checker,
        })
    }

    /// The candidate grasps of `cylinder` in their order of preference, with the obstacles'
    /// highest point setting where descents start and lifts end.
    fn cylinder_candidates(
        &self,
        cylinder: &GripCylinder,
        obstacles: &[PerceivedObstacle],
    ) -> Result<Vec<Candidate>, Failure> {
        let belt_top = self.belt_top_z;
        let obstacle_top = obstacles
            .iter()
            .chain([&cylinder.obstacle])
            .map(|o| o.top_z)
            .fold(belt_top, f64::max);
        // Grip where the tube grasp grips (the fingertips just above the belt), or for a
        // standing cylinder as low as the palm still clears its top.
        let low_z = belt_top + super::GRASP_TCP_ABOVE_BOTTOM_M;
        let grasp_z = if cylinder.lying() {
            low_z
        } else {
            low_z.max(cylinder.obstacle.top_z + PLANNING_MARGIN_M - self.palm_above_tcp_m())
        };
        let fingertip_z = grasp_z - FINGERTIP_BELOW_TCP_M;
        if !cylinder.lying() {
            let span_top_z = cylinder.at(cylinder.grip_span_m[1]).z;
            if fingertip_z > span_top_z - PAD_MIN_OVERLAP_M {
                return fail(
                    FailureReason::Unreachable,
                    format!(
                        "the standing {} is too tall for the fingers to reach its body",
                        cylinder.obstacle.name
                    ),
                );
            }
        }
        // From above everything near, and as far above the cylinder's own top as the tube
        // grasp's descent starts above a tube's.
        let approach_z = (grasp_z + APPROACH_M)
            .max(obstacle_top + FINGERTIP_BELOW_TCP_M + 0.03)
            .max(cylinder.obstacle.top_z + FINGERTIP_BELOW_TCP_M + APPROACH_M / 2.0);
        let lift_z = grasp_z + (obstacle_top - belt_top + 0.04).max(APPROACH_M);
        let mut places: Vec<(f64, f64)> = Vec::new();
        if cylinder.lying() {
            let axis_yaw = cylinder.axis.y.atan2(cylinder.axis.x);
            // Along the span, the middle of it first, then outwards.
            let [from, to] = cylinder.grip_span_m;
            let half_m = ((to - from) / 2.0 - PAD_MIN_OVERLAP_M).max(0.0);
            let mid = (from + to) / 2.0;
            let steps = (half_m / ALONG_STEP_M).floor() as i32;
            let mut along: Vec<f64> = vec![mid];
            for k in 1..=steps {
                let d = f64::from(k) * ALONG_STEP_M;
                along.extend([mid + d, mid - d]);
            }
            for s in along {
                for yaw_deg in LYING_YAWS_DEG {
                    places.push((
                        s,
                        axis_yaw + std::f64::consts::FRAC_PI_2 + yaw_deg.to_radians(),
                    ));
                }
            }
        } else {
            let steps = (360.0 / STANDING_YAW_STEP_DEG).round() as i32;
            places.extend(
                (0..steps).map(|k| (0.0, f64::from(k) * STANDING_YAW_STEP_DEG.to_radians())),
            );
        }
        let mut candidates = Vec::new();
        for tilt_deg in TILTS_DEG {
            for &(along_m, yaw_rad) in &places {
                let p = if cylinder.lying() {
                    cylinder.at(along_m)
                } else {
                    cylinder.centre
                };
                let pose = GraspPose {
                    yaw_rad,
                    tilt_rad: tilt_deg.to_radians(),
                };
                let tcp = |z: f64| self.world_from_tcp(Vector3::new(p.x, p.y, z), pose);
                candidates.push(Candidate {
                    pose,
                    above: tcp(approach_z),
                    at: tcp(grasp_z),
                    lifted: tcp(lift_z),
                });
            }
        }
        Ok(candidates)
    }

    /// The TCP pose in the world at `xyz` with the gripper's `pose`.
    fn world_from_tcp(&self, xyz: Vector3<f64>, pose: GraspPose) -> Isometry3<f64> {
        self.world_from_base * self.base_from_tcp(xyz, pose.yaw_rad, pose.tilt_rad)
    }
}

/// A bounding cylinder along the axis `axis` through `centre` as a perceived obstacle (the
/// shape's own axis is its local y), for tests and callers that build one by hand.
pub fn cylinder_obstacle(
    name: &'static str,
    centre: &Point3<f64>,
    axis: &Vector3<f64>,
    radius_m: f64,
    length_m: f64,
) -> PerceivedObstacle {
    let rotation = UnitQuaternion::rotation_between(&Vector3::y(), axis)
        .unwrap_or_else(|| UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0));
    let world_from_shape = Isometry3::from_parts(Translation3::from(centre.coords), rotation);
    let half = length_m / 2.0;
    let top_z =
        centre.z + (axis.z.abs() * half + (1.0 - axis.z * axis.z).max(0.0).sqrt() * radius_m);
    PerceivedObstacle {
        name,
        world_from_shape,
        shape: SharedShape::cylinder(half as f32, radius_m as f32),
        top_z,
    }
}
