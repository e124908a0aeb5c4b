//! The `[faults]` section: the faults a real cell meets (a weakening gripper, camera blackouts,
//! arm stops, a slow or stalled belt, a photo-eye that lies), each injected in a share of
//! trials that the trial's seed decides, so a faulty run repeats as exactly as any other.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::ScenarioError;
use super::validate::Checker;

/// The fault kinds a scenario may name under `[faults]`, in the order reports list them.
pub const FAULT_KINDS: [&str; 5] = ["gripper", "camera", "arm", "belt", "photo_eye"];

/// Longest fault duration or delay a scenario may ask for, s: far beyond any trial's time-out
/// that makes sense, and short of the values that only a typo gives.
pub const MAX_FAULT_DURATION_S: f64 = 3600.0;

/// Which faults a scenario injects; a kind left out is never injected and draws nothing.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FaultsSection {
    /// The gripper's force falls to a fraction some time after the jaws close on a part.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gripper: Option<GripperFaultSection>,
    /// The camera delivers nothing, or black frames, for a while.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraFaultSection>,
    /// The arm stops mid-motion for a while: its servos hold, then release.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arm: Option<ArmFaultSection>,
    /// The belt runs slower than commanded, or stalls; its encoder shows the truth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub belt: Option<BeltFaultSection>,
    /// The photo-eye reports an item that is not there, or misses one that is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub photo_eye: Option<PhotoEyeFaultSection>,
    /// Tables under `[faults]` that name no known kind: kept so that validation can name them
    /// (`faults.laser: unknown fault kind`) instead of the reader's bare "unknown field".
    #[serde(flatten, default, skip_serializing)]
    pub unknown: BTreeMap<String, toml::Value>,
}

impl FaultsSection {
    /// Whether no fault is injected at all: such a scenario draws nothing for faults.
    pub fn is_empty(&self) -> bool {
        self.gripper.is_none()
            && self.camera.is_none()
            && self.arm.is_none()
            && self.belt.is_none()
            && self.photo_eye.is_none()
            && self.unknown.is_empty()
    }

    /// Checks every fault's values; the first problem found is returned.
    pub(super) fn validate(&self, c: &Checker) -> Result<(), ScenarioError> {
        if let Some(name) = self.unknown.keys().next() {
            return Err(c.fail(
                format!("faults.{name}"),
                format!(
                    "unknown fault kind `{name}`; the kinds are {}",
                    FAULT_KINDS.join(", ")
                ),
            ));
        }
        if let Some(gripper) = &self.gripper {
            c.in_range("faults.gripper.rate", gripper.rate, 0.0, 1.0)?;
            range_s(c, "faults.gripper.delay_range_s", gripper.delay_range_s)?;
            below_one(
                c,
                "faults.gripper.force_fraction",
                gripper.force_fraction,
                0.0,
            )?;
        }
        if let Some(camera) = &self.camera {
            c.in_range("faults.camera.rate", camera.rate, 0.0, 1.0)?;
            duration_s(c, "faults.camera.duration_s", camera.duration_s)?;
            if let BlackoutMode::Unknown(name) = &camera.mode {
                return Err(unknown_mode(
                    c,
                    "faults.camera.mode",
                    name,
                    &BlackoutMode::NAMES,
                ));
            }
        }
        if let Some(arm) = &self.arm {
            c.in_range("faults.arm.rate", arm.rate, 0.0, 1.0)?;
            duration_s(c, "faults.arm.duration_s", arm.duration_s)?;
        }
        if let Some(belt) = &self.belt {
            c.in_range("faults.belt.rate", belt.rate, 0.0, 1.0)?;
            match &belt.mode {
                BeltFaultMode::Unknown(name) => {
                    return Err(unknown_mode(
                        c,
                        "faults.belt.mode",
                        name,
                        &BeltFaultMode::NAMES,
                    ));
                }
                BeltFaultMode::Slow => {
                    c.positive("faults.belt.speed_fraction", belt.speed_fraction)?;
                    below_one(c, "faults.belt.speed_fraction", belt.speed_fraction, 0.0)?;
                }
                BeltFaultMode::Stall => {}
            }
            range_s(c, "faults.belt.onset_range_s", belt.onset_range_s)?;
            duration_s(c, "faults.belt.duration_s", belt.duration_s)?;
        }
        if let Some(eye) = &self.photo_eye {
            c.in_range(
                "faults.photo_eye.false_trigger_rate",
                eye.false_trigger_rate,
                0.0,
                1.0,
            )?;
            c.in_range(
                "faults.photo_eye.missed_trigger_rate",
                eye.missed_trigger_rate,
                0.0,
                1.0,
            )?;
        }
        Ok(())
    }
}

/// A duration: positive, finite and at most [`MAX_FAULT_DURATION_S`].
fn duration_s(c: &Checker, key: &str, value: f64) -> Result<(), ScenarioError> {
    c.positive_up_to(key, value, MAX_FAULT_DURATION_S)
}

/// A share in `[low, 1)`: a fault that keeps the whole is no fault.
fn below_one(c: &Checker, key: &str, value: f64, low: f64) -> Result<(), ScenarioError> {
    c.in_range(key, value, low, 1.0)?;
    if value < 1.0 {
        Ok(())
    } else {
        Err(c.fail(key, format!("must lie in [{low}, 1), got {value}")))
    }
}

/// A range of times `[least, most]` with `0 <= least <= most <= MAX_FAULT_DURATION_S`.
fn range_s(c: &Checker, key: &str, [least, most]: [f64; 2]) -> Result<(), ScenarioError> {
    let ordered = least.is_finite()
        && most.is_finite()
        && 0.0 <= least
        && least <= most
        && most <= MAX_FAULT_DURATION_S;
    if ordered {
        Ok(())
    } else {
        Err(c.fail(
            key,
            format!(
                "must be [least, most] with 0 <= least <= most <= {MAX_FAULT_DURATION_S} s, \
                 got {least}, {most}"
            ),
        ))
    }
}

