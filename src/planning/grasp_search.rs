//! The grasp search: candidate picks over the gripper's yaw and lean, the direction the fingers
//! come down in and every IK branch, each scored by its smallest clearance to the obstacles
//! along the descent, the grasp and the lift, ranked best first.

use nalgebra::{Isometry3, Point3, Vector3};

use super::pick_planner::{
    APPROACH_M, FINGERTIP_BELOW_TCP_M, LINE_STEP_M, PAD_HALF_WIDTH_M, PART_OBSTACLE,
    PLANNING_MARGIN_M,
};
use super::{Clearance, CollisionChecker, PickPlanner, straight_line};
use crate::kinematics::{IkSolver, JointVector};
use crate::station::Percept;

/// Clearance beyond which candidates count as equally good, m: past it the search keeps the
/// first in its order of preference (upright, the jaws across the line to the nearest
/// obstacle, the arm's nearest branch), and stops looking.
pub const CLEARANCE_CAP_M: f64 = 0.02;
/// Leans of the gripper the search starts from, upright first, deg.
const TILTS_DEG: [f64; 5] = [0.0, 25.0, -25.0, 40.0, -40.0];
/// The largest lean the refinement may reach, deg.
const MAX_TILT_DEG: f64 = 40.0;
/// Yaws the search starts from at each lean, offsets from the preferred one, deg: these first,
/// then the 10-degree steps between them.
pub(super) const COARSE_YAWS_DEG: [f64; 10] = [
    0.0, 180.0, 30.0, -30.0, 210.0, 150.0, 60.0, -60.0, 90.0, 270.0,
];
/// First steps of the continuous refinement around the best candidate (yaw, lean), deg; each
/// round halves them.
const REFINE_STEPS_DEG: (f64, f64) = (5.0, 10.0);
/// Rounds of the refinement.
const REFINE_ROUNDS: usize = 3;

/// Every 10 degrees of yaw that [`COARSE_YAWS_DEG`] leaves out, those nearest the preferred
/// yaw (or its half-turn, the same jaw line) first.
pub(super) fn fine_yaws_deg() -> impl Iterator<Item = f64> {
    let coarse = |deg: f64| {
        COARSE_YAWS_DEG
            .iter()
            .any(|c| (c - deg).rem_euclid(360.0).abs() < 1e-9)
    };
    let mut fine: Vec<f64> = (0..36)
        .map(|k| f64::from(k) * 10.0)
        .filter(|&deg| !coarse(deg))
        .collect();
    // Distance to the jaw line of the preferred yaw: 0 at 0 and 180 degrees, 90 at 90 and 270.
    let off_line = |deg: f64| {
        let d = deg.rem_euclid(180.0);
        d.min(180.0 - d)
    };
    fine.sort_by(|a, b| off_line(*a).total_cmp(&off_line(*b)).then(a.total_cmp(b)));
    fine.into_iter()
}

/// How the open fingers come down onto the part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Approach {
    /// Straight down, whatever the lean.
    Vertical,
    /// Along the leaning tool's own axis: the wrist comes in from the side it leans to.
    AlongTool,
}

/// The gripper's orientation over the part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspPose {
    /// Yaw of the jaw line, world, rad.
    pub yaw_rad: f64,
    /// Lean about the jaw line, rad (0: the tool points straight down).
    pub tilt_rad: f64,
}

/// A candidate whose path has been scored.
#[derive(Debug, Clone)]
pub struct ScoredGrasp {
    /// The gripper's orientation.
    pub pose: GraspPose,
    /// How the fingers come down.
    pub approach: Approach,
    /// Joint path of the descent, from above the part to the grasp.
    pub down: Vec<JointVector>,
    /// Joint path of the lift, from the grasp straight up.
    pub up: Vec<JointVector>,
    /// Smallest clearance along the descent, grasp and lift, m, at most [`CLEARANCE_CAP_M`];
    /// 0 when the fingers come within the planning margin of the belt.
    pub clearance_m: f64,
    /// The pair that sets it, when below the cap.
    pub nearest: Option<Clearance>,
}

/// The search's answer: grasps best first, and how many candidates it weighed.
#[derive(Debug, Clone, Default)]
pub struct GraspRanking {
    /// Scored grasps, the best first (each later one was the best before a better was found).
    pub grasps: Vec<ScoredGrasp>,
    /// Candidates (pose, IK branch and approach) ranked by their clearance bound.
    pub candidates: usize,
    /// Of those, the ones whose whole path was scored.
    pub scored: usize,
    /// Whether any candidate had an IK solution along its whole path.
    pub reachable: bool,
}

