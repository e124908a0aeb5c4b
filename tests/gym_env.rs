//! The step-by-step environment (`twincell::gym`): trials reset as `twincell run` seeds them,
//! steps are deterministic, bad actions are refused naming their key, and the judge records a
//! trial's end.

use std::path::Path;

use twincell::cell::CellModel;
use twincell::gym::{Action, ActionError, ArmTarget, CellEnv, EnvError, Observation};
use twincell::outcome::{FailureReason, Outcome, Perception};
use twincell::scenario::Scenario;

fn paper_env(perception: Perception) -> CellEnv {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper_50.toml");
    let Ok(scenario) = Scenario::load(&path) else {
        panic!("paper_50.toml does not load");
    };
    let Ok(model) = CellModel::new(scenario, &path) else {
        panic!("paper_50's cell model");
    };
    match CellEnv::new(model, perception) {
        Ok(env) => env,
        Err(e) => panic!("environment: {e}"),
    }
}

fn bits(obs: &Observation) -> Vec<u64> {
    let mut out: Vec<u64> = obs
        .joint_positions_rad
        .iter()
        .chain(&obs.joint_velocities_rad_s)
        .chain(&obs.jaw_force_n)
        .map(|v| v.to_bits())
        .collect();
    for v in [
        obs.jaw_width_m,
        obs.belt_position_m,
        obs.belt_speed_m_s,
        obs.sim_time_s,
    ] {
        out.push(v.to_bits());
    }
    out.push(u64::from(obs.photo_eye));
    out
}

/// Runs the belt until the photo-eye sees the part, then sweeps joint 1 a little; the
/// observations' bits.
fn rollout(env: &mut CellEnv, trial: u32, steps: usize) -> Vec<Vec<u64>> {
    let Ok(first) = env.reset(trial, None) else {
        panic!("reset");
    };
    let home = first.joint_positions_rad;
    let mut seen = vec![bits(&first)];
    let mut eye = false;
    for k in 0..steps {
        let mut q = home;
        q[0] += 0.2 * (k as f64 * 0.1).sin();
        let action = Action {
            belt_run: !eye,
            ..Action::hold(q, 0.09, 60.0)
        };
        let Ok(result) = env.step(&action) else {
            panic!("step {k}");
        };
        eye |= result.observation.photo_eye;
        seen.push(bits(&result.observation));
    }
    seen
}

#[test]
fn a_trial_steps_the_same_every_time() {
    let mut a = paper_env(Perception::Oracle);
    let mut b = paper_env(Perception::Oracle);
    let first = rollout(&mut a, 3, 60);
    assert_eq!(first, rollout(&mut b, 3, 60));
    // Reset again on the same environment: the same trial from the start.
    assert_eq!(first, rollout(&mut a, 3, 60));
    // Another trial is another draw.
    assert_ne!(first, rollout(&mut a, 4, 60));
}

#[test]
fn the_belt_brings_the_part_to_the_photo_eye_and_the_judge_sees_it_unsorted() {
    let mut env = paper_env(Perception::Oracle);
    let Ok(first) = env.reset(0, None) else {
        panic!("reset");
    };
    assert!(!first.photo_eye);
    let Some(truth) = first.truth else {
        panic!("oracle mode shows the truth");
    };
    let home = first.joint_positions_rad;
    let period_s = env.control_period_s();
    assert!((period_s - 8.0 / 240.0).abs() < 1e-12);
    let mut arrived = None;
    for k in 0..400 {
        let action = Action {
            belt_run: true,
            ..Action::hold(home, 0.09, 60.0)
        };
        let Ok(result) = env.step(&action) else {
            panic!("step {k}");
        };
        assert!(result.record.is_none());
        let obs = result.observation;
        assert!((obs.sim_time_s - (k + 1) as f64 * period_s).abs() < 1e-9);
        if obs.photo_eye {
            arrived = Some(obs);
            break;
        }
    }
    let Some(obs) = arrived else {
        panic!("the part never reached the photo-eye");
    };
    assert!(obs.belt_position_m > 0.0 && obs.belt_speed_m_s > 0.0);
    // The part or a bottle (whichever the belt brings first) truly stands at the photo-eye.
    let scenario = env.model().scenario().clone();
    let Some(now) = obs.truth else {
        panic!("truth");
    };
    let nearest_m = std::iter::once(&now.world_from_part)
        .chain(&now.world_from_bottles)
        .map(|pose| (pose.translation.x - scenario.conveyor.photo_eye_x_m).abs())
        .fold(f64::INFINITY, f64::min);
    assert!(nearest_m < 0.05, "nothing within {nearest_m} m of the eye");
    assert_eq!(now.part_type, truth.part_type);
    // Giving up with the part on the belt: judged, in no bin.
    let Some(record) = env.finish() else {
        panic!("an episode runs");
    };
    assert_eq!(record.outcome, Outcome::Failure);
    assert_eq!(record.failure, Some(FailureReason::WrongBin));
    assert_eq!(record.placed_bin, None);
    let Some(part) = &record.part else {
        panic!("the truth about the part");
    };
    assert_eq!(part.part_type, scenario.part_types[truth.part_type].name);
    // Over is over.
    assert!(matches!(
        env.step(&Action::hold(home, 0.09, 60.0)),
        Err(EnvError::EpisodeOver(0))
    ));
}

