//! The task layer: one sorting trial as an explicit state machine ([`Phase`]) over the cell,
//! sequencing perception, planning and control each tick; the stream feeder; the oracle and
//! camera percept adapters; and the judging of outcomes against the truth.

mod at_eye;
mod belt_follow;
mod belt_hold;
mod cell_data;
mod fault_handling;
mod feeder;
mod grip_recovery;
pub mod judge;
mod let_through;
mod lying_repick;
mod motion_stages;
mod observer;
mod perceive;
mod phase;
mod pick_cycle;
mod removal;
mod runner;
mod sorter;
mod stream;
mod tracking;
mod tracking_plan;
mod tracking_stream;

pub use crate::outcome::Phase;
pub use crate::station::{CameraPerception, StationItem, TargetRule};
pub use cell_data::CellData;
pub use feeder::{FeedItem, Feeder};
pub use observer::{
    BoreView, CellView, DetectionView, PerceptionFrame, SAMPLE_RATE_HZ, TrialObserver,
    TrialObserverFactory,
};
pub use phase::PhaseDeadline;
pub use runner::{CellTrialRunner, RunnerError};