/// One pick's search: the part's place, the heights of its lines and what is scored against.
pub struct GraspSearch<'a> {
    planner: &'a PickPlanner,
    /// The obstacles clearance is measured to: all but the part (the fingers close on it) and
    /// what lies below the belt's top (the fingertips stop above it by design; the planner's
    /// margin check keeps them clear).
    scoring: CollisionChecker,
    /// What lies below the belt's top, the belt itself: not scored, but a candidate that comes
    /// within the planning margin of it scores 0.
    floor: CollisionChecker,
    part_xy: [f64; 2],
    grasp_z: f64,
    approach_z: f64,
    lift_z: f64,
    preferred_yaw_rad: f64,
    open_m: f64,
    q_now: JointVector,
}

impl<'a> GraspSearch<'a> {
    /// The search for a pick of `percept`'s part by `planner`, checked by `checker`, from the
    /// arm at `q_now`.
    pub fn new(
        planner: &'a PickPlanner,
        percept: &Percept,
        checker: &CollisionChecker,
        q_now: &JointVector,
    ) -> Self {
        let belt_top = planner.belt_top_z;
        let [x, y] = percept.part_xy;
        let grasp_z = belt_top + planner.grasp_tcp_above_bottom_m(percept.part_height_m);
        let obstacle_top = percept
            .obstacles
            .iter()
            .map(|o| o.top_z)
            .fold(belt_top, f64::max);
        // Lift so the part's bottom clears the bottle and the rails.
        let lift_z = grasp_z + (obstacle_top - belt_top + 0.04).max(APPROACH_M);
        // Come down from above the bottle: the fingertips hang 15 mm below the TCP.
        let approach_z = (grasp_z + APPROACH_M).max(obstacle_top + 0.015 + 0.03);
        // Fingers close across the line to the nearest obstacle first, so neither passes near it.
        let nearest = percept.obstacles.iter().min_by(|a, b| {
            let d = |o: &Isometry3<f64>| (o.translation.x - x).hypot(o.translation.y - y);
            d(&a.world_from_shape).total_cmp(&d(&b.world_from_shape))
        });
        let preferred_yaw_rad = nearest.map_or(0.0, |o| {
            let t = o.world_from_shape.translation;
            (t.y - y).atan2(t.x - x) + std::f64::consts::FRAC_PI_2
        });
        let belt_top_in_base = (planner.world_from_base.inverse() * Point3::new(x, y, belt_top)).z;
        let below_belt_top = |o: &&super::Obstacle| {
            let pose = crate::math::pose_to_physics(&o.base_from_shape);
            f64::from(o.shape.compute_aabb(&pose).maxs.z) <= belt_top_in_base + 1e-3
        };
        let others = checker
            .obstacles()
            .iter()
            .filter(|o| o.name != PART_OBSTACLE);
        let (floor_obstacles, scored_obstacles): (Vec<&super::Obstacle>, Vec<&super::Obstacle>) =
            others.partition(below_belt_top);
        let checker_of = |obstacles: Vec<&super::Obstacle>, margin_m: f64| {
            CollisionChecker::new(
                planner.model.clone(),
                planner.robot_shapes.clone(),
                planner.finger_reference_m,
                obstacles.into_iter().cloned().collect(),
                margin_m,
            )
        };
        let scoring = checker_of(scored_obstacles, 0.0);
        let floor = checker_of(floor_obstacles, PLANNING_MARGIN_M);
        Self {
            planner,
            scoring,
            floor,
            part_xy: [x, y],
            grasp_z,
            approach_z,
            lift_z,
            preferred_yaw_rad,
            open_m: planner.open_offset_m(percept),
            q_now: *q_now,
        }
    }

