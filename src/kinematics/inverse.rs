//! Closed-form inverse kinematics of the AUBO i5 (joints 2-4 parallel, offset wrist).
//!
//! The derivation follows the UR family's: the wrist centre `p5 = p6 - d6 z6` fixes joint 1 through
//! the lateral offset `D` of the parallel-axis plane; the angle between the flange z axis and that
//! plane's normal fixes joint 5; the normal seen from the flange fixes joint 6; what remains is a
//! planar two-link problem for joints 2 and 3, with joint 4 closing the orientation.

use std::f64::consts::{PI, TAU};

use nalgebra::{Isometry3, Matrix3, Vector3};

use super::{ArmModel, DOF, DhRow, JointVector, KinematicsError};

/// Tolerance by which a pose may lie past the edge of reach and still be clamped onto it.
const REACH_TOLERANCE: f64 = 1e-9;
/// Below this `1 - |cos(theta5)|` the wrist counts as straight (singular): `acos` of a cosine
/// this close to one is noise of order 1e-7 rad, so joint 6 would be read from noise.
const WRIST_SINGULAR_ONE_MINUS_COS: f64 = 1e-14;
/// The twists of the DH rows that the closed form solves (`alpha_0` to `alpha_5`), degrees.
pub(crate) const CLOSED_FORM_ALPHA_DEG: [f64; DOF] = [0.0, 90.0, 180.0, 180.0, -90.0, 90.0];
/// Solutions whose joints all agree within this are the same solution.
const DISTINCT_TOLERANCE_RAD: f64 = 1e-9;

/// An inverse-kinematics solver: every joint vector that puts the TCP at a pose.
pub trait IkSolver {
    /// All solutions within joint limits for `tcp_in_base` (empty when unreachable).
    fn solve(&self, tcp_in_base: &Isometry3<f64>) -> IkSolutions;
}

/// The solutions of one inverse-kinematics query, in a deterministic order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IkSolutions {
    solutions: Vec<JointVector>,
}

impl IkSolutions {
    /// The solutions as a slice.
    pub fn as_slice(&self) -> &[JointVector] {
        &self.solutions
    }

    /// Number of solutions.
    pub fn len(&self) -> usize {
        self.solutions.len()
    }

    /// Whether the pose is unreachable within limits.
    pub fn is_empty(&self) -> bool {
        self.solutions.is_empty()
    }

    /// The solution closest to `reference` (sum of squared joint differences), if any.
    pub fn nearest(&self, reference: &JointVector) -> Option<JointVector> {
        let distance = |q: &JointVector| -> f64 {
            q.iter()
                .zip(reference)
                .map(|(a, b)| (a - b) * (a - b))
                .sum()
        };
        let mut best: Option<(f64, JointVector)> = None;
        for q in &self.solutions {
            let d = distance(q);
            if best.is_none_or(|(best_d, _)| d < best_d) {
                best = Some((d, *q));
            }
        }
        best.map(|(_, q)| q)
    }

    /// The solutions ordered by distance from `reference`, nearest first (ties keep the
    /// solver's order).
    pub fn by_distance_from(&self, reference: &JointVector) -> Vec<JointVector> {
        let distance = |q: &JointVector| -> f64 {
            q.iter()
                .zip(reference)
                .map(|(a, b)| (a - b) * (a - b))
                .sum()
        };
        let mut ordered = self.solutions.clone();
        ordered.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
        ordered
    }

    fn push_distinct(&mut self, q: JointVector) {
        let duplicate = self.solutions.iter().any(|s| {
            s.iter()
                .zip(&q)
                .all(|(a, b)| (a - b).abs() <= DISTINCT_TOLERANCE_RAD)
        });
        if !duplicate {
            self.solutions.push(q);
        }
    }
}

impl IntoIterator for IkSolutions {
    type Item = JointVector;
    type IntoIter = std::vec::IntoIter<JointVector>;

    fn into_iter(self) -> Self::IntoIter {
        self.solutions.into_iter()
    }
}

