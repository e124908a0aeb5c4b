use super::*;
use crate::rng::SimRng;

/// Random joint vectors within the arm's position limits.
fn random_q(rng: &mut SimRng, arm: &ArmModel) -> JointVector {
    std::array::from_fn(|j| rng.range(arm.limits[j].min_rad, arm.limits[j].max_rad))
}

/// Samples `trajectory` finely; checks every joint's velocity and acceleration against the
/// limits scaled by `fraction`, and that velocity is continuous (it changes by no more than the
/// acceleration limit allows between samples). Returns the largest velocity and acceleration
/// as shares of their limits.
fn check_limits(arm: &ArmModel, trajectory: &JointTrajectory, fraction: f64) -> (f64, f64) {
    let duration = trajectory.duration_s();
    let n = 20_000;
    let dt = duration / f64::from(n);
    let (mut v_share, mut a_share) = (0.0f64, 0.0f64);
    let mut previous = trajectory.sample(0.0).expect("non-empty");
    assert_eq!(previous.qd, [0.0; DOF]);
    for i in 1..=n {
        let now = trajectory.sample(dt * f64::from(i)).expect("non-empty");
        for (j, limit) in arm.limits.iter().enumerate() {
            let v_max = limit.max_velocity_rad_s * fraction;
            let a_max = limit.max_accel_rad_s2 * fraction;
            v_share = v_share.max(now.qd[j].abs() / v_max);
            a_share = a_share.max(now.qdd[j].abs() / a_max);
            assert!(now.qd[j].abs() <= v_max * (1.0 + 1e-9), "joint {j} {now:?}");
            assert!(
                now.qdd[j].abs() <= a_max * (1.0 + 1e-9),
                "joint {j} {now:?}"
            );
            let jump = (now.qd[j] - previous.qd[j]).abs();
            assert!(
                jump <= a_max * dt * (1.0 + 1e-6) + 1e-12,
                "joint {j} jumps {jump}"
            );
            // Position follows the velocity (trapezoidal integration, exact up to the jerk).
            let mean = 0.5 * (now.qd[j] + previous.qd[j]);
            let moved = now.q[j] - previous.q[j];
            assert!(
                (moved - mean * dt).abs() <= a_max * dt * dt + 1e-12,
                "joint {j}"
            );
        }
        previous = now;
    }
    (v_share, a_share)
}

#[test]
fn random_waypoints_stop_at_each_within_the_limits() {
    let arm = ArmModel::aubo_i5();
    let mut rng = SimRng::new(11);
    for _ in 0..20 {
        let count = 2 + (rng.next_u64() % 3) as usize;
        let waypoints: Vec<JointVector> = (0..count).map(|_| random_q(&mut rng, &arm)).collect();
        let fraction = rng.range(0.2, 1.0);
        let trajectory = JointTrajectory::through(&arm, &waypoints, fraction);
        let (v, a) = check_limits(&arm, &trajectory, fraction);
        // Time-optimal: the binding joint reaches a limit.
        assert!(v > 0.999 || a > 0.999, "{v} {a}");
        // At rest exactly at every waypoint.
        for (k, start) in trajectory.part_starts_s().iter().enumerate() {
            let at = trajectory.sample(*start).expect("non-empty");
            assert_eq!(at.q, waypoints[k]);
            assert_eq!(at.qd, [0.0; DOF]);
        }
        let end = trajectory
            .sample(trajectory.duration_s())
            .expect("non-empty");
        assert_eq!(end.q, waypoints[count - 1]);
        assert_eq!(end.qd, [0.0; DOF]);
        let after = trajectory
            .sample(trajectory.duration_s() + 1.0)
            .expect("non-empty");
        assert_eq!(after.q, waypoints[count - 1]);
    }
}

#[test]
fn random_blends_are_continuous_within_the_limits_and_faster() {
    let arm = ArmModel::aubo_i5();
    let mut rng = SimRng::new(12);
    for _ in 0..20 {
        let count = 3 + (rng.next_u64() % 3) as usize;
        let waypoints: Vec<JointVector> = (0..count).map(|_| random_q(&mut rng, &arm)).collect();
        let parts = || {
            waypoints
                .windows(2)
                .map(|pair| JointTrajectory::along(&arm, vec![pair[0], pair[1]], 1.0))
                .collect::<Vec<_>>()
        };
        let stopping = JointTrajectory::join(parts(), false);
        let blended = JointTrajectory::join(parts(), true);
        check_limits(&arm, &blended, 1.0);
        let start = blended.sample(0.0).expect("non-empty");
        assert_eq!(start.q, waypoints[0]);
        let end = blended.sample(blended.duration_s()).expect("non-empty");
        assert_eq!(end.q, waypoints[count - 1]);
        assert_eq!(end.qd, [0.0; DOF]);
        // The arm does not stop at a junction.
        for start in &blended.part_starts_s()[1..] {
            let at = blended.sample(*start + 1e-6).expect("non-empty");
            assert!(at.qd.iter().any(|v| v.abs() > 1e-3), "stopped at {start}");
        }
        assert!(blended.duration_s() < stopping.duration_s());
    }
}