    /// The TCP poses of a candidate in the arm's base frame: above the part where the descent
    /// starts, at the grasp, and where the lift ends.
    fn poses(
        &self,
        pose: GraspPose,
        approach: Approach,
    ) -> (Isometry3<f64>, Isometry3<f64>, Isometry3<f64>) {
        let [x, y] = self.part_xy;
        let tilt = pose.tilt_rad;
        // A leaning jaw's lower corner hangs deeper: raise the TCP to keep the tips clear.
        let corner_drop =
            FINGERTIP_BELOW_TCP_M * (tilt.cos() - 1.0) + PAD_HALF_WIDTH_M * tilt.abs().sin();
        let grasp_z = self.grasp_z + corner_drop.max(0.0);
        let tcp = |z: f64| {
            self.planner
                .base_from_tcp(Vector3::new(x, y, z), pose.yaw_rad, tilt)
        };
        let at = tcp(grasp_z);
        let above = match approach {
            Approach::Vertical => tcp(self.approach_z),
            Approach::AlongTool => {
                // Back out along the tool axis until as high as the vertical approach starts.
                let back_m = (self.approach_z - grasp_z) / tilt.cos();
                at * nalgebra::Translation3::new(0.0, 0.0, -back_m)
            }
        };
        (above, at, tcp(self.lift_z))
    }

    /// The pose `offset_deg` of yaw from the preferred one at `tilt_deg` of lean.
    fn pose_deg(&self, offset_deg: f64, tilt_deg: f64) -> GraspPose {
        GraspPose {
            yaw_rad: self.preferred_yaw_rad + offset_deg.to_radians(),
            tilt_rad: tilt_deg.to_radians(),
        }
    }

    /// Scores a candidate whose grasp configuration is `q_at`: its smallest clearance along
    /// the grasp, the descent and the lift, measured bottom up. The lift is scored with the
    /// jaws open too: that envelope holds the closed jaws' for everything outside them, and
    /// leaves out what stands between them, the part itself (or a second look at it, which
    /// perception can report as another part beside it).
    /// Scoring stops as soon as the clearance falls to `floor_m` (it could not win then).
    /// `None` when a line has no continuous IK path.
    fn score(
        &self,
        pose: GraspPose,
        approach: Approach,
        q_at: &JointVector,
        floor_m: f64,
    ) -> Option<ScoredGrasp> {
        let (above, at, lifted) = self.poses(pose, approach);
        let ik = &self.planner.ik;
        let rise = straight_line(ik, &at, &above, q_at, LINE_STEP_M)?;
        let up = straight_line(ik, &at, &lifted, q_at, LINE_STEP_M)?;
        let mut clearance_m = CLEARANCE_CAP_M;
        let mut nearest = None;
        let configurations = rise
            .iter()
            .map(|q| (q, self.open_m))
            .chain(up.iter().skip(1).map(|q| (q, self.open_m)));
        for (q, fingers_m) in configurations {
            if let Some((link, obstacle)) = self.floor.check_configuration(q, fingers_m, None, &[])
            {
                clearance_m = 0.0;
                nearest = Some(Clearance {
                    distance_m: 0.0,
                    link,
                    obstacle,
                });
                break;
            }
            if let Some(hit) = self.scoring.clearance(q, fingers_m, None, &[], clearance_m) {
                clearance_m = hit.distance_m;
                nearest = Some(hit);
                if clearance_m <= floor_m {
                    break;
                }
            }
        }
        let mut down = rise;
        down.reverse();
        Some(ScoredGrasp {
            pose,
            approach,
            down,
            up,
            clearance_m,
            nearest,
        })
    }