/// A rigid transform as a rotation matrix and a translation: cheaper than quaternions here,
/// since every rotation below is built from a sine and cosine already at hand.
#[derive(Debug, Clone, Copy)]
struct Frame {
    r: Matrix3<f64>,
    p: Vector3<f64>,
}

impl Frame {
    fn from_isometry(iso: &Isometry3<f64>) -> Self {
        Self {
            r: *iso.rotation.to_rotation_matrix().matrix(),
            p: iso.translation.vector,
        }
    }

    fn compose(&self, other: &Frame) -> Frame {
        Frame {
            r: self.r * other.r,
            p: self.r * other.p + self.p,
        }
    }

    fn inverse(&self) -> Frame {
        let rt = self.r.transpose();
        Frame {
            r: rt,
            p: -(rt * self.p),
        }
    }

    fn transform_point(&self, point: &Vector3<f64>) -> Vector3<f64> {
        self.r * point + self.p
    }
}

/// The DH transform of `row` at an angle given by its sine and cosine.
fn dh_frame(row: &DhRow, s: f64, c: f64) -> Frame {
    let (sa, ca) = (row.alpha_rad.sin(), row.cos_alpha());
    // RotX(alpha) * RotZ(theta), written out.
    let r = Matrix3::new(c, -s, 0.0, s * ca, c * ca, -sa, s * sa, c * sa, ca);
    Frame {
        r,
        p: Vector3::new(row.a_m, -sa * row.d_m, ca * row.d_m),
    }
}

/// The closed-form solver for arms with the AUBO i5's DH structure.
#[derive(Debug, Clone)]
pub struct AnalyticIk {
    arm: ArmModel,
    dh0_from_base: Isometry3<f64>,
    /// DH frame 6 in the TCP's frame (the flange's, when the flange is DH frame 6).
    tcp_from_flange: Isometry3<f64>,
    /// Lateral offset of the parallel-axis plane from the base z axis, along joint 2's axis.
    lateral_offset_m: f64,
}

impl AnalyticIk {
    /// A solver for `arm`; fails when its DH table lacks the structure the closed form needs.
    pub fn new(arm: ArmModel) -> Result<Self, KinematicsError> {
        for (i, (row, expected)) in arm.dh.iter().zip(CLOSED_FORM_ALPHA_DEG).enumerate() {
            let alpha_deg = row.alpha_rad.to_degrees();
            let wrapped = (alpha_deg - expected + 180.0).rem_euclid(360.0) - 180.0;
            if wrapped.abs() > 1e-9 {
                return Err(KinematicsError::UnsupportedGeometry {
                    reason: format!(
                        "alpha of row {} is {alpha_deg} deg, expected {expected}",
                        i + 1
                    ),
                });
            }
        }
        let zero_a = [0, 1, 4, 5];
        if let Some(&i) = zero_a.iter().find(|&&i| arm.dh[i].a_m != 0.0) {
            return Err(KinematicsError::UnsupportedGeometry {
                reason: format!("a of row {} must be 0", i + 1),
            });
        }
        if arm.dh[2].a_m <= 0.0 || arm.dh[3].a_m <= 0.0 {
            return Err(KinematicsError::UnsupportedGeometry {
                reason: "link lengths a2 and a3 must be positive".into(),
            });
        }
        // z3 = -z2 and z4 = z2 (two half-turn twists), so the offsets add up with these signs.
        let lateral_offset_m = arm.dh[1].d_m - arm.dh[2].d_m + arm.dh[3].d_m;
        Ok(Self {
            dh0_from_base: arm.base_from_dh0.inverse(),
            tcp_from_flange: match &arm.dh6_from_flange {
                Some(dh6_from_flange) => (dh6_from_flange * arm.flange_from_tcp).inverse(),
                None => arm.flange_from_tcp.inverse(),
            },
            lateral_offset_m,
            arm,
        })
    }

    /// The arm this solver solves for.
    pub fn arm(&self) -> &ArmModel {
        &self.arm
    }

