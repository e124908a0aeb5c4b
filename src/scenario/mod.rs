//! Scenario files: the cell's dimensions, part table, bins and trial settings, from TOML.
//!
//! Every field is validated on load; an error names the file, the key and the reason.

mod camera_sections;
mod catalogue;
mod extends;
mod faults;
mod overrides;
mod robot_arm;
mod separability;
mod scenario_error;
mod validate;
mod validate_camera;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use camera_sections::{
    CAMERA_ENVELOPE, CameraEnvelope, CameraSection, DEFAULT_CAMERA_HEIGHT_ABOVE_BELT_M, LightSpec,
    LightingSection, SensorSection,
};
pub use catalogue::{BinId, Catalogue, PartKind, PartTypeId, STEEL_DENSITY_KG_M3};
pub use extends::EXTENDS_KEY;
pub use faults::{
    ArmFaultSection, BeltFaultMode, BeltFaultSection, BlackoutMode, CameraFaultSection,
    FAULT_KINDS, FaultsSection, GripperFaultSection, MAX_FAULT_DURATION_S, PhotoEyeFaultSection,
};
pub use overrides::{
    Override, OverrideSyntaxError, SweepAxis, parse_value, split_values, sweep_grid,
};
pub use scenario_error::ScenarioError;
pub use separability::{Confusion, SizedType, confusable_types, confusion, first_confusion};

use extends::ScenarioDocument;

/// A whole scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Scenario name, used in reports.
    pub name: String,
    /// Scenario seed; each trial's seed derives from it and the trial index.
    pub seed: u64,
    /// Number of trials.
    pub trials: u32,
    /// The least success rate this scenario must reach, in [0, 1]: the batch's gate when
    /// `--min-success` does not set one (exit code 1 below it). `None`: no gate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_success: Option<f64>,
    /// Parts per trial: 1 for the paper's experiment; more makes each trial one run of a
    /// continuous stream of that many parts (see [`StreamSection`]).
    #[serde(default = "one")]
    pub parts_per_trial: u32,
    /// Roundness tolerance: parts whose bore is out of round by more go to the reject bin, mm.
    pub roundness_tolerance_mm: f64,
    /// Half-width of the band around the tolerance inside which no measurement can prove
    /// conformance either way (ISO 14253-1's uncertainty zone): the metrology's expanded
    /// uncertainty (k = 2) of roundness, mm. A part whose true roundness lies inside it may go to
    /// its accept bin or the reject bin; reports count such parts apart.
    #[serde(default = "default_roundness_uncertainty_mm")]
    pub roundness_uncertainty_mm: f64,
    /// Physics settings.
    #[serde(default)]
    pub physics: PhysicsSection,
    /// The arm and its pedestal.
    #[serde(default)]
    pub robot: RobotSection,
    /// The gripper.
    #[serde(default)]
    pub gripper: GripperSection,
    /// The conveyor.
    #[serde(default)]
    pub conveyor: ConveyorSection,
    /// The part table: at least six types.
    pub part_types: Vec<PartType>,
    /// How part instances are drawn.
    #[serde(default)]
    pub parts: PartsSection,
    /// The plastic-bottle distractor.
    #[serde(default)]
    pub bottle: BottleSection,
    /// The bins: one per accepted type group, and one reject bin.
    pub bins: Vec<Bin>,
    /// Time-outs and tolerances of the task controller.
    #[serde(default)]
    pub task: TaskSection,
    /// The feeder of a stream trial (`parts_per_trial` > 1).
    #[serde(default)]
    pub stream: StreamSection,
    /// The overhead camera at the pick station.
    #[serde(default)]
    pub camera: CameraSection,
    /// How the camera's findings are read.
    #[serde(default)]
    pub perception: PerceptionSection,
    /// The cell's lights.
    #[serde(default)]
    pub lighting: LightingSection,
    /// Sensor and scene realism drawn per image: noise, stains, light and pose variation.
    #[serde(default)]
    pub sensor: SensorSection,
    /// Faults injected in a share of trials (none when absent).
    #[serde(default, skip_serializing_if = "FaultsSection::is_empty")]
    pub faults: FaultsSection,
}

fn one() -> u32 {
    1
}

/// The metrology's expanded uncertainty of roundness (k = 2) in the closed loop, mm, for
/// scenarios that do not give their own (`twincell calibrate` measures 0.018-0.019 mm on the
/// overhead camera and writes a camera's own band; see docs/calibrate.md).
pub const DEFAULT_ROUNDNESS_UNCERTAINTY_MM: f64 = 0.02;

fn default_roundness_uncertainty_mm() -> f64 {
    DEFAULT_ROUNDNESS_UNCERTAINTY_MM
}