    /// Every candidate, ranked: the poses over yaw and lean bounded by the tool's clearance at
    /// the grasp (which no arm configuration can improve on), then scored best bound first,
    /// every IK branch and approach of each, until no bound left can beat the best; then the
    /// best refined over continuous yaw and lean.
    pub fn rank(&self) -> GraspRanking {
        let ik = &self.planner.ik;
        let fine = fine_yaws_deg().collect::<Vec<_>>();
        let mut poses = Vec::new();
        for tilt_deg in TILTS_DEG {
            for &offset_deg in COARSE_YAWS_DEG.iter().chain(&fine) {
                let pose = self.pose_deg(offset_deg, tilt_deg);
                let (_, at, _) = self.poses(pose, Approach::Vertical);
                let branches = ik.solve(&at).by_distance_from(&self.q_now);
                let Some(first) = branches.first() else {
                    continue;
                };
                let bound_m = self
                    .scoring
                    .tool_clearance(first, self.open_m, &[], CLEARANCE_CAP_M)
                    .map_or(CLEARANCE_CAP_M, |c| c.distance_m);
                poses.push((pose, branches, bound_m));
            }
        }
        // Stable: among equal bounds the order of preference stands.
        poses.sort_by(|a, b| b.2.total_cmp(&a.2));
        let approaches_of = |pose: &GraspPose| -> &'static [Approach] {
            if pose.tilt_rad == 0.0 {
                &[Approach::Vertical]
            } else {
                &[Approach::Vertical, Approach::AlongTool]
            }
        };
        let mut ranking = GraspRanking {
            candidates: poses
                .iter()
                .map(|(pose, branches, _)| branches.len() * approaches_of(pose).len())
                .sum(),
            ..GraspRanking::default()
        };
        let mut best_m = f64::NEG_INFINITY;
        'poses: for (pose, branches, bound_m) in &poses {
            for q_at in branches {
                for &approach in approaches_of(pose) {
                    // Nothing left can beat the best: every later bound is at most this one.
                    if *bound_m <= best_m {
                        break 'poses;
                    }
                    let Some(scored) = self.score(*pose, approach, q_at, best_m) else {
                        continue;
                    };
                    ranking.scored += 1;
                    ranking.reachable = true;
                    if scored.clearance_m > best_m {
                        best_m = scored.clearance_m;
                        ranking.grasps.push(scored);
                    }
                }
            }
        }
        if let Some(best) = ranking.grasps.last().cloned() {
            let refined = self.refine(best, &mut ranking);
            if refined.clearance_m > best_m {
                ranking.grasps.push(refined);
            }
        }
        ranking.grasps.reverse();
        ranking
    }

    /// Every candidate of the starting grid scored in full, none pruned: what [`Self::rank`]
    /// must match or beat.
    #[cfg(test)]
    pub(super) fn exhaustive(&self) -> Vec<ScoredGrasp> {
        let mut all = Vec::new();
        for tilt_deg in TILTS_DEG {
            for offset_deg in COARSE_YAWS_DEG.into_iter().chain(fine_yaws_deg()) {
                let pose = self.pose_deg(offset_deg, tilt_deg);
                let (_, at, _) = self.poses(pose, Approach::Vertical);
                for q_at in self.planner.ik.solve(&at).by_distance_from(&self.q_now) {
                    for approach in [Approach::Vertical, Approach::AlongTool] {
                        if tilt_deg == 0.0 && approach == Approach::AlongTool {
                            continue;
                        }
                        all.extend(self.score(pose, approach, &q_at, f64::NEG_INFINITY));
                    }
                }
            }
        }
        all
    }

    /// The best candidate improved by a pattern search over continuous yaw and lean, its IK
    /// branch followed from the candidate's own.
    fn refine(&self, mut best: ScoredGrasp, ranking: &mut GraspRanking) -> ScoredGrasp {
        let ik = &self.planner.ik;
        let (mut yaw_step, mut tilt_step) = (
            REFINE_STEPS_DEG.0.to_radians(),
            REFINE_STEPS_DEG.1.to_radians(),
        );
        for _ in 0..REFINE_ROUNDS {
            if best.clearance_m >= CLEARANCE_CAP_M {
                break;
            }
            let base = best.pose;
            let neighbours = [
                (yaw_step, 0.0),
                (-yaw_step, 0.0),
                (0.0, tilt_step),
                (0.0, -tilt_step),
            ];
            for (d_yaw, d_tilt) in neighbours {
                let tilt_rad = base.tilt_rad + d_tilt;
                if tilt_rad.abs() > MAX_TILT_DEG.to_radians() + 1e-9 {
                    continue;
                }
                let pose = GraspPose {
                    yaw_rad: base.yaw_rad + d_yaw,
                    tilt_rad,
                };
                let approach = if tilt_rad == 0.0 {
                    Approach::Vertical
                } else {
                    best.approach
                };
                let (_, at, _) = self.poses(pose, approach);
                let Some(&q_ref) = best.down.last() else {
                    continue;
                };
                let Some(q_at) = ik.solve(&at).nearest(&q_ref) else {
                    continue;
                };
                ranking.candidates += 1;
                let Some(scored) = self.score(pose, approach, &q_at, best.clearance_m) else {
                    continue;
                };
                ranking.scored += 1;
                if scored.clearance_m > best.clearance_m {
                    best = scored;
                }
            }
            yaw_step /= 2.0;
            tilt_step /= 2.0;
        }
        best
    }
}