    /// Every solution for a flange pose given in DH frame 0, as DH angles (not yet limited).
    fn solve_dh(&self, flange_in_dh0: &Isometry3<f64>, out: &mut Vec<JointVector>) {
        let dh = &self.arm.dh;
        let flange = Frame::from_isometry(flange_in_dh0);
        let z6 = flange.r.column(2).into_owned();
        let p5 = flange.p - dh[5].d_m * z6;

        let radius = p5.x.hypot(p5.y);
        let offset = self.lateral_offset_m;
        if radius < offset.abs() * (1.0 - REACH_TOLERANCE) || radius == 0.0 {
            return;
        }
        let phi = p5.y.atan2(p5.x);
        let shoulder = (offset / radius).clamp(-1.0, 1.0).asin();
        let twist12 = dh_frame(&dh[1], 0.0, 1.0);
        for theta1 in [phi + shoulder, phi + PI - shoulder] {
            let (s1, c1) = theta1.sin_cos();
            let joint2_axis = Vector3::new(s1, -c1, 0.0);
            let cos5 = z6.dot(&joint2_axis).clamp(-1.0, 1.0);
            let axis_in_flange = flange.r.transpose() * joint2_axis;
            // DH frame 1' = frame 1 twisted onto joint 2's axis: the planar chain starts there.
            let planar_from_dh0 = dh_frame(&dh[0], s1, c1)
                .compose(&Frame {
                    r: twist12.r,
                    p: Vector3::new(dh[1].a_m, 0.0, 0.0),
                })
                .inverse();
            let planar_from_flange = planar_from_dh0.compose(&flange);
            if (1.0 - cos5.abs()) < WRIST_SINGULAR_ONE_MINUS_COS {
                // Joints 4 and 6 turn about one axis: the solutions form a family. Take the
                // member with q6 = 0, or the nearest one that the elbow can reach.
                let theta5 = if cos5 > 0.0 { 0.0 } else { PI };
                let p5_planar = planar_from_dh0.transform_point(&p5);
                self.singular_wrist_branch(theta1, theta5, &planar_from_flange, &p5_planar, out);
                continue;
            }
            let wrist = cos5.acos();
            let s5_abs = (1.0 - cos5 * cos5).max(0.0).sqrt();
            for (theta5, s5) in [(wrist, s5_abs), (-wrist, -s5_abs)] {
                let (y6, x6) = (axis_in_flange.y / s5, -axis_in_flange.x / s5);
                let norm6 = y6.hypot(x6);
                let theta6 = y6.atan2(x6);
                let wrist_frame = (theta5, s5, cos5, theta6, y6 / norm6, x6 / norm6);
                self.planar_branch(theta1, wrist_frame, &planar_from_flange, out);
            }
        }
    }

    /// Where DH frame 4 lies in the planar frame for the given wrist angles (sines and cosines).
    fn dh4_in_planar(
        &self,
        s5: f64,
        c5: f64,
        s6: f64,
        c6: f64,
        planar_from_flange: &Frame,
    ) -> Frame {
        let dh = &self.arm.dh;
        let dh4_from_flange = dh_frame(&dh[4], s5, c5).compose(&dh_frame(&dh[5], s6, c6));
        planar_from_flange.compose(&dh4_from_flange.inverse())
    }

