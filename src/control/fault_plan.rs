//! Which of a scenario's faults fire in one trial, and when: drawn from the trial's seed, one
//! derived stream per fault kind, so a scenario without faults draws nothing and a fault kind
//! added to a scenario leaves the other kinds' draws (and the cell's own) where they were.

use crate::outcome::{FaultKind, Phase};
use crate::rng::SimRng;
use crate::scenario::{BeltFaultMode, BlackoutMode, FaultsSection, Scenario};

/// Salt of the fault streams, mixed into the trial's seed.
const FAULT_SALT: u64 = 0x4641_554C_5453;

/// The arm motions a stop may interrupt, in the order a pick cycle plays them.
pub const ARM_MOTIONS: [Phase; 6] = [
    Phase::Approach,
    Phase::Descend,
    Phase::Lift,
    Phase::Transport,
    Phase::Place,
    Phase::Retreat,
];

/// How far along the interrupted motion an arm stop may come, as shares of its duration: not
/// at its very ends, where a stop is a stop between motions.
const ARM_STOP_SPAN: [f64; 2] = [0.1, 0.9];

/// The gripper weakens on one grasp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripFault {
    /// The grasp it strikes, counting the trial's grasps from 0.
    pub grasp: u32,
    /// Time from the jaws being commanded closed to the force falling, s.
    pub delay_s: f64,
    /// The share of the commanded force the jaws keep.
    pub force_fraction: f64,
}

/// What the camera delivers while blacked out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlackoutFrames {
    /// No frame at all.
    None,
    /// Frames, all black.
    Black,
}

/// The camera blacks out once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraBlackout {
    /// The look it begins at, counting the trial's looks at the pick station from 0.
    pub look: u32,
    /// How long it lasts from that look's first shot, s.
    pub duration_s: f64,
    /// What the camera delivers meanwhile.
    pub frames: BlackoutFrames,
}

/// The arm stops once mid-motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmStop {
    /// The pick cycle it strikes, counting the trial's cycles from 0.
    pub cycle: u32,
    /// The motion it interrupts.
    pub motion: Phase,
    /// How far along that motion it comes, as a share of the motion's duration.
    pub at_fraction: f64,
    /// How long the servos hold before they release, s.
    pub duration_s: f64,
}

/// The belt runs slow, or stalls, for a while.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeltFault {
    /// When it begins, trial time, s.
    pub onset_s: f64,
    /// How long it lasts, s.
    pub duration_s: f64,
    /// The share of the commanded speed the belt runs at meanwhile (0: a stall).
    pub speed_fraction: f64,
}

impl BeltFault {
    /// Whether the fault holds the belt at trial time `time_s`.
    pub fn active_at(&self, time_s: f64) -> bool {
        time_s >= self.onset_s && time_s < self.onset_s + self.duration_s
    }
}

/// The photo-eye's lies in one trial.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhotoEyeFaults {
    /// Trial time of a trigger with nothing in the beam, s.
    pub false_trigger_at_s: Option<f64>,
    /// The beam crossing that goes unreported, counting the trial's crossings from 0.
    pub missed_crossing: Option<u32>,
}

/// Which faults fire in one trial and when; the empty plan injects nothing.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FaultPlan {
    /// A gripper that weakens.
    pub gripper: Option<GripFault>,
    /// A camera blackout.
    pub camera: Option<CameraBlackout>,
    /// An arm stop.
    pub arm: Option<ArmStop>,
    /// A slow or stalled belt.
    pub belt: Option<BeltFault>,
    /// A false or a missed trigger of the photo-eye.
    pub photo_eye: PhotoEyeFaults,
}