/// Physics settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhysicsSection {
    /// Fixed time step, s.
    pub dt_s: f64,
    /// Solver substeps per step while a robot collider is near a moving body (fewer while none
    /// is: `sim::FREE_SOLVER_ITERATIONS`).
    pub solver_iterations: usize,
    /// Natural frequency of contacts between moving bodies, Hz.
    pub contact_frequency_hz: f64,
    /// Damping ratio of contacts between moving bodies.
    pub contact_damping_ratio: f64,
}

impl Default for PhysicsSection {
    fn default() -> Self {
        // Why each value: see `sim::World::new`, which turns these into solver settings.
        Self {
            dt_s: 1.0 / 240.0,
            solver_iterations: 4,
            contact_frequency_hz: 60.0,
            contact_damping_ratio: 2.0,
        }
    }
}

/// The arm on its pedestal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotSection {
    /// Pedestal top (the arm's base_link) in the world, m.
    pub base_xyz_m: [f64; 3],
    /// Pedestal footprint (square side), m.
    pub pedestal_side_m: f64,
    /// Home joint angles, rad.
    pub home_q_rad: [f64; 6],
    /// Fraction of the joint speed and acceleration limits used for free motion (1: the arm's
    /// full published limits, along time-optimal trajectories).
    pub speed_fraction: f64,
    /// Fraction of the joint limits used while carrying a part; the grip's own limit (what the
    /// jaws' friction holds, see `planning::Payload`) applies on top of it.
    pub carry_speed_fraction: f64,
    /// Optional URDF path (relative to the scenario file); the built-in arm when absent.
    pub urdf: Option<PathBuf>,
}

impl Default for RobotSection {
    fn default() -> Self {
        Self {
            base_xyz_m: [0.0, 0.0, 0.6],
            pedestal_side_m: 0.3,
            // TCP pointing down 0.3 m in front of the base and 0.4 m above it, elbow up.
            home_q_rad: [
                -1.153_817,
                0.458_529,
                1.673_047,
                -0.356_278,
                std::f64::consts::FRAC_PI_2,
                0.416_979,
            ],
            // The simulated servos overshoot a velocity plateau by a few per cent, and a loaded
            // wrist more when its acceleration steps at the start of a carry: at these fractions
            // the measured speeds stay within the published limits (docs/motion.md).
            speed_fraction: 0.9,
            carry_speed_fraction: 0.85,
            urdf: None,
        }
    }
}

/// The parallel gripper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GripperSection {
    /// Force each finger presses with, N.
    pub grip_force_n: f64,
    /// Friction coefficient of the finger pads.
    pub pad_friction: f64,
    /// Clearance between an open finger and the part's outer surface, m.
    pub open_clearance_m: f64,
    /// How far a pad deflects before a held part slides, mm (`sim::PadStiction`); 0 turns it off.
    pub pad_preslide_mm: f64,
}

impl Default for GripperSection {
    fn default() -> Self {
        Self {
            grip_force_n: 60.0,
            pad_friction: 1.0,
            open_clearance_m: 0.012,
            pad_preslide_mm: 1.0,
        }
    }
}

/// The belt conveyor: runs along +x of the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ConveyorSection {
    /// Centre of the belt's top surface, m.
    pub belt_center_m: [f64; 3],
    /// Belt length along x, m.
    pub length_m: f64,
    /// Belt width along y, m.
    pub width_m: f64,
    /// Belt surface speed, m/s.
    pub speed_m_s: f64,
    /// The speed the belt slows to before an item reaches the photo-eye, m/s. When `speed_m_s`
    /// is higher, a slow-down zone upstream of the eye (long enough to brake from the one to
    /// the other) drops the belt to this speed, so an item stops just past the beam instead of
    /// running through it; at or below it the belt runs at `speed_m_s` to the eye.
    pub creep_speed_m_s: f64,
    /// x of the photo-eye beam (the pick station), m.
    pub photo_eye_x_m: f64,
    /// How far upstream of the photo-eye parts are placed, m.
    pub spawn_upstream_m: f64,
    /// Belt friction coefficient.
    pub friction: f64,
    /// Conveyor tracking: the belt never stops; the arm meets each part on the moving belt and
    /// follows it through descend, grasp and lift (`false`: stop-and-go, the paper's way).
    /// Streams only.
    #[serde(skip_serializing_if = "is_false")]
    pub tracking: bool,
}