    /// Solves the planar two-link problem for joints 2-4 and pushes up to two DH solutions.
    /// `wrist` is (theta5, sin, cos, theta6, sin, cos).
    fn planar_branch(
        &self,
        theta1: f64,
        wrist: (f64, f64, f64, f64, f64, f64),
        planar_from_flange: &Frame,
        out: &mut Vec<JointVector>,
    ) {
        let (theta5, s5, c5, theta6, s6, c6) = wrist;
        let dh4_in_planar = self.dh4_in_planar(s5, c5, s6, c6, planar_from_flange);
        let p = dh4_in_planar.p;
        let (a2, a3) = (self.arm.dh[2].a_m, self.arm.dh[3].a_m);
        let cos3 = (p.x * p.x + p.y * p.y - a2 * a2 - a3 * a3) / (2.0 * a2 * a3);
        if cos3.abs() > 1.0 + REACH_TOLERANCE {
            return;
        }
        let cos3 = cos3.clamp(-1.0, 1.0);
        let elbow = cos3.acos();
        let sin_elbow = (1.0 - cos3 * cos3).max(0.0).sqrt();
        let psi = dh4_in_planar.r[(1, 0)].atan2(dh4_in_planar.r[(0, 0)]);
        let toward_wrist = p.y.atan2(p.x);
        for (theta3, s3) in [(elbow, sin_elbow), (-elbow, -sin_elbow)] {
            let theta2 = toward_wrist - (-a3 * s3).atan2(a2 + a3 * cos3);
            let theta4 = psi - theta2 + theta3;
            out.push([theta1, theta2, theta3, theta4, theta5, theta6]);
        }
    }

    /// The singular wrist (theta5 = 0 or pi): one member of the family of solutions.
    ///
    /// With the wrist straight, joints 4 and 6 turn about one axis and frame 4's origin lies on a
    /// circle of radius `d5` about the wrist centre, its place on the circle set by theta6. Prefer
    /// q6 = 0; when that member is out of the elbow's reach or the joint limits, take the
    /// members at the nearest reachable radius, then a sweep of theta6, first that fits wins.
    fn singular_wrist_branch(
        &self,
        theta1: f64,
        theta5: f64,
        planar_from_flange: &Frame,
        p5_planar: &Vector3<f64>,
        out: &mut Vec<JointVector>,
    ) {
        let preferred_theta6 = self.arm.theta_offsets_rad[5];
        let mut candidates = vec![preferred_theta6];
        candidates.extend(self.reach_edge_theta6(
            theta5,
            preferred_theta6,
            planar_from_flange,
            p5_planar,
        ));
        candidates.extend((-8..8).map(|k| preferred_theta6 + f64::from(k) * PI / 8.0));
        for theta6 in candidates {
            let before = out.len();
            let (s6, c6) = theta6.sin_cos();
            let (s5, c5) = theta5.sin_cos();
            self.planar_branch(
                theta1,
                (theta5, s5, c5, theta6, s6, c6),
                planar_from_flange,
                out,
            );
            if out[before..]
                .iter()
                .any(|theta| self.within_limits_modulo_turns(theta))
            {
                return;
            }
            out.truncate(before);
        }
    }

    /// Values of theta6 that put frame 4 at the elbow's nearest reachable radius.
    ///
    /// Frame 4 = wrist centre - d5 u(phi4) with u(phi) = (-sin phi, cos phi), where phi4 is frame
    /// 4's planar angle and phi4 + s theta6 is fixed by the flange (s = +1 at theta5 = 0, -1 at
    /// pi). Solves |c - d5 u(phi4)| = radius for phi4.
    fn reach_edge_theta6(
        &self,
        theta5: f64,
        theta6: f64,
        planar_from_flange: &Frame,
        p5_planar: &Vector3<f64>,
    ) -> Vec<f64> {
        let (a2, a3) = (self.arm.dh[2].a_m, self.arm.dh[3].a_m);
        let d5 = self.arm.dh[4].d_m;
        let (s5, c5) = theta5.sin_cos();
        let (s6, c6) = theta6.sin_cos();
        let p4 = self.dh4_in_planar(s5, c5, s6, c6, planar_from_flange).p;
        let radius = p4.x.hypot(p4.y);
        let (min_reach, max_reach) = ((a2 - a3).abs(), a2 + a3);
        let c = nalgebra::Vector2::new(p5_planar.x, p5_planar.y);
        let c_norm = c.norm();
        if (min_reach..=max_reach).contains(&radius) || d5 == 0.0 || c_norm == 0.0 {
            return Vec::new();
        }
        let target = radius.clamp(min_reach, max_reach);
        let cos_gap = (c_norm * c_norm + d5 * d5 - target * target) / (2.0 * d5 * c_norm);
        if cos_gap.abs() > 1.0 + REACH_TOLERANCE {
            return Vec::new();
        }
        let gap = cos_gap.clamp(-1.0, 1.0).acos();
        // c . u(phi) = |c| cos(phi + pi/2 - angle(c)).
        let base = c.y.atan2(c.x) - std::f64::consts::FRAC_PI_2;
        let offset = c - nalgebra::Vector2::new(p4.x, p4.y);
        let current_phi4 = (-offset.x).atan2(offset.y);
        let sign = if theta5 == 0.0 { 1.0 } else { -1.0 };
        [base + gap, base - gap]
            .into_iter()
            .map(|phi4| theta6 - sign * wrap_angle(phi4 - current_phi4))
            .collect()
    }