impl FaultPlan {
    /// The faults of the trial whose seed is `seed` in `scenario`. Each kind draws from its own
    /// stream derived from the seed; a scenario without `[faults]` draws nothing.
    pub fn draw(scenario: &Scenario, seed: u64) -> Self {
        let faults: &FaultsSection = &scenario.faults;
        if faults.is_empty() {
            return Self::default();
        }
        // Events that happen once per part (a grasp, a look, a cycle) are drawn among the
        // trial's parts; a look may also fall on a bottle of a stream.
        let parts = u64::from(scenario.parts_per_trial.max(1));
        let looks = if scenario.is_stream() {
            parts + u64::from(scenario.stream.bottles)
        } else {
            parts
        };
        let stream = |kind: u64| SimRng::derive(seed ^ FAULT_SALT, kind);
        let mut plan = Self::default();
        if let Some(section) = &faults.gripper {
            let mut rng = stream(0);
            if rng.uniform() < section.rate {
                let [least, most] = section.delay_range_s;
                plan.gripper = Some(GripFault {
                    grasp: rng.below(parts) as u32,
                    delay_s: rng.range(least, most),
                    force_fraction: section.force_fraction,
                });
            }
        }
        if let Some(section) = &faults.camera {
            let mut rng = stream(1);
            if rng.uniform() < section.rate {
                plan.camera = Some(CameraBlackout {
                    look: rng.below(looks) as u32,
                    duration_s: section.duration_s,
                    frames: match section.mode {
                        BlackoutMode::BlackFrame => BlackoutFrames::Black,
                        BlackoutMode::NoFrame | BlackoutMode::Unknown(_) => BlackoutFrames::None,
                    },
                });
            }
        }
        if let Some(section) = &faults.arm {
            let mut rng = stream(2);
            if rng.uniform() < section.rate {
                plan.arm = Some(ArmStop {
                    cycle: rng.below(parts) as u32,
                    motion: ARM_MOTIONS[rng.below(ARM_MOTIONS.len() as u64) as usize],
                    at_fraction: rng.range(ARM_STOP_SPAN[0], ARM_STOP_SPAN[1]),
                    duration_s: section.duration_s,
                });
            }
        }
        if let Some(section) = &faults.belt {
            let mut rng = stream(3);
            if rng.uniform() < section.rate {
                let [least, most] = section.onset_range_s;
                plan.belt = Some(BeltFault {
                    onset_s: rng.range(least, most),
                    duration_s: section.duration_s,
                    speed_fraction: match section.mode {
                        BeltFaultMode::Slow => section.speed_fraction,
                        BeltFaultMode::Stall | BeltFaultMode::Unknown(_) => 0.0,
                    },
                });
            }
        }
        if let Some(section) = &faults.photo_eye {
            let mut rng = stream(4);
            if rng.uniform() < section.false_trigger_rate {
                // Before the first item reaches the beam, so that the trigger is surely false.
                let belt = &scenario.conveyor;
                let first_arrival_s = belt.spawn_upstream_m / belt.speed_m_s;
                plan.photo_eye.false_trigger_at_s = Some(rng.range(0.0, first_arrival_s));
            }
            let mut rng = stream(5);
            if rng.uniform() < section.missed_trigger_rate {
                plan.photo_eye.missed_crossing = Some(rng.below(looks) as u32);
            }
        }
        plan
    }

    /// The grip fault that strikes grasp `grasp` (counting the trial's grasps from 0), if any.
    pub fn grip_fault_at(&self, grasp: u32) -> Option<GripFault> {
        self.gripper.filter(|f| f.grasp == grasp)
    }

    /// The blackout that begins at look `look` (counting the trial's looks from 0), if any.
    pub fn blackout_at(&self, look: u32) -> Option<CameraBlackout> {
        self.camera.filter(|f| f.look == look)
    }

    /// The arm stop that strikes `motion` of pick cycle `cycle`, if any.
    pub fn arm_stop_in(&self, cycle: u32, motion: Phase) -> Option<ArmStop> {
        self.arm.filter(|f| f.cycle == cycle && f.motion == motion)
    }

    /// Whether the photo-eye has a lie planned.
    pub fn photo_eye_lies(&self) -> bool {
        self.photo_eye != PhotoEyeFaults::default()
    }

    /// Whether the plan injects no fault.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }

