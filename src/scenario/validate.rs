//! Scenario validation: every check names the file, the key and the reason.

use std::collections::BTreeSet;
use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};

use super::separability::confusable_types;
use super::{Scenario, ScenarioError, UNIDENTIFIED};
use crate::kinematics::{AnalyticIk, ArmModel, IkSolver};

/// The widest the gripper opens: twice the finger stroke, m.
pub const MAX_GRIPPER_OPENING_M: f64 = 0.10;
/// The most force a finger motor can give, N.
pub const MAX_FINGER_FORCE_N: f64 = 100.0;

/// Farthest any placed thing (robot base, belt, bin, camera) may sit from the cell's origin
/// along each axis, m: the arm reaches under 1 m, so a cell fits well within this.
pub const MAX_CELL_REACH_M: f64 = 10.0;
/// Fastest belt, m/s: conveyors that feed a pick station run at a few tenths of this.
pub const MAX_BELT_SPEED_M_S: f64 = 5.0;
/// Highest friction coefficient accepted (rubber on steel is about 1).
pub const MAX_FRICTION: f64 = 5.0;
/// Smallest `diameter_tolerance_mm`, mm: a few times the bore diameter's uncertainty at the
/// default camera; tighter than the outer diameter's reading it leaves parts unidentified.
pub const MIN_DIAMETER_TOLERANCE_MM: f64 = 0.1;
/// Shortest tube, mm: the tube family the detector is trained on starts here
/// (`render::family`), and the pads, stopping 8 mm over the belt, still grip 22 mm of it.
pub const MIN_PART_HEIGHT_MM: f64 = 30.0;
/// Most bottles a single-part trial may put near its part.
pub const MAX_BOTTLES: i64 = 8;

/// A value as an error message shows it: plainly, or in exponent form when huge or tiny.
fn show(value: f64) -> String {
    if value == 0.0 || !value.is_finite() || (1e-6..1e9).contains(&value.abs()) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

pub(super) struct Checker<'a> {
    file: &'a Path,
}

impl Checker<'_> {
    pub(super) fn fail(&self, key: impl Into<String>, reason: impl Into<String>) -> ScenarioError {
        ScenarioError {
            file: self.file.to_path_buf(),
            key: key.into(),
            reason: reason.into(),
        }
    }

    pub(super) fn positive(&self, key: &str, value: f64) -> Result<(), ScenarioError> {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(self.fail(
                key,
                format!("must be a positive number, got {}", show(value)),
            ))
        }
    }

    pub(super) fn in_range(
        &self,
        key: &str,
        value: f64,
        low: f64,
        high: f64,
    ) -> Result<(), ScenarioError> {
        if value.is_finite() && (low..=high).contains(&value) {
            Ok(())
        } else {
            Err(self.fail(
                key,
                format!("must lie in [{low}, {high}], got {}", show(value)),
            ))
        }
    }

    /// A positive value no larger than `high`: `(0, high]`.
    pub(super) fn positive_up_to(
        &self,
        key: &str,
        value: f64,
        high: f64,
    ) -> Result<(), ScenarioError> {
        if value.is_finite() && value > 0.0 && value <= high {
            Ok(())
        } else {
            Err(self.fail(
                key,
                format!(
                    "must be a positive number in (0, {high}], got {}",
                    show(value)
                ),
            ))
        }
    }

    /// A point whose every coordinate lies within `reach` of the origin, m.
    pub(super) fn point_within(
        &self,
        key: &str,
        point: &[f64; 3],
        reach: f64,
    ) -> Result<(), ScenarioError> {
        if point.iter().all(|v| v.is_finite() && v.abs() <= reach) {
            Ok(())
        } else {
            Err(self.fail(
                key,
                format!(
                    "must lie in [-{reach}, {reach}] m on each axis, got [{}]",
                    point.map(show).join(", ")
                ),
            ))
        }
    }

    pub(super) fn finite(&self, key: &str, values: &[f64]) -> Result<(), ScenarioError> {
        if values.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(self.fail(key, "must be finite numbers"))
        }
    }
}

