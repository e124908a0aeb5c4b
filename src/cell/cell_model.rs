//! What a scenario fixes, built once for a whole batch: the scenario itself, the robot's
//! description, and the arm read from it with its closed-form inverse kinematics. Each trial's
//! world is built from it ([`super::Cell::build`]) and reset from the trial's seed.

use std::path::{Path, PathBuf};

use super::layout::CellError;
use crate::kinematics::{AnalyticIk, ArmModel, BUILTIN_URDF, BUILTIN_URDF_PATH, UrdfArm};
use crate::scenario::{Catalogue, Scenario};
use crate::sim::{SimArm, SimError, World, WorldParams};
use nalgebra::Isometry3;

/// A robot description: where it was read from (named in errors, anchoring mesh paths) and
/// its text.
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfSource {
    /// The file.
    pub path: PathBuf,
    /// Its text.
    pub text: String,
}

/// The cell's model: what every trial of a scenario shares.
#[derive(Debug, Clone)]
pub struct CellModel {
    scenario: Scenario,
    catalogue: Catalogue,
    urdf: UrdfSource,
    arm: UrdfArm,
    ik: AnalyticIk,
}

impl UrdfSource {
    /// The URDF `scenario` names in `robot.urdf`, read relative to `scenario_path`; `None` when
    /// it names none (the built-in URDF).
    pub fn of_scenario(
        scenario: &Scenario,
        scenario_path: &Path,
    ) -> Result<Option<Self>, CellError> {
        let Some(relative) = &scenario.robot.urdf else {
            return Ok(None);
        };
        let path = scenario_path
            .parent()
            .unwrap_or(Path::new("."))
            .join(relative);
        let text = std::fs::read_to_string(&path).map_err(|e| {
            CellError::Sim(SimError::Urdf {
                reason: e.to_string(),
                path: path.clone(),
            })
        })?;
        Ok(Some(Self { path, text }))
    }
}

impl CellModel {
    /// The model of `scenario`, read from `scenario_path` (which anchors a relative
    /// `robot.urdf`); the built-in URDF when the scenario names none.
    pub fn new(scenario: Scenario, scenario_path: &Path) -> Result<Self, CellError> {
        let urdf = UrdfSource::of_scenario(&scenario, scenario_path)?;
        Self::with_urdf(scenario, urdf)
    }

    /// The model of `scenario` with the robot described by `urdf` (the built-in URDF when
    /// `None`).
    pub fn with_urdf(scenario: Scenario, urdf: Option<UrdfSource>) -> Result<Self, CellError> {
        let urdf = urdf.unwrap_or_else(|| UrdfSource {
            path: PathBuf::from(BUILTIN_URDF_PATH),
            text: BUILTIN_URDF.to_owned(),
        });
        let arm = UrdfArm::from_urdf_str(&urdf.text).map_err(|e| {
            CellError::Sim(SimError::Urdf {
                reason: e.to_string(),
                path: urdf.path.clone(),
            })
        })?;
        let ik = AnalyticIk::new(arm.model.clone()).map_err(|e| {
            CellError::Sim(SimError::Urdf {
                reason: e.to_string(),
                path: urdf.path.clone(),
            })
        })?;
        Ok(Self {
            catalogue: Catalogue::of(&scenario),
            scenario,
            urdf,
            arm,
            ik,
        })
    }

    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The scenario's part types and bins by id, in SI units.
    pub fn catalogue(&self) -> &Catalogue {
        &self.catalogue
    }

    /// Sets every part type's grip force (for experiments such as a too-weak gripper).
    pub fn set_grip_force_n(&mut self, force_n: f64) {
        self.scenario.gripper.grip_force_n = force_n;
        for part in &mut self.scenario.part_types {
            part.grip_force_n = None;
        }
        self.catalogue = Catalogue::of(&self.scenario);
    }

    /// The robot's description.
    pub fn urdf(&self) -> &UrdfSource {
        &self.urdf
    }

    /// The arm's joints and links by name, and its kinematic model.
    pub fn arm(&self) -> &UrdfArm {
        &self.arm
    }

    /// The arm's kinematic model with the gripper's TCP.
    pub fn arm_model(&self) -> &ArmModel {
        &self.arm.model
    }

    /// The closed-form inverse kinematics of the arm.
    pub fn ik(&self) -> &AnalyticIk {
        &self.ik
    }

    /// A physics world of the scenario's `[physics]` holding the arm alone, its base where the
    /// scenario puts it (the arm as loaded, not yet at home).
    pub fn arm_world(&self) -> Result<(World, SimArm), SimError> {
        let mut world = World::new(WorldParams::from_section(&self.scenario.physics));
        let [x, y, z] = self.scenario.robot.base_xyz_m;
        let arm = SimArm::from_urdf_with(
            &mut world,
            &self.urdf.text,
            &self.urdf.path,
            Some(&self.arm),
            Isometry3::translation(x, y, z),
        )?;
        Ok((world, arm))
    }
}
