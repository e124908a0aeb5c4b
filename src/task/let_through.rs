//! Letting an unpickable part pass: when the planner finds no safe grasp before the arm has
//! moved, and the scenario declares a collector at the belt's end, the part is marked
//! unpickable and the belt carries it into the collector. The trial ends `passed`, not sorted.

use super::cell_data::CellData;
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::outcome::{Failure, FailureReason, PassedRecord, Phase, fail};
use crate::scenario::BinId;

/// Time the part gets to come to rest in the collector once it is inside, s.
const REST_S: f64 = 0.5;
/// Extra time beyond the belt travel to the end for the part to fall in, s.
const FALL_MARGIN_S: f64 = 3.0;

/// Planner refusals that make a part unpickable: no grasp clear of the obstacles, or none the
/// arm can reach. Anything else is a fault, not a judgement about the part.
pub(crate) fn is_refusal(reason: FailureReason) -> bool {
    matches!(
        reason,
        FailureReason::Collision | FailureReason::NoIkSolution | FailureReason::Unreachable
    )
}

impl Sorter<'_> {
    /// The part's cycle after its pick was refused: let through to the collector when the
    /// refusal came from planning (the arm still at home) in a single-part trial of a scenario
    /// with a collector. Returns the cycle's result and, when the part reached the collector,
    /// what passed it and the bottles' largest move before the belt carried them on, m.
    pub(crate) fn let_through_if_refused(
        &self,
        model: &CellModel,
        data: &mut CellData,
        result: Result<(), Failure>,
    ) -> (Result<(), Failure>, Option<(PassedRecord, f64)>) {
        let Err(refusal) = &result else {
            return (result, None);
        };
        let Some(collector) = model.catalogue().collector_bin() else {
            return (result, None);
        };
        if data.phase != Phase::Plan || !is_refusal(refusal.reason) || model.scenario().is_stream()
        {
            return (result, None);
        }
        let refusal = refusal.clone();
        let moved_m = data.bottle_displacement_m();
        match data.carry_to_collector(model, self.current, collector) {
            Ok(()) => {
                let passed = PassedRecord {
                    reason: refusal.reason,
                    detail: format!("unpickable: {}", refusal.detail),
                    collector: model.catalogue().bin_name(collector).to_owned(),
                };
                (Ok(()), Some((passed, moved_m)))
            }
            Err(failure) => (Err(failure), None),
        }
    }
}

impl CellData {
    /// Runs the belt, the arm holding at home, until part `part` rests in the collector; fails
    /// when it does not get there in the time the belt needs to carry it off the end and a
    /// margin for the fall.
    pub(crate) fn carry_to_collector(
        &mut self,
        model: &CellModel,
        part: usize,
        collector: BinId,
    ) -> Result<(), Failure> {
        let belt = &model.scenario().conveyor;
        self.phase = Phase::Pass;
        self.belt.run_at(belt.speed_m_s);
        let body = self.cell.items.parts()[part].body;
        let Some(start) = self.cell.body_pose(body) else {
            return fail(FailureReason::PhysicsBlowUp, "part body missing");
        };
        let end_x = belt.belt_center_m[0] + belt.length_m / 2.0;
        let travel_m = (end_x - start.translation.x).max(0.0);
        let limit_s = self.cell.world.time_s() + travel_m / belt.speed_m_s + FALL_MARGIN_S;
        let at = |data: &Self| {
            let at = data
                .cell
                .body_pose(body)
                .map(|p| p.translation.vector)
                .unwrap_or_default();
            format!("it is at x {:.3}, y {:.3}, z {:.3} m", at.x, at.y, at.z)
        };
        while self.bin_holding(part) != Some(collector) {
            if self.cell.world.time_s() > limit_s {
                return fail(
                    FailureReason::Dropped,
                    format!(
                        "let through as unpickable, the part did not reach the collector ({})",
                        at(self)
                    ),
                );
            }
            self.step(model)?;
        }
        self.settle(model, REST_S)?;
        self.belt.run_at(0.0);
        if self.bin_holding(part) != Some(collector) {
            return fail(
                FailureReason::Dropped,
                format!(
                    "let through as unpickable, the part bounced out of the collector ({})",
                    at(self)
                ),
            );
        }
        Ok(())
    }
}
