//! The phases of a trial and the simulated seconds spent in each: one list, in the order
//! records write them, from which names, successors and per-phase seconds all follow.

use std::fmt;

use serde::de::{MapAccess, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// What the cell is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Phase {
    /// The belt runs until something breaks the photo-eye's beam, then stops and settles.
    Wait,
    /// The camera (or the oracle) looks at the pick station.
    Perceive,
    /// Grasp and place are searched for and collision-checked.
    Plan,
    /// Jaws open, the arm moves above the part.
    Approach,
    /// Straight down around the part.
    Descend,
    /// The jaws close with the part type's force until they stop on it.
    Grasp,
    /// Straight up with the part.
    Lift,
    /// Over to the bin, carrying.
    Transport,
    /// Down into the bin's slot.
    Place,
    /// Jaws open over the placed part.
    Release,
    /// Up and home.
    Retreat,
    /// The belt runs a bottle through the station (a stream lets bottles pass).
    Pass,
}

/// Number of phases.
pub const PHASE_COUNT: usize = 12;

impl Phase {
    /// Every phase, in the order records list them: waiting, the pick cycle, passing.
    pub const ALL: [Phase; PHASE_COUNT] = [
        Phase::Wait,
        Phase::Perceive,
        Phase::Plan,
        Phase::Approach,
        Phase::Descend,
        Phase::Grasp,
        Phase::Lift,
        Phase::Transport,
        Phase::Place,
        Phase::Release,
        Phase::Retreat,
        Phase::Pass,
    ];

    /// The pick cycle, in order: from a stopped belt to the arm back home (every phase but
    /// waiting and passing).
    pub const PICK_CYCLE: [Phase; PHASE_COUNT - 2] = {
        let mut cycle = [Phase::Wait; PHASE_COUNT - 2];
        let mut i = 0;
        while i < cycle.len() {
            cycle[i] = Phase::ALL[i + 1];
            i += 1;
        }
        cycle
    };

    const NAMES: [&'static str; PHASE_COUNT] = [
        "wait",
        "perceive",
        "plan",
        "approach",
        "descend",
        "grasp",
        "lift",
        "transport",
        "place",
        "release",
        "retreat",
        "pass",
    ];

    /// The phase's place in [`Phase::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The phase's name in records, logs and recordings.
    pub fn as_str(self) -> &'static str {
        Self::NAMES[self.index()]
    }

    /// The phase named `name`, if any.
    pub fn from_name(name: &str) -> Option<Phase> {
        Self::NAMES
            .iter()
            .position(|n| *n == name)
            .map(|i| Self::ALL[i])
    }

    /// The phase after this one when it succeeds: along the pick cycle, back to waiting after
    /// the retreat or a bottle's pass.
    pub fn next(self) -> Phase {
        match self {
            Self::Wait => Self::PICK_CYCLE[0],
            Self::Retreat | Self::Pass => Self::Wait,
            _ => {
                let at = Self::PICK_CYCLE.iter().position(|p| *p == self);
                at.and_then(|i| Self::PICK_CYCLE.get(i + 1).copied())
                    .unwrap_or(Self::Wait)
            }
        }
    }

    /// Whether the part is in the jaws, so that the hold monitor watches it.
    pub fn holds_part(self) -> bool {
        matches!(self, Self::Lift | Self::Transport | Self::Place)
    }
}

impl fmt::Display for Phase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for Phase {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for Phase {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        Phase::from_name(&name)
            .ok_or_else(|| serde::de::Error::custom(format!("unknown phase `{name}`")))
    }
}

/// Simulated seconds spent in each phase of a trial; written as an object keyed by the phases'
/// names, in [`Phase::ALL`]'s order.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseSeconds([f64; PHASE_COUNT]);

impl PhaseSeconds {
    /// Every phase with its seconds, in [`Phase::ALL`]'s order.
    pub fn iter(&self) -> impl Iterator<Item = (Phase, f64)> + '_ {
        Phase::ALL.iter().map(|p| (*p, self.0[p.index()]))
    }
}

impl std::ops::Index<Phase> for PhaseSeconds {
    type Output = f64;

    fn index(&self, phase: Phase) -> &f64 {
        &self.0[phase.index()]
    }
}

impl std::ops::IndexMut<Phase> for PhaseSeconds {
    fn index_mut(&mut self, phase: Phase) -> &mut f64 {
        &mut self.0[phase.index()]
    }
}

impl Serialize for PhaseSeconds {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(PHASE_COUNT))?;
        for (phase, seconds) in self.iter() {
            map.serialize_entry(phase.as_str(), &seconds)?;
        }
        map.end()
    }
}

impl<'de> Deserialize<'de> for PhaseSeconds {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct SecondsVisitor;

        impl<'de> Visitor<'de> for SecondsVisitor {
            type Value = PhaseSeconds;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("seconds keyed by phase name")
            }

            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<PhaseSeconds, A::Error> {
                let mut seconds = PhaseSeconds::default();
                while let Some((name, value)) = map.next_entry::<String, f64>()? {
                    let phase = Phase::from_name(&name).ok_or_else(|| {
                        serde::de::Error::custom(format!("unknown phase `{name}`"))
                    })?;
                    seconds[phase] = value;
                }
                Ok(seconds)
            }
        }

        deserializer.deserialize_map(SecondsVisitor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pick_cycle_follows_next_and_returns_to_waiting() {
        let mut phase = Phase::Wait;
        let mut seen = Vec::new();
        for _ in 0..Phase::PICK_CYCLE.len() {
            phase = phase.next();
            seen.push(phase);
        }
        assert_eq!(seen, Phase::PICK_CYCLE);
        assert_eq!(Phase::Retreat.next(), Phase::Wait);
        assert_eq!(Phase::Pass.next(), Phase::Wait);
    }

    #[test]
    fn all_lists_each_phase_at_its_index_with_a_distinct_name() {
        for (i, phase) in Phase::ALL.iter().enumerate() {
            assert_eq!(phase.index(), i);
            assert_eq!(Phase::from_name(phase.as_str()), Some(*phase));
        }
        let mut names: Vec<&str> = Phase::ALL.iter().map(|p| p.as_str()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), PHASE_COUNT);
    }

    #[test]
    fn seconds_are_keyed_by_phase_and_written_by_name_in_order() {
        let mut seconds = PhaseSeconds::default();
        for (k, phase) in Phase::ALL.iter().enumerate() {
            seconds[*phase] += k as f64 + 0.5;
        }
        let json = serde_json::to_string(&seconds).expect("serializes");
        assert!(
            json.starts_with("{\"wait\":0.5,\"perceive\":1.5,"),
            "{json}"
        );
        assert!(json.ends_with("\"pass\":11.5}"), "{json}");
        let back: PhaseSeconds = serde_json::from_str(&json).expect("reads back");
        assert_eq!(back, seconds);
        assert!(serde_json::from_str::<PhaseSeconds>("{\"nap\":1.0}").is_err());
    }

    #[test]
    fn only_the_carrying_phases_watch_the_hold() {
        let holding: Vec<Phase> = Phase::ALL.into_iter().filter(|p| p.holds_part()).collect();
        assert_eq!(holding, [Phase::Lift, Phase::Transport, Phase::Place]);
    }
}