impl Scenario {
    /// Checks every value; the first problem found is returned.
    pub fn validate(&self, file: &Path) -> Result<(), ScenarioError> {
        let c = Checker { file };
        if self.name.trim().is_empty() {
            return Err(c.fail("name", "must not be empty"));
        }
        if self.trials == 0 {
            return Err(c.fail("trials", "must be at least 1"));
        }
        if let Some(rate) = self.min_success {
            c.in_range("min_success", rate, 0.0, 1.0)?;
        }
        if !(1..=1000).contains(&self.parts_per_trial) {
            return Err(c.fail("parts_per_trial", "must lie in [1, 1000]"));
        }
        c.positive_up_to("roundness_tolerance_mm", self.roundness_tolerance_mm, 5.0)?;
        c.in_range(
            "roundness_uncertainty_mm",
            self.roundness_uncertainty_mm,
            0.0,
            self.roundness_tolerance_mm,
        )?;
        c.in_range("physics.dt_s", self.physics.dt_s, 1e-4, 0.02)?;
        c.in_range(
            "physics.contact_frequency_hz",
            self.physics.contact_frequency_hz,
            1.0,
            10_000.0,
        )?;
        c.in_range(
            "physics.contact_damping_ratio",
            self.physics.contact_damping_ratio,
            0.0,
            100.0,
        )?;
        if !(1..=64).contains(&self.physics.solver_iterations) {
            return Err(c.fail("physics.solver_iterations", "must lie in [1, 64]"));
        }
        let arm = self.arm_model(file)?;
        self.validate_robot(&c, &arm)?;
        self.validate_conveyor(&c)?;
        self.validate_parts(&c)?;
        self.validate_bottle(&c)?;
        self.validate_bins(&c, &arm)?;
        self.validate_stream(&c)?;
        let task = &self.task;
        c.positive_up_to("task.wait_timeout_s", task.wait_timeout_s, 3600.0)?;
        c.positive_up_to("task.trial_timeout_s", task.trial_timeout_s, 86_400.0)?;
        c.positive_up_to("task.slip_tolerance_m", task.slip_tolerance_m, 1.0)?;
        c.positive_up_to("task.bottle_tolerance_m", task.bottle_tolerance_m, 1.0)?;
        self.validate_camera(&c)?;
        self.faults.validate(&c)?;
        Ok(())
    }

    fn validate_stream(&self, c: &Checker) -> Result<(), ScenarioError> {
        let stream = &self.stream;
        if !self.is_stream() {
            if stream != &super::StreamSection::default() {
                return Err(c.fail("stream", "only used when parts_per_trial is more than 1"));
            }
            return Ok(());
        }
        // Two items must fit side by side: the widest part or the bottle (lying, its length),
        // plus room for the open fingers between them.
        let widest_part_m = self
            .part_types
            .iter()
            .map(|p| p.outer_diameter_mm / 1000.0)
            .fold(0.0, f64::max);
        let bottle_m = if self.stream.bottles > 0 && self.bottle.lying_fraction > 0.0 {
            self.bottle.height_m
        } else {
            2.0 * self.bottle.radius_m
        };
        let least = widest_part_m.max(bottle_m) + 0.08;
        c.in_range("stream.spacing_m", stream.spacing_m, least, 10.0)?;
        if stream.bottles > 1000 {
            return Err(c.fail("stream.bottles", "must lie in [0, 1000]"));
        }
        if self.bottle.enabled {
            return Err(c.fail(
                "bottle.enabled",
                "a stream mixes its bottles in through stream.bottles; set bottle.enabled = false",
            ));
        }
        Ok(())
    }

    fn validate_robot(&self, c: &Checker, arm: &ArmModel) -> Result<(), ScenarioError> {
        let robot = &self.robot;
        c.point_within("robot.base_xyz_m", &robot.base_xyz_m, MAX_CELL_REACH_M)?;
        c.positive_up_to("robot.pedestal_side_m", robot.pedestal_side_m, 2.0)?;
        c.positive("robot.base_xyz_m[2]", robot.base_xyz_m[2])?;
        c.in_range("robot.speed_fraction", robot.speed_fraction, 0.01, 1.0)?;
        c.in_range(
            "robot.carry_speed_fraction",
            robot.carry_speed_fraction,
            0.01,
            1.0,
        )?;
        if let Err(e) = arm.check_limits(&robot.home_q_rad) {
            return Err(c.fail("robot.home_q_rad", e.to_string()));
        }
        let gripper = &self.gripper;
        c.in_range(
            "gripper.grip_force_n",
            gripper.grip_force_n,
            0.0,
            MAX_FINGER_FORCE_N,
        )?;
        c.positive("gripper.grip_force_n", gripper.grip_force_n)?;
        c.positive_up_to("gripper.pad_friction", gripper.pad_friction, MAX_FRICTION)?;
        c.in_range(
            "gripper.open_clearance_m",
            gripper.open_clearance_m,
            0.0,
            0.05,
        )?;
        c.in_range("gripper.pad_preslide_mm", gripper.pad_preslide_mm, 0.0, 5.0)?;
        Ok(())
    }