    /// The kinds of fault the plan injects.
    pub fn kinds(&self) -> Vec<FaultKind> {
        let eye =
            self.photo_eye.false_trigger_at_s.is_some() || self.photo_eye.missed_crossing.is_some();
        [
            (FaultKind::Gripper, self.gripper.is_some()),
            (FaultKind::Camera, self.camera.is_some()),
            (FaultKind::Arm, self.arm.is_some()),
            (FaultKind::Belt, self.belt.is_some()),
            (FaultKind::PhotoEye, eye),
        ]
        .into_iter()
        .filter_map(|(kind, fires)| fires.then_some(kind))
        .collect()
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::scenario::{
        ArmFaultSection, BeltFaultSection, CameraFaultSection, GripperFaultSection,
        PhotoEyeFaultSection,
    };

    fn paper() -> Scenario {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper_50.toml");
        Scenario::load(&path).expect("paper_50 loads")
    }

    fn with_all_faults(rate: f64) -> Scenario {
        let mut scenario = paper();
        scenario.faults = FaultsSection {
            gripper: Some(GripperFaultSection {
                rate,
                delay_range_s: [0.3, 0.9],
                force_fraction: 0.1,
            }),
            camera: Some(CameraFaultSection {
                rate,
                duration_s: 1.5,
                mode: BlackoutMode::BlackFrame,
            }),
            arm: Some(ArmFaultSection {
                rate,
                duration_s: 0.7,
            }),
            belt: Some(BeltFaultSection {
                rate,
                mode: BeltFaultMode::Stall,
                speed_fraction: 0.5,
                onset_range_s: [0.2, 0.6],
                duration_s: 2.0,
            }),
            photo_eye: Some(PhotoEyeFaultSection {
                false_trigger_rate: rate,
                missed_trigger_rate: rate,
            }),
            unknown: Default::default(),
        };
        scenario
    }

    #[test]
    fn a_scenario_without_faults_plans_none() {
        let scenario = paper();
        for seed in 0..200 {
            assert!(FaultPlan::draw(&scenario, seed).is_empty());
        }
    }

    #[test]
    fn the_plan_repeats_for_a_seed_and_each_fault_fires_at_its_rate() {
        let scenario = with_all_faults(0.2);
        let n = 4000;
        let mut fired = [0usize; 6];
        for seed in 0..n {
            let plan = FaultPlan::draw(&scenario, seed * 7919 + 13);
            assert_eq!(plan, FaultPlan::draw(&scenario, seed * 7919 + 13));
            let eye = plan.photo_eye;
            let flags = [
                plan.gripper.is_some(),
                plan.camera.is_some(),
                plan.arm.is_some(),
                plan.belt.is_some(),
                eye.false_trigger_at_s.is_some(),
                eye.missed_crossing.is_some(),
            ];
            for (count, flag) in fired.iter_mut().zip(flags) {
                *count += usize::from(flag);
            }
        }
        // Binomial(4000, 0.2): sd 25, so 5 sd is 125 either side of 800.
        for (kind, count) in fired.iter().enumerate() {
            assert!((675..=925).contains(count), "kind {kind}: {count} of {n}");
        }
    }

    #[test]
    fn drawn_times_stay_in_their_ranges_and_follow_the_section() {
        let scenario = with_all_faults(1.0);
        let first_arrival_s = scenario.conveyor.spawn_upstream_m / scenario.conveyor.speed_m_s;
        let mut motions = std::collections::BTreeSet::new();
        for seed in 0..500 {
            let plan = FaultPlan::draw(&scenario, seed);
            assert_eq!(plan.kinds(), FaultKind::ALL);
            let grip = plan.gripper.expect("rate 1");
            assert!((0.3..0.9).contains(&grip.delay_s), "{grip:?}");
            assert_eq!((grip.grasp, grip.force_fraction), (0, 0.1));
            let camera = plan.camera.expect("rate 1");
            assert_eq!(camera.frames, BlackoutFrames::Black);
            assert_eq!((camera.look, camera.duration_s), (0, 1.5));
            let arm = plan.arm.expect("rate 1");
            assert!((0.1..0.9).contains(&arm.at_fraction), "{arm:?}");
            assert_eq!((arm.cycle, arm.duration_s), (0, 0.7));
            motions.insert(arm.motion);
            let belt = plan.belt.expect("rate 1");
            assert!((0.2..0.6).contains(&belt.onset_s), "{belt:?}");
            assert_eq!(belt.speed_fraction, 0.0, "a stall runs at none");
            let at = plan.photo_eye.false_trigger_at_s.expect("rate 1");
            assert!((0.0..first_arrival_s).contains(&at), "{at}");
            assert_eq!(plan.photo_eye.missed_crossing, Some(0));
        }
        assert_eq!(
            motions.len(),
            ARM_MOTIONS.len(),
            "every motion may be struck"
        );
        // Each fault is found at its own event and no other.
        let plan = FaultPlan::draw(&scenario, 3);
        assert_eq!(plan.grip_fault_at(0), plan.gripper);
        assert_eq!(plan.grip_fault_at(1), None);
        assert_eq!(plan.blackout_at(0), plan.camera);
        assert_eq!(plan.blackout_at(1), None);
        let stop = plan.arm.expect("rate 1");
        assert_eq!(plan.arm_stop_in(0, stop.motion), Some(stop));
        assert_eq!(plan.arm_stop_in(1, stop.motion), None);
        let other = ARM_MOTIONS.iter().find(|&&m| m != stop.motion).copied();
        assert_eq!(other.and_then(|m| plan.arm_stop_in(0, m)), None);
        assert!(plan.photo_eye_lies() && !FaultPlan::default().photo_eye_lies());
    }

    #[test]
    fn a_stream_spreads_its_faults_over_its_parts_and_kinds_draw_independently() {
        let mut stream = with_all_faults(1.0);
        stream.parts_per_trial = 4;
        stream.stream.bottles = 2;
        let mut grasps = std::collections::BTreeSet::new();
        let mut looks = std::collections::BTreeSet::new();
        for seed in 0..300 {
            let plan = FaultPlan::draw(&stream, seed);
            grasps.insert(plan.gripper.expect("rate 1").grasp);
            looks.insert(plan.camera.expect("rate 1").look);
        }
        assert_eq!(grasps.into_iter().collect::<Vec<_>>(), [0, 1, 2, 3]);
        assert_eq!(looks.into_iter().collect::<Vec<_>>(), [0, 1, 2, 3, 4, 5]);
        // Dropping one kind leaves every other kind's draw as it was.
        let mut fewer = stream.clone();
        fewer.faults.camera = None;
        for seed in 0..100 {
            let (all, less) = (
                FaultPlan::draw(&stream, seed),
                FaultPlan::draw(&fewer, seed),
            );
            assert_eq!(less.camera, None);
            assert_eq!(
                (less.gripper, less.arm, less.belt),
                (all.gripper, all.arm, all.belt)
            );
            assert_eq!(less.photo_eye, all.photo_eye);
        }
    }

    #[test]
    fn a_belt_fault_holds_for_its_window_only() {
        let fault = BeltFault {
            onset_s: 0.5,
            duration_s: 1.0,
            speed_fraction: 0.4,
        };
        assert!(!fault.active_at(0.49));
        assert!(fault.active_at(0.5) && fault.active_at(1.49));
        assert!(!fault.active_at(1.5));
    }
}