impl ConveyorSection {
    /// Length of the slow-down zone that ends at the photo-eye, m: the distance in which a
    /// drive ramping at `accel_m_s2` brings the belt from `speed_m_s` down to
    /// `creep_speed_m_s`, plus 10 mm; 0 (no zone) when the belt runs no faster than the creep.
    pub fn slow_zone_m(&self, accel_m_s2: f64) -> f64 {
        if self.speed_m_s <= self.creep_speed_m_s {
            return 0.0;
        }
        (self.speed_m_s.powi(2) - self.creep_speed_m_s.powi(2)) / (2.0 * accel_m_s2) + 0.01
    }
}

impl Default for ConveyorSection {
    fn default() -> Self {
        Self {
            belt_center_m: [0.0, -0.45, 0.70],
            length_m: 1.6,
            width_m: 0.32,
            speed_m_s: 0.25,
            creep_speed_m_s: 0.25,
            photo_eye_x_m: 0.05,
            spawn_upstream_m: 0.3,
            friction: 0.8,
            tracking: false,
        }
    }
}

/// One axle-part type: a steel tube standing upright.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartType {
    /// Type name.
    pub name: String,
    /// Nominal bore diameter, mm.
    pub bore_diameter_mm: f64,
    /// Outer diameter, mm.
    pub outer_diameter_mm: f64,
    /// Height, mm.
    pub height_mm: f64,
    /// Material density, kg/m^3 (steel by default).
    #[serde(default = "steel")]
    pub density_kg_m3: f64,
    /// Grip force per jaw for this type, N (the gripper's default when absent): the cell's
    /// recipe, chosen by the detected type.
    #[serde(default)]
    pub grip_force_n: Option<f64>,
    /// Largest difference between a measured and the nominal bore or outer diameter that still
    /// names this type, mm (default [`DEFAULT_DIAMETER_TOLERANCE_MM`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diameter_tolerance_mm: Option<f64>,
}

/// The diameter tolerance of a type that sets none, mm. On the default overhead camera the
/// readings err by at most 0.05 mm (bore) and 0.14 mm (outer diameter, the coarser) over
/// paper_50's 50 parts; a tilted or coarser camera reads coarser, so the default leaves several
/// times that (`twincell calibrate` estimates the camera's own; see docs/calibrate.md).
pub const DEFAULT_DIAMETER_TOLERANCE_MM: f64 = 1.0;

impl PartType {
    /// The type's diameter tolerance for identification, mm.
    pub fn diameter_tolerance_mm(&self) -> f64 {
        self.diameter_tolerance_mm
            .unwrap_or(DEFAULT_DIAMETER_TOLERANCE_MM)
    }
}

/// The type name decisions carry for a part that no type, or more than one, fits by
/// measurement; no scenario type may take it.
pub const UNIDENTIFIED: &str = "unidentified";

/// How the camera names a part's type.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TypeBy {
    /// By measuring its bore and outer diameters against every type's nominal sizes.
    #[default]
    Measurement,
    /// By the detector's class (the paper's way): the model must be trained on the catalogue.
    Detector,
}

/// The `[perception]` section: how the camera's findings are read.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PerceptionSection {
    /// How a part's type is named.
    pub type_by: TypeBy,
}

fn steel() -> f64 {
    STEEL_DENSITY_KG_M3
}

/// How part instances are drawn.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PartsSection {
    /// Largest true out-of-roundness drawn, mm (uniform in [0, max]).
    pub max_roundness_mm: f64,
    /// Largest lateral offset of a part from the belt's centre line, m.
    pub max_lateral_offset_m: f64,
}

impl Default for PartsSection {
    fn default() -> Self {
        Self {
            max_roundness_mm: 1.0,
            max_lateral_offset_m: 0.06,
        }
    }
}

/// The plastic bottle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BottleSection {
    /// Whether a bottle is placed at all.
    pub enabled: bool,
    /// Body radius, m.
    pub radius_m: f64,
    /// Total height, m.
    pub height_m: f64,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Nearest and farthest centre distance from the part, m.
    pub distance_range_m: [f64; 2],
    /// Share of bottles that lie on their side.
    pub lying_fraction: f64,
    /// How many bottles a single-part trial puts near its part, `[fewest, most]`, drawn
    /// uniformly (a stream's bottles come from `stream.bottles` instead). Signed, so that a
    /// negative count is refused by validation with the key's range, not by the TOML reader.
    pub count_range: [i64; 2],
    /// When set, the first bottle's gap to the part, `[least, most]`, m: the distance between
    /// their footprints (a standing bottle's disc, a lying bottle's rectangle), not between
    /// centres. The other bottles, and the first when this is unset, keep their centres
    /// `distance_range_m` from the part's and at least 10 mm clear of it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub near_gap_range_m: Option<[f64; 2]>,
    /// How many of the bottles, the first ones, stand at `near_gap_range_m` from the part when
    /// that is set (at least 1, at most `count_range`'s fewest). Signed for the same reason as
    /// `count_range`.
    pub near_count: i64,
}

