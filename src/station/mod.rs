//! The perception station: what the cell knows of the pick station, and how it comes to know
//! it. The camera adapter renders the sensor's frame, runs the detector and measures the bores
//! (`CameraPerception`, its `Sighting`); the bottle fit finds a bottle's pose from its outline,
//! and the lying-part finder a tube fallen on its side; and `Percept` is what the planner is
//! told: the part's type, place and bore, and the obstacles near it; on a belt, the tracks that keep each item's identity and belt position
//! from look to look (`TrackSet`). Everything here reads images and calibrations, never the
//! world.

mod area_of_interest;
pub mod belt_frame;
mod bore_floor;
mod bottle_evidence;
pub mod bottle_fit;
mod bottle_merge;
mod bottle_outline;
mod bottle_unboxed;
pub mod camera_percept;
mod frame_check;
mod measured_tube;
pub mod lying_part;
pub mod metrology_study;
mod percept;
mod sighting_percept;
pub mod tracks;
mod silhouette;
pub mod type_reader;

pub use belt_frame::{BeltFrame, SeenItem, TubeEnvelope};
pub use bore_floor::{imaged_radius_px, station_bore_params};
pub use bottle_evidence::{Evidence, MIN_SUPPORT, bottle_sightings};
pub use bottle_fit::{BottleFitter, BottlePose};
pub use bottle_unboxed::BeltBand;
pub use camera_percept::{
    BottleSighting, CameraPerception, CameraPerceptionError, PartSighting, Sighting, StationItem,
    TargetRule, find_in_window, measure_found, measure_in_window, part_window,
};
pub use frame_check::{BLANK_LEVEL, black_frame, frame_is_blank};
pub use lying_part::{LyingPart, LyingPartFinder, TubeSize};
pub use measured_tube::{BeltScene, MeasuredTube};
pub use metrology_study::{ErrorSummary, KnownPart, MetrologyStudy, ShotErrors, StudySummary};
pub use percept::{PerceivedObstacle, Percept, bottle_obstacle, part_obstacle};
pub use sighting_percept::{
    NEIGHBOURHOOD_M, StationModel, Surroundings, cut_neighbour_travel_m, surroundings_travel_m,
};
pub use silhouette::{Silhouette, box_residual_px};
pub use tracks::{
    BeltPoint, ItemKind, ItemSighting, Track, TrackEnd, TrackId, TrackSet, TrackerParams, ViewSpan,
};
pub use type_reader::{TypeDecision, TypeReader};
