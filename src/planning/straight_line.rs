//! Straight tool-space lines turned into dense joint-space paths through the IK solver.

use nalgebra::Isometry3;

use crate::kinematics::{IkSolver, JointVector};

/// Largest joint change between neighbouring samples before the path counts as jumping
/// branches (a singularity or a limit in the way), rad.
const MAX_STEP_RAD: f64 = 0.15;

/// Joint configurations along the straight line (and slerped rotation) from `from` to `to`,
/// starting at `q_start` (a solution for `from`) and continuing each sample from the last.
/// `None` when a sample has no solution or the path would jump between IK branches.
pub fn straight_line(
    ik: &dyn IkSolver,
    from: &Isometry3<f64>,
    to: &Isometry3<f64>,
    q_start: &JointVector,
    step_m: f64,
) -> Option<Vec<JointVector>> {
    let length = (to.translation.vector - from.translation.vector).norm();
    let angle = from.rotation.angle_to(&to.rotation);
    // Rotations count as 0.1 m per radian when choosing the sample count.
    let samples = ((length.max(0.1 * angle)) / step_m.max(1e-4))
        .ceil()
        .max(1.0) as usize;
    let mut path = Vec::with_capacity(samples + 1);
    path.push(*q_start);
    let mut previous = *q_start;
    for i in 1..=samples {
        let t = i as f64 / samples as f64;
        let pose = from.lerp_slerp(to, t);
        let q = ik.solve(&pose).nearest(&previous)?;
        let jump = q
            .iter()
            .zip(&previous)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if jump > MAX_STEP_RAD {
            return None;
        }
        path.push(q);
        previous = q;
    }
    Some(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{AnalyticIk, ArmModel, tcp_pose};

    #[test]
    fn line_samples_stay_on_the_line() {
        let arm = ArmModel::aubo_i5().with_tool(Isometry3::translation(0.0, 0.0, 0.125));
        let ik = AnalyticIk::new(arm.clone()).expect("AUBO geometry");
        let q0 = [-1.15, 0.46, 1.67, -0.36, 1.57, 0.42];
        let from = tcp_pose(&arm, &q0);
        let to = Isometry3::translation(0.0, 0.0, -0.2) * from;
        let path = straight_line(&ik, &from, &to, &q0, 0.005).expect("reachable line");
        assert!(path.len() > 40);
        for q in &path {
            let p = tcp_pose(&arm, q).translation.vector;
            let off_line = ((p - from.translation.vector).xy()).norm();
            assert!(off_line < 1e-9, "{off_line}");
        }
    }
}