    fn validate_conveyor(&self, c: &Checker) -> Result<(), ScenarioError> {
        let belt = &self.conveyor;
        c.point_within(
            "conveyor.belt_center_m",
            &belt.belt_center_m,
            MAX_CELL_REACH_M,
        )?;
        c.positive_up_to("conveyor.length_m", belt.length_m, 50.0)?;
        c.positive_up_to("conveyor.width_m", belt.width_m, 2.0)?;
        c.positive_up_to("conveyor.speed_m_s", belt.speed_m_s, MAX_BELT_SPEED_M_S)?;
        c.positive_up_to(
            "conveyor.creep_speed_m_s",
            belt.creep_speed_m_s,
            MAX_BELT_SPEED_M_S,
        )?;
        c.positive_up_to("conveyor.friction", belt.friction, MAX_FRICTION)?;
        c.positive_up_to("conveyor.spawn_upstream_m", belt.spawn_upstream_m, 50.0)?;
        let half = belt.length_m / 2.0;
        let (start, end) = (belt.belt_center_m[0] - half, belt.belt_center_m[0] + half);
        c.in_range("conveyor.photo_eye_x_m", belt.photo_eye_x_m, start, end)?;
        if belt.photo_eye_x_m - belt.spawn_upstream_m < start {
            return Err(c.fail(
                "conveyor.spawn_upstream_m",
                "puts the spawn point off the upstream end of the belt",
            ));
        }
        if belt.belt_center_m[2] <= 0.0 {
            return Err(c.fail("conveyor.belt_center_m[2]", "belt must be above the floor"));
        }
        if belt.tracking && !self.is_stream() {
            return Err(c.fail(
                "conveyor.tracking",
                "picks from a moving stream: needs parts_per_trial > 1",
            ));
        }
        if belt.tracking && !self.faults.is_empty() {
            return Err(c.fail(
                "conveyor.tracking",
                "faults are injected and recovered in stop-and-go only; remove [faults]",
            ));
        }
        Ok(())
    }

    fn validate_parts(&self, c: &Checker) -> Result<(), ScenarioError> {
        if self.part_types.is_empty() {
            return Err(c.fail("part_types", "needs at least one type"));
        }
        let mut names = BTreeSet::new();
        for (i, part) in self.part_types.iter().enumerate() {
            let key = |field: &str| format!("part_types[{i}].{field}");
            if part.name.trim().is_empty() || !names.insert(part.name.as_str()) {
                return Err(c.fail(key("name"), "must be a unique, non-empty name"));
            }
            c.positive_up_to(&key("bore_diameter_mm"), part.bore_diameter_mm, 100.0)?;
            c.positive_up_to(&key("outer_diameter_mm"), part.outer_diameter_mm, 100.0)?;
            c.in_range(&key("density_kg_m3"), part.density_kg_m3, 100.0, 25_000.0)?;
            c.in_range(&key("height_mm"), part.height_mm, MIN_PART_HEIGHT_MM, 200.0)?;
            if let Some(tolerance) = part.diameter_tolerance_mm {
                c.in_range(
                    &key("diameter_tolerance_mm"),
                    tolerance,
                    MIN_DIAMETER_TOLERANCE_MM,
                    10.0,
                )?;
            }
            if part.name == UNIDENTIFIED {
                return Err(c.fail(key("name"), "is the name of unidentified parts in reports"));
            }
            if let Some(force) = part.grip_force_n {
                c.in_range(&key("grip_force_n"), force, 0.0, MAX_FINGER_FORCE_N)?;
                c.positive(&key("grip_force_n"), force)?;
            }
            if part.bore_diameter_mm + 2.0 * self.parts.max_roundness_mm + 4.0
                >= part.outer_diameter_mm
            {
                return Err(c.fail(
                    key("bore_diameter_mm"),
                    "leaves a wall under 2 mm around the bore",
                ));
            }
            let opening = part.outer_diameter_mm / 1000.0 + 2.0 * self.gripper.open_clearance_m;
            if opening > MAX_GRIPPER_OPENING_M {
                return Err(c.fail(
                    key("outer_diameter_mm"),
                    format!(
                        "needs a gripper opening of {:.0} mm, wider than its {:.0} mm",
                        opening * 1000.0,
                        MAX_GRIPPER_OPENING_M * 1000.0
                    ),
                ));
            }
            let max_offset = self.conveyor.width_m / 2.0 - part.outer_diameter_mm / 2000.0;
            if self.parts.max_lateral_offset_m > max_offset {
                return Err(c.fail(
                    "parts.max_lateral_offset_m",
                    format!("lets part `{}` overhang the belt edge", part.name),
                ));
            }
        }
        if let Some(reason) = confusable_types(self) {
            return Err(c.fail("part_types", reason));
        }
        c.in_range(
            "parts.max_roundness_mm",
            self.parts.max_roundness_mm,
            0.0,
            5.0,
        )?;
        c.in_range(
            "parts.max_lateral_offset_m",
            self.parts.max_lateral_offset_m,
            0.0,
            1.0,
        )?;
        Ok(())
    }