#[test]
fn bad_actions_are_refused_naming_the_key() {
    let mut env = paper_env(Perception::Oracle);
    let home = env.model().scenario().robot.home_q_rad;
    assert!(matches!(
        env.step(&Action::hold(home, 0.05, 50.0)),
        Err(EnvError::NoEpisode)
    ));
    let Ok(_) = env.reset(1, None) else {
        panic!("reset");
    };
    let mut nan = home;
    nan[2] = f64::NAN;
    let Err(EnvError::Action(e)) = env.step(&Action::hold(nan, 0.05, 50.0)) else {
        panic!("a NaN target passed");
    };
    assert!(matches!(
        e,
        ActionError::NotFinite {
            key: "joints",
            index: 2,
            ..
        }
    ));
    assert!(e.to_string().starts_with("joints: element 2 is NaN"), "{e}");
    let mut far = home;
    far[4] = 4.0;
    let Err(EnvError::Action(e)) = env.step(&Action::hold(far, 0.05, 50.0)) else {
        panic!("a target past the limits passed");
    };
    assert!(
        matches!(e, ActionError::JointOutOfLimit { joint: 5, .. }),
        "{e}"
    );
    for (width, force, key) in [(0.2, 50.0, "jaw_width"), (0.05, -1.0, "jaw_force")] {
        let Err(EnvError::Action(e)) = env.step(&Action::hold(home, width, force)) else {
            panic!("{key} out of range passed");
        };
        assert!(e.to_string().starts_with(key), "{e}");
    }
    // A refused action leaves the trial as it was: the next good one runs from time 0.
    let Ok(result) = env.step(&Action::hold(home, 0.05, 50.0)) else {
        panic!("a good action");
    };
    assert!((result.observation.sim_time_s - env.control_period_s()).abs() < 1e-9);
}

#[test]
fn a_tool_pose_goes_through_the_ik_and_an_unreachable_one_holds() {
    let mut env = paper_env(Perception::Oracle);
    let Ok(first) = env.reset(2, None) else {
        panic!("reset");
    };
    let Some(truth) = first.truth else {
        panic!("truth");
    };
    // 0.25 m above the part, the tool turned as it is at home.
    let Some(world_from_base) = env.world_from_base() else {
        panic!("base");
    };
    let home_tcp = world_from_base
        * twincell::kinematics::tcp_pose(env.model().arm_model(), &first.joint_positions_rad);
    let mut above = home_tcp;
    above.translation.vector = truth.world_from_part.translation.vector;
    above.translation.z += 0.25;
    let mut last = None;
    for _ in 0..90 {
        let action = Action {
            arm: ArmTarget::ToolPose(above),
            ..Action::hold(first.joint_positions_rad, 0.09, 60.0)
        };
        let Ok(result) = env.step(&action) else {
            panic!("step");
        };
        assert!(!result.ik_unreachable);
        last = Some(result.observation);
    }
    let Some(last) = last else {
        panic!("no step");
    };
    // The arm reached it: the measured joints' forward kinematics put the TCP there.
    let model = env.model();
    let tcp = twincell::kinematics::tcp_pose(model.arm_model(), &last.joint_positions_rad);
    let error_m = ((world_from_base * tcp).translation.vector - above.translation.vector).norm();
    assert!(error_m < 0.005, "TCP {error_m} m from the target");
    let mut far = above;
    far.translation.z += 5.0;
    let action = Action {
        arm: ArmTarget::ToolPose(far),
        ..Action::hold(last.joint_positions_rad, 0.09, 60.0)
    };
    let Ok(result) = env.step(&action) else {
        panic!("step");
    };
    assert!(result.ik_unreachable);
}
