//! The arm a scenario's `robot.urdf` (or the built-in URDF) describes, for the checks that
//! need its reach and limits.

use std::path::Path;

use super::{Scenario, ScenarioError};
use crate::kinematics::{ArmModel, BUILTIN_URDF_PATH, UrdfArm};

impl Scenario {
    /// The arm's kinematic model with the gripper's TCP; an error naming `file`, the key
    /// `robot.urdf`, the URDF and why when it cannot be read or solved.
    pub(super) fn arm_model(&self, file: &Path) -> Result<ArmModel, ScenarioError> {
        let fail = |reason: String| ScenarioError {
            file: file.to_path_buf(),
            key: "robot.urdf".into(),
            reason,
        };
        let arm = match &self.robot.urdf {
            Some(relative) => {
                let path = file.parent().unwrap_or(Path::new(".")).join(relative);
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| fail(format!("cannot read {}: {e}", path.display())))?;
                UrdfArm::from_urdf_str(&text)
                    .map_err(|e| fail(format!("{}: {e}", path.display())))?
            }
            None => UrdfArm::builtin()
                .map_err(|e| fail(format!("the built-in {BUILTIN_URDF_PATH}: {e}")))?,
        };
        Ok(arm.model)
    }
}