impl Default for BottleSection {
    fn default() -> Self {
        Self {
            enabled: true,
            radius_m: 0.033,
            height_m: 0.20,
            mass_kg: 0.03,
            distance_range_m: [0.10, 0.16],
            lying_fraction: 0.0,
            count_range: [1, 1],
            near_gap_range_m: None,
            near_count: 1,
        }
    }
}

/// A bin standing on a table beside the arm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bin {
    /// Bin name.
    pub name: String,
    /// Centre of the bin's floor, m.
    pub floor_center_m: [f64; 3],
    /// Inside size along x and y, m.
    pub size_m: [f64; 2],
    /// Wall height above the floor, m.
    #[serde(default = "wall_height")]
    pub wall_height_m: f64,
    /// Part types this bin accepts (empty for the reject bin).
    #[serde(default)]
    pub accepts: Vec<String>,
    /// Whether this is the reject bin.
    #[serde(default)]
    pub reject: bool,
    /// Whether this bin takes the foreign objects (bottles) the cell removes from the belt to
    /// free a blocked part; at most one, reachable, accepting no type.
    #[serde(default, skip_serializing_if = "is_false")]
    pub waste: bool,
    /// Whether this bin is the collector at the belt's downstream end that catches what the
    /// belt carries off it (items let through as unpickable); at most one, under the belt's
    /// end, accepting no type.
    #[serde(default, skip_serializing_if = "is_false")]
    pub collector: bool,
}

fn is_false(flag: &bool) -> bool {
    !*flag
}

fn wall_height() -> f64 {
    0.08
}

/// Time-outs and tolerances of the task controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TaskSection {
    /// Longest wait for a part at the photo-eye, s.
    pub wait_timeout_s: f64,
    /// Longest time for the whole trial, s.
    pub trial_timeout_s: f64,
    /// Part movement relative to the fingers that counts as a slip, m.
    pub slip_tolerance_m: f64,
    /// Bottle displacement that counts as disturbing it, m.
    pub bottle_tolerance_m: f64,
}

impl Default for TaskSection {
    fn default() -> Self {
        Self {
            wait_timeout_s: 6.0,
            trial_timeout_s: 45.0,
            slip_tolerance_m: 0.025,
            bottle_tolerance_m: 0.01,
        }
    }
}

/// The feeder of a stream trial: parts and bottles put on the belt one after another, a fixed
/// belt distance apart, in a seeded random order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StreamSection {
    /// Belt travel between two items put on the belt, m: the feeder places the next item at
    /// the spawn point (`conveyor.spawn_upstream_m` before the photo-eye) once the belt has
    /// carried the previous one this far.
    pub spacing_m: f64,
    /// Bottles mixed into the stream (each passes the pick station untouched).
    pub bottles: u32,
}

impl Default for StreamSection {
    fn default() -> Self {
        Self {
            spacing_m: 0.25,
            bottles: 0,
        }
    }
}

impl Scenario {
    /// Whether a trial is a stream of several parts rather than the paper's single part.
    pub fn is_stream(&self) -> bool {
        self.parts_per_trial > 1
    }

    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        Self::from_toml(&read(path)?, path)
    }

    /// Parses and validates scenario TOML; `path` names the source in errors, and the bases
    /// that an `extends` key names are read relative to its folder.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self, ScenarioError> {
        let document = ScenarioDocument::resolve(text, path)?;
        let scenario: Scenario = if document.has_bases() {
            document.deserialize(document.table.clone())?
        } else {
            let parsed = toml::de::Deserializer::parse(text)
                .map_err(|e| ScenarioError::from_toml(path, text, &e))?;
            serde_path_to_error::deserialize(parsed)
                .map_err(|e| ScenarioError::from_path_error(path, Some(text), &e))?
        };
        scenario.validate(path).map_err(|e| document.blame(e))?;
        Ok(scenario)
    }

    /// The files a scenario file is made of: itself, then each base it extends, with their
    /// bytes (a batch's identity covers them all).
    pub fn source_files(path: &Path) -> Result<Vec<(PathBuf, String)>, ScenarioError> {
        let text = read(path)?;
        Ok(ScenarioDocument::resolve(&text, path)?.sources)
    }
}

/// The text of the scenario file at `path`.
fn read(path: &Path) -> Result<String, ScenarioError> {
    std::fs::read_to_string(path).map_err(|e| ScenarioError {
        file: path.to_path_buf(),
        key: String::new(),
        reason: format!("cannot read: {e}"),
    })
}