#[test]
fn a_dense_straight_path_keeps_its_samples_and_limits() {
    let arm = ArmModel::aubo_i5();
    let mut rng = SimRng::new(13);
    for _ in 0..10 {
        let (a, b) = (random_q(&mut rng, &arm), random_q(&mut rng, &arm));
        let n = 40;
        let path: Vec<JointVector> = (0..=n)
            .map(|i| std::array::from_fn(|j| a[j] + (b[j] - a[j]) * f64::from(i) / f64::from(n)))
            .collect();
        let trajectory = JointTrajectory::along(&arm, path.clone(), 1.0);
        check_limits(&arm, &trajectory, 1.0);
        let end = trajectory
            .sample(trajectory.duration_s())
            .expect("non-empty");
        assert_eq!(Some(end.q), path.last().copied());
        // The sample path lies on the polyline: each sample is between its neighbours.
        for i in 0..=50 {
            let t = trajectory.duration_s() * f64::from(i) / 50.0;
            let q = trajectory.sample(t).expect("non-empty").q;
            let u = (q[0] - a[0]) / (b[0] - a[0]);
            for j in 1..DOF {
                assert!((q[j] - (a[j] + (b[j] - a[j]) * u)).abs() < 1e-9);
            }
        }
    }
}

#[test]
fn tool_limits_slow_the_whole_path_down() {
    let arm = ArmModel::aubo_i5().with_tool(nalgebra::Isometry3::translation(0.0, 0.0, 0.125));
    let mut rng = SimRng::new(14);
    for _ in 0..10 {
        let (a, b) = (random_q(&mut rng, &arm), random_q(&mut rng, &arm));
        let fast = JointTrajectory::through(&arm, &[a, b], 1.0);
        let limits = ToolLimits {
            speed_m_s: 0.5,
            accel_m_s2: 3.0,
        };
        let slow = fast.clone().within_tool_limits(&arm, &limits);
        let (speed, accel) = slow.peak_tool_motion(&arm);
        assert!(speed <= limits.speed_m_s * 1.01, "{speed}");
        assert!(accel <= limits.accel_m_s2 * 1.01, "{accel}");
        assert!(slow.duration_s() >= fast.duration_s());
        assert_eq!(slow.end(), Some(b));
        // A speed cap alone lowers the cruise rate and keeps the ramps: within the limits, at
        // least as fast as the uniform slow-down, and still within the joints' own limits.
        let speed_only = ToolLimits {
            speed_m_s: 0.5,
            accel_m_s2: 1e3,
        };
        let capped = fast.clone().with_tool_limits(&arm, &speed_only);
        let (speed, _) = capped.peak_tool_motion(&arm);
        assert!(speed <= speed_only.speed_m_s * 1.01, "{speed}");
        let uniform = fast.clone().within_tool_limits(&arm, &speed_only);
        assert!(capped.duration_s() <= uniform.duration_s() + 1e-9);
        assert_eq!(capped.end(), Some(b));
        check_limits(&arm, &capped, 1.0);
    }
}

#[test]
fn a_tool_speed_cap_along_the_path_keeps_every_limit_and_is_never_slower_than_at_the_peak() {
    let arm = ArmModel::aubo_i5().with_tool(nalgebra::Isometry3::translation(0.0, 0.0, 0.125));
    let mut rng = SimRng::new(26);
    let mut quicker = 0;
    for _ in 0..30 {
        let (a, b) = (random_q(&mut rng, &arm), random_q(&mut rng, &arm));
        let fraction = rng.range(0.3, 1.0);
        let limits = ToolLimits {
            speed_m_s: rng.range(0.3, 1.5),
            accel_m_s2: rng.range(5.0, 100.0),
        };
        let along = JointTrajectory::along_tool_speed(&arm, vec![a, b], fraction, &limits);
        let (speed, accel) = along.peak_tool_motion(&arm);
        assert!(speed <= limits.speed_m_s * 1.01, "{speed} over {limits:?}");
        assert!(accel <= limits.accel_m_s2 * 1.01, "{accel} over {limits:?}");
        assert_eq!((along.start(), along.end()), (Some(a), Some(b)));
        check_limits(&arm, &along, fraction);
        // The joint path is the straight one from a to b.
        for k in 0..=50 {
            let q = along
                .sample(along.duration_s() * f64::from(k) / 50.0)
                .expect("samples")
                .q;
            let j = (0..DOF)
                .max_by(|&i, &k| (b[i] - a[i]).abs().total_cmp(&(b[k] - a[k]).abs()))
                .expect("joints");
            let u = (q[j] - a[j]) / (b[j] - a[j]);
            for i in 0..DOF {
                assert!((q[i] - (a[i] + (b[i] - a[i]) * u)).abs() < 1e-9);
            }
        }
        let peak =
            JointTrajectory::through(&arm, &[a, b], fraction).with_tool_limits(&arm, &limits);
        assert!(
            along.duration_s() <= peak.duration_s() * 1.02,
            "slower than the peak's cap"
        );
        if along.duration_s() < 0.95 * peak.duration_s() {
            quicker += 1;
        }
        // Blended behind a move, it keeps the blend's continuity and the limits.
        let c = random_q(&mut rng, &arm);
        let lead = JointTrajectory::through(&arm, &[c, a], fraction);
        let joined = JointTrajectory::join(vec![lead, along], true);
        check_limits(&arm, &joined, fraction);
        assert_eq!(joined.end(), Some(b));
    }
    assert!(
        quicker > 5,
        "only {quicker} of 30 moves quicker than capped at their peak"
    );
}