fn unknown_mode(c: &Checker, key: &str, name: &str, known: &[&str]) -> ScenarioError {
    c.fail(
        key,
        format!("unknown kind `{name}`; the kinds are {}", known.join(", ")),
    )
}

/// A gripper whose force falls after it has closed on a part (ARIAC's faulty gripper).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GripperFaultSection {
    /// Share of trials in which one grasp weakens, in [0, 1].
    pub rate: f64,
    /// Time from the jaws closing to the force falling, drawn uniformly in `[least, most]`, s.
    #[serde(default = "default_grip_delay_range_s")]
    pub delay_range_s: [f64; 2],
    /// The share of the commanded force the jaws keep once it has fallen, in [0, 1).
    #[serde(default = "default_force_fraction")]
    pub force_fraction: f64,
}

fn default_grip_delay_range_s() -> [f64; 2] {
    [0.2, 2.0]
}

fn default_force_fraction() -> f64 {
    0.05
}

/// How a camera blackout shows.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(from = "String", into = "String")]
pub enum BlackoutMode {
    /// The camera delivers no frame at all (a lost link).
    NoFrame,
    /// The camera delivers frames, all black (a shutter or a lamp that fails).
    BlackFrame,
    /// A name that is no mode; validation refuses it, naming the key.
    Unknown(String),
}

impl BlackoutMode {
    /// The modes a scenario may name.
    pub const NAMES: [&str; 2] = ["no_frame", "black_frame"];
}

impl From<String> for BlackoutMode {
    fn from(name: String) -> Self {
        match name.as_str() {
            "no_frame" => Self::NoFrame,
            "black_frame" => Self::BlackFrame,
            _ => Self::Unknown(name),
        }
    }
}

impl From<BlackoutMode> for String {
    fn from(mode: BlackoutMode) -> Self {
        match mode {
            BlackoutMode::NoFrame => "no_frame".into(),
            BlackoutMode::BlackFrame => "black_frame".into(),
            BlackoutMode::Unknown(name) => name,
        }
    }
}

/// Camera blackouts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFaultSection {
    /// Share of trials in which the camera blacks out once, in [0, 1].
    pub rate: f64,
    /// How long a blackout lasts, s.
    #[serde(default = "one_second")]
    pub duration_s: f64,
    /// What the camera delivers meanwhile: `"no_frame"` or `"black_frame"`.
    #[serde(default = "default_blackout_mode")]
    pub mode: BlackoutMode,
}

fn one_second() -> f64 {
    1.0
}

fn default_blackout_mode() -> BlackoutMode {
    BlackoutMode::NoFrame
}

/// Arm stops (a protective stop, a drive fault): the servos hold where the arm is, then
/// release and the motion goes on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmFaultSection {
    /// Share of trials in which the arm stops once mid-motion, in [0, 1].
    pub rate: f64,
    /// How long the arm stands, s.
    #[serde(default = "one_second")]
    pub duration_s: f64,
}

/// How a faulty belt misbehaves.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(from = "String", into = "String")]
pub enum BeltFaultMode {
    /// The belt runs at `speed_fraction` of its commanded speed (a slipping drive).
    Slow,
    /// The belt stands still whatever it is told (a jammed roller).
    Stall,
    /// A name that is no mode; validation refuses it, naming the key.
    Unknown(String),
}

impl BeltFaultMode {
    /// The modes a scenario may name.
    pub const NAMES: [&str; 2] = ["slow", "stall"];
}

impl From<String> for BeltFaultMode {
    fn from(name: String) -> Self {
        match name.as_str() {
            "slow" => Self::Slow,
            "stall" => Self::Stall,
            _ => Self::Unknown(name),
        }
    }
}

impl From<BeltFaultMode> for String {
    fn from(mode: BeltFaultMode) -> Self {
        match mode {
            BeltFaultMode::Slow => "slow".into(),
            BeltFaultMode::Stall => "stall".into(),
            BeltFaultMode::Unknown(name) => name,
        }
    }
}

/// A belt that runs slower than commanded, or stalls, for a while.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BeltFaultSection {
    /// Share of trials in which the belt misbehaves once, in [0, 1].
    pub rate: f64,
    /// `"slow"` or `"stall"`.
    #[serde(default = "default_belt_mode")]
    pub mode: BeltFaultMode,
    /// The share of the commanded speed a slow belt runs at, in (0, 1); a stall runs at none.
    #[serde(default = "default_speed_fraction")]
    pub speed_fraction: f64,
    /// When the fault begins, after the trial starts, drawn uniformly in `[least, most]`, s.
    #[serde(default = "default_onset_range_s")]
    pub onset_range_s: [f64; 2],
    /// How long it lasts, s.
    #[serde(default = "default_belt_duration_s")]
    pub duration_s: f64,
}

fn default_belt_mode() -> BeltFaultMode {
    BeltFaultMode::Slow
}

fn default_speed_fraction() -> f64 {
    0.5
}

fn default_onset_range_s() -> [f64; 2] {
    [0.0, 1.0]
}

fn default_belt_duration_s() -> f64 {
    3.0
}

/// A photo-eye that lies: a trigger with nothing in the beam, or an item that passes unseen.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhotoEyeFaultSection {
    /// Share of trials with one false trigger, in [0, 1].
    #[serde(default)]
    pub false_trigger_rate: f64,
    /// Share of trials in which one item passes the beam without a trigger, in [0, 1].
    #[serde(default)]
    pub missed_trigger_rate: f64,
}
