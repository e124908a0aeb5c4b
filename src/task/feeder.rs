//! The stream's feeder: parts and bottles in a seeded order, each put on the belt at the spawn
//! point once the belt has carried the previous one `stream.spacing_m`.

use nalgebra::Isometry3;

use crate::cell::{Cell, CellModel};
use crate::rng::SimRng;
use crate::scenario::Scenario;

/// What the feeder puts on the belt next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeedItem {
    /// An axle part of a type drawn from the catalogue.
    Part,
    /// A bottle, standing or lying.
    Bottle,
}

/// The items still to come and the belt travel since the last one went on.
#[derive(Debug, Clone)]
pub struct Feeder {
    /// Items still to come, taken from the end.
    queue: Vec<FeedItem>,
    travel_since_feed_m: f64,
    rng: SimRng,
}

impl Feeder {
    /// The feeder of `scenario`'s trial, drawing from `rng` (the trial's stream after the cell
    /// was built). A stream opens with its first part already on the belt; the rest follow in a
    /// seeded order. A single-part trial feeds nothing.
    pub fn new(scenario: &Scenario, mut rng: SimRng) -> Self {
        let mut queue = Vec::new();
        if scenario.is_stream() {
            queue.extend(std::iter::repeat_n(
                FeedItem::Part,
                scenario.parts_per_trial as usize - 1,
            ));
            queue.extend(std::iter::repeat_n(
                FeedItem::Bottle,
                scenario.stream.bottles as usize,
            ));
            for i in (1..queue.len()).rev() {
                let j = rng.below(i as u64 + 1) as usize;
                queue.swap(i, j);
            }
            queue.reverse();
        }
        Self {
            queue,
            travel_since_feed_m: 0.0,
            rng,
        }
    }

    /// The items still to come, next first.
    pub fn remaining(&self) -> impl Iterator<Item = FeedItem> + '_ {
        self.queue.iter().rev().copied()
    }

    /// The belt carried things `belt_travel_m` further: puts the next item on when the spacing
    /// is reached. A new bottle gets no rest pose in `bottle_rest` until the belt next stops.
    pub fn advance(
        &mut self,
        belt_travel_m: f64,
        model: &CellModel,
        cell: &mut Cell,
        bottle_rest: &mut Vec<Option<Isometry3<f64>>>,
    ) {
        if self.queue.is_empty() {
            return;
        }
        let scenario = model.scenario();
        self.travel_since_feed_m += belt_travel_m;
        if self.travel_since_feed_m < scenario.stream.spacing_m {
            return;
        }
        self.travel_since_feed_m -= scenario.stream.spacing_m;
        match self.queue.pop() {
            Some(FeedItem::Part) => {
                cell.spawn_part(model, &mut self.rng);
            }
            Some(FeedItem::Bottle) => {
                cell.spawn_bottle(scenario, &mut self.rng);
                bottle_rest.push(None);
            }
            None => {}
        }
    }
}