    fn validate_bottle(&self, c: &Checker) -> Result<(), ScenarioError> {
        let bottle = &self.bottle;
        c.positive_up_to("bottle.radius_m", bottle.radius_m, 0.2)?;
        c.positive_up_to("bottle.height_m", bottle.height_m, 0.5)?;
        c.positive_up_to("bottle.mass_kg", bottle.mass_kg, 5.0)?;
        c.in_range("bottle.lying_fraction", bottle.lying_fraction, 0.0, 1.0)?;
        let [near, far] = bottle.distance_range_m;
        if !(near.is_finite() && far.is_finite() && 0.0 < near && near <= far && far <= 2.0) {
            return Err(c.fail(
                "bottle.distance_range_m",
                format!("must be [near, far] with 0 < near <= far <= 2 m, got {near}, {far}"),
            ));
        }
        let [fewest, most] = bottle.count_range;
        if !(1 <= fewest && fewest <= most && most <= MAX_BOTTLES) {
            return Err(c.fail(
                "bottle.count_range",
                format!(
                    "must be [fewest, most] with 1 <= fewest <= most <= {MAX_BOTTLES}, got \
                     {fewest}, {most}"
                ),
            ));
        }
        if let Some([least, most]) = bottle.near_gap_range_m
            && !(least.is_finite()
                && most.is_finite()
                && 0.0 <= least
                && least <= most
                && most <= 0.5)
        {
            return Err(c.fail(
                "bottle.near_gap_range_m",
                format!(
                    "must be [least, most] with 0 <= least <= most <= 0.5 m, got {least}, {most}"
                ),
            ));
        }
        if !(1 <= bottle.near_count && bottle.near_count <= fewest) {
            return Err(c.fail(
                "bottle.near_count",
                format!(
                    "must lie in [1, {fewest}] (bottle.count_range's fewest), got {}",
                    bottle.near_count
                ),
            ));
        }
        Ok(())
    }