    /// Whether DH angles `theta` give controller angles within limits, up to whole turns.
    fn within_limits_modulo_turns(&self, theta: &JointVector) -> bool {
        let q = self.arm.q_from_theta(theta);
        q.iter().zip(&self.arm.limits).all(|(&qi, limit)| {
            let wrapped = wrap_angle(qi);
            [wrapped, wrapped - TAU, wrapped + TAU]
                .iter()
                .any(|&v| limit.contains(v))
        })
    }
}

impl IkSolver for AnalyticIk {
    fn solve(&self, tcp_in_base: &Isometry3<f64>) -> IkSolutions {
        let mut result = IkSolutions {
            solutions: Vec::with_capacity(8),
        };
        let translation = tcp_in_base.translation.vector;
        let rotation = tcp_in_base.rotation.coords;
        if !translation
            .iter()
            .chain(rotation.iter())
            .all(|v| v.is_finite())
        {
            return result;
        }
        let flange_in_dh0 = self.dh0_from_base * tcp_in_base * self.tcp_from_flange;
        let mut raw = Vec::with_capacity(8);
        self.solve_dh(&flange_in_dh0, &mut raw);
        for theta in &raw {
            let q = self.arm.q_from_theta(theta).map(wrap_angle);
            push_limited_variants(&self.arm, &q, &mut result);
        }
        result
    }
}

/// Wraps an angle into (-pi, pi].
fn wrap_angle(angle_rad: f64) -> f64 {
    // The solver's angles lie within a few turns of zero: subtracting beats `rem_euclid`.
    if angle_rad.abs() <= PI {
        return angle_rad;
    }
    let wrapped = angle_rad.rem_euclid(TAU);
    if wrapped > PI { wrapped - TAU } else { wrapped }
}

/// Pushes every 2pi-equivalent variant of `q` that lies within the joint limits.
fn push_limited_variants(arm: &ArmModel, q: &JointVector, out: &mut IkSolutions) {
    // Common case: limits narrower than a turn leave one candidate per joint.
    if q.iter().zip(&arm.limits).all(|(&v, limit)| {
        limit.contains(v) && !limit.contains(v - TAU) && !limit.contains(v + TAU)
    }) {
        out.push_distinct(*q);
        return;
    }
    let mut choices: [[f64; 3]; DOF] = [[0.0; 3]; DOF];
    let mut counts = [0usize; DOF];
    for joint in 0..DOF {
        for candidate in [q[joint], q[joint] - TAU, q[joint] + TAU] {
            if arm.limits[joint].contains(candidate) {
                choices[joint][counts[joint]] = candidate;
                counts[joint] += 1;
            }
        }
        if counts[joint] == 0 {
            return;
        }
    }
    let mut index = [0usize; DOF];
    loop {
        out.push_distinct(std::array::from_fn(|j| choices[j][index[j]]));
        // Odometer over the per-joint choices, last joint fastest.
        let mut joint = DOF;
        loop {
            if joint == 0 {
                return;
            }
            joint -= 1;
            index[joint] += 1;
            if index[joint] < counts[joint] {
                break;
            }
            index[joint] = 0;
        }
    }
}
