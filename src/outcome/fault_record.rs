//! What a record says about a fault injected into its trial: the kind, when it struck, what
//! the controller did about it, whether the cell recovered, and the parts it cost.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// A kind of fault, named as a scenario's `[faults]` names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// The grip force fell some time after the jaws closed.
    Gripper,
    /// The camera delivered no frame, or black frames, for a while.
    Camera,
    /// The arm stopped mid-motion for a while.
    Arm,
    /// The belt ran slower than commanded, or stalled.
    Belt,
    /// The photo-eye triggered with nothing there, or missed an item.
    PhotoEye,
}

impl FaultKind {
    /// Every kind, in the order reports list them.
    pub const ALL: [FaultKind; 5] = [
        FaultKind::Gripper,
        FaultKind::Camera,
        FaultKind::Arm,
        FaultKind::Belt,
        FaultKind::PhotoEye,
    ];

    /// The kind's name in records and reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Gripper => "gripper",
            Self::Camera => "camera",
            Self::Arm => "arm",
            Self::Belt => "belt",
            Self::PhotoEye => "photo_eye",
        }
    }
}

/// One thing the controller did about a fault, from what its sensors showed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultAction {
    /// Saw a part fall from the jaws (the jaws closed further than the part is wide).
    SawDrop,
    /// Looked at the belt again and found the dropped part there.
    FoundOnBelt,
    /// Picked the part again.
    Repicked,
    /// Saw the jaws' force fall below what was commanded while they still held the part.
    SawWeakGrip,
    /// Opened and closed the jaws again on the part where it stood, which restores the force.
    Regripped,
    /// Carried the weakly held part back over the belt and set it down where it was grasped.
    SetDown,
    /// Saw the part lying on the belt (the pose is in the record's `saw_lying_part`).
    SawLyingPart,
    /// Picked the lying part by its body, square to its axis, and carried it to the bin decided
    /// while it stood (whether it got there is the record's `recovered`).
    RepickedLying,
    /// Found the dropped part neither in the jaws nor on the belt, and counted it lost.
    CountedLost,
    /// Asked the camera again after a wait, each wait longer than the last.
    RetriedCamera,
    /// Gave up on the camera after its last retry and let the item through.
    LetThrough,
    /// Waited out an arm stop with the servos holding.
    HeldThroughStop,
    /// Checked the rest of the interrupted motion for collisions again, and found it clear.
    RecheckedMotion,
    /// Found the rest of the interrupted motion no longer clear, and stopped the cycle.
    AbandonedMotion,
    /// Saw the belt's encoder fall behind the commanded travel.
    SawBeltShortfall,
    /// Kept feeding while the belt was behind, within the wait's time-out.
    WaitedForBelt,
    /// Gave up the feed at the wait's time-out, with the encoder's reason.
    TimedOutFeed,
    /// Looked at a trigger, saw nothing at the station, and ran the belt on.
    IgnoredFalseTrigger,
    /// Nothing: the fault struck where it did no harm.
    NoneNeeded,
}

/// A fault injected into a trial, and how the trial came through it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FaultRecord {
    /// The fault's kind.
    pub kind: FaultKind,
    /// Simulated time when it struck, s.
    pub at_s: f64,
    /// What it was, in words (its size and length, the phase it struck in).
    pub detail: String,
    /// What the controller did about it, in order.
    pub actions: Vec<FaultAction>,
    /// Whether the cell came through it: the item it struck was handled as it would have been
    /// without it (sorted, or for a bottle let through), later than it would have been at most.
    pub recovered: bool,
    /// Parts it cost: dropped off the belt and outside every bin, or run off the belt unseen.
    #[serde(default)]
    pub lost_parts: u32,
    /// A part seen lying on the belt after the fault, as perception fitted it (it is picked
    /// lying when the record's actions say `repicked_lying`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saw_lying_part: Option<LyingPartRecord>,
}

/// A tube perception saw lying on the belt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LyingPartRecord {
    /// The middle of its axis in the world, m.
    pub centre_m: [f64; 3],
    /// Its axis on the belt, from the world's x axis, in [0, 180), degrees.
    pub axis_yaw_deg: f64,
    /// Its length, mm.
    pub length_mm: f64,
    /// Its outer diameter, mm.
    pub diameter_mm: f64,
    /// The catalogue type its size matches best.
    pub part_type: String,
}

/// Per fault kind over a batch: faults injected, recovered from, and parts lost to them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FaultTally {
    /// Faults of the kind that struck.
    pub injected: u32,
    /// Of those, the ones the cell came through.
    pub recovered: u32,
    /// Parts lost to them.
    pub lost: u32,
}

impl FaultTally {
    /// The tally per kind of `faults`, only the kinds that struck.
    pub fn by_kind<'a>(
        faults: impl IntoIterator<Item = &'a FaultRecord>,
    ) -> BTreeMap<FaultKind, FaultTally> {
        let mut tally: BTreeMap<FaultKind, FaultTally> = BTreeMap::new();
        for fault in faults {
            let entry = tally.entry(fault.kind).or_default();
            entry.injected += 1;
            entry.recovered += u32::from(fault.recovered);
            entry.lost += fault.lost_parts;
        }
        tally
    }

    /// The share recovered, or `None` when none was injected.
    pub fn recovered_share(&self) -> Option<f64> {
        (self.injected > 0).then(|| f64::from(self.recovered) / f64::from(self.injected))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fault(kind: FaultKind, recovered: bool, lost_parts: u32) -> FaultRecord {
        FaultRecord {
            kind,
            at_s: 1.0,
            detail: String::new(),
            actions: vec![FaultAction::NoneNeeded],
            recovered,
            lost_parts,
            saw_lying_part: None,
        }
    }

    #[test]
    fn the_tally_counts_each_kind_apart() {
        let faults = [
            fault(FaultKind::Gripper, true, 0),
            fault(FaultKind::Gripper, false, 1),
            fault(FaultKind::Gripper, true, 0),
            fault(FaultKind::Belt, false, 0),
        ];
        let tally = FaultTally::by_kind(&faults);
        assert_eq!(tally.len(), 2);
        let grip = tally[&FaultKind::Gripper];
        assert_eq!((grip.injected, grip.recovered, grip.lost), (3, 2, 1));
        assert_eq!(grip.recovered_share(), Some(2.0 / 3.0));
        assert_eq!(tally[&FaultKind::Belt].recovered_share(), Some(0.0));
        assert_eq!(FaultTally::default().recovered_share(), None);
    }

    #[test]
    fn kinds_are_named_as_the_scenario_names_them() {
        for kind in FaultKind::ALL {
            let json = serde_json::to_string(&kind).expect("serialise");
            assert_eq!(json, format!("\"{}\"", kind.as_str()));
        }
        let record = fault(FaultKind::PhotoEye, true, 0);
        let json = serde_json::to_string(&record).expect("serialise");
        assert!(json.contains("\"kind\":\"photo_eye\"") && json.contains("\"none_needed\""));
        let back: FaultRecord = serde_json::from_str(&json).expect("parse");
        assert_eq!(back, record);
    }
}