    fn validate_bins(&self, c: &Checker, arm: &ArmModel) -> Result<(), ScenarioError> {
        let mut names = BTreeSet::new();
        let known: BTreeSet<&str> = self.part_types.iter().map(|p| p.name.as_str()).collect();
        let rejects = self.bins.iter().filter(|b| b.reject).count();
        if rejects != 1 {
            return Err(c.fail(
                "bins",
                format!("needs exactly one reject bin, got {rejects}"),
            ));
        }
        let ik = AnalyticIk::new(arm.clone()).map_err(|e| c.fail("robot.urdf", e.to_string()))?;
        let tallest_m = self
            .part_types
            .iter()
            .map(|p| p.height_mm / 1000.0)
            .fold(0.0, f64::max);
        for (flag, count) in [
            ("waste", self.bins.iter().filter(|b| b.waste).count()),
            (
                "collector",
                self.bins.iter().filter(|b| b.collector).count(),
            ),
        ] {
            if count > 1 {
                return Err(c.fail("bins", format!("at most one {flag} bin, got {count}")));
            }
        }
        for (i, bin) in self.bins.iter().enumerate() {
            let key = |field: &str| format!("bins[{i}].{field}");
            let roles = [bin.reject, bin.waste, bin.collector];
            if roles.iter().filter(|r| **r).count() > 1 {
                return Err(c.fail(
                    key("waste"),
                    "a bin is at most one of reject, waste and collector",
                ));
            }
            if (bin.waste || bin.collector) && !bin.accepts.is_empty() {
                return Err(c.fail(key("accepts"), "a waste bin or collector accepts no type"));
            }
            if bin.name.trim().is_empty() || !names.insert(bin.name.as_str()) {
                return Err(c.fail(key("name"), "must be a unique, non-empty name"));
            }
            c.point_within(
                &key("floor_center_m"),
                &bin.floor_center_m,
                MAX_CELL_REACH_M,
            )?;
            c.positive_up_to(&key("size_m[0]"), bin.size_m[0], 2.0)?;
            c.positive_up_to(&key("size_m[1]"), bin.size_m[1], 2.0)?;
            c.positive_up_to(&key("wall_height_m"), bin.wall_height_m, 1.0)?;
            if bin.reject && !bin.accepts.is_empty() {
                return Err(c.fail(key("accepts"), "the reject bin accepts no type"));
            }
            if let Some(unknown) = bin.accepts.iter().find(|t| !known.contains(t.as_str())) {
                return Err(c.fail(
                    key("accepts"),
                    format!("names unknown part type `{unknown}`"),
                ));
            }
            if bin.collector {
                // Under the belt's end, out of the arm's way: no place pose to reach.
                self.validate_collector(c, &key, bin)?;
                continue;
            }
            // The place pose: gripper pointing down, the tallest part's bottom 2 cm above the rim.
            let base = self.robot.base_xyz_m;
            let tcp_z = bin.floor_center_m[2] + bin.wall_height_m + 0.02 + tallest_m;
            let place = Isometry3::from_parts(
                Translation3::new(
                    bin.floor_center_m[0] - base[0],
                    bin.floor_center_m[1] - base[1],
                    tcp_z - base[2],
                ),
                UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0),
            );
            if ik.solve(&place).is_empty() {
                return Err(c.fail(
                    key("floor_center_m"),
                    "bin is out of the arm's reach (no IK solution for placing a part in it)",
                ));
            }
        }
        for part in &self.part_types {
            let count = self
                .bins
                .iter()
                .filter(|b| b.accepts.contains(&part.name))
                .count();
            if count != 1 {
                return Err(c.fail(
                    "bins",
                    format!(
                        "part type `{}` must be accepted by exactly one bin, found {count}",
                        part.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// A collector must catch what runs off the belt's downstream (+x) end: its opening starts
    /// at most 20 mm past the end and reaches 100 mm beyond it, spans the belt's width, and its
    /// rim lies at least 20 mm below the belt's top.
    fn validate_collector(
        &self,
        c: &Checker,
        key: &dyn Fn(&str) -> String,
        bin: &super::Bin,
    ) -> Result<(), ScenarioError> {
        let belt = &self.conveyor;
        let end_x = belt.belt_center_m[0] + belt.length_m / 2.0;
        let [cx, cy, floor_z] = bin.floor_center_m;
        let (near_x, far_x) = (cx - bin.size_m[0] / 2.0, cx + bin.size_m[0] / 2.0);
        if near_x > end_x + 0.02 || far_x < end_x + 0.1 {
            return Err(c.fail(
                key("floor_center_m"),
                format!(
                    "a collector must sit at the belt's downstream end: its opening spans x = \
                     {near_x:.3}..{far_x:.3} m, the belt ends at x = {end_x:.3} m (the opening \
                     must start within 20 mm past the end and reach 100 mm beyond it)"
                ),
            ));
        }
        let half_width = belt.width_m / 2.0;
        let (belt_y, half_y) = (belt.belt_center_m[1], bin.size_m[1] / 2.0);
        if cy - half_y > belt_y - half_width || cy + half_y < belt_y + half_width {
            return Err(c.fail(
                key("size_m[1]"),
                "a collector's opening must span the belt's whole width",
            ));
        }
        if floor_z + bin.wall_height_m > belt.belt_center_m[2] - 0.02 {
            return Err(c.fail(
                key("floor_center_m[2]"),
                "a collector's rim must lie at least 20 mm below the belt's top",
            ));
        }
        Ok(())
    }
}
