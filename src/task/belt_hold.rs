//! Holding a tracking stream's belt (`conveyor.tracking`), as a line-tracking cell's conveyor
//! stop does: the belt runs while the arm can make its window, and is stopped only when a part
//! queued would otherwise ride out of it unpicked.
//!
//! Each part latched gets its **standing limit** (`Sorter::standing_limit`): the last place in
//! the pick window at which the arm can pick it from a stopped belt and place it. While the arm
//! is busy off the belt (carrying, placing, coming back), each tick checks the parts queued:
//! one whose belt, stopped now, would bring it to a stand within [`HOLD_BACKOFF_M`] of its limit
//! (its braking included) holds the belt. When the arm is free it picks a part standing on a
//! held belt (the one furthest along that it can pick there), and the belt runs again once the
//! part is lifted off it. With the belt running, the arm goes for the earliest part it can meet
//! moving, unless following that part to the lift's end would carry another past its limit:
//! then, as when no part can be met moving, the belt is held at once and the part furthest
//! along is picked standing. The arm never follows a part while the belt is held or braking:
//! no hold is made from the moment a moving meet is chosen to the end of its lift.
//!
//! Every hold is logged with its part and its time, and counted in the part's record.

use super::belt_follow::{EyeWatch, Latched};
use super::cell_data::CellData;
use super::sorter::Sorter;
use super::tracking_plan::Meet;
use crate::cell::CellModel;
use crate::control::BELT_ACCEL_M_S2;
use crate::outcome::Failure;
use crate::station::TargetRule;

/// A belt is held when a part would come to a stand within this distance of its standing
/// limit (upstream of it), m: clear of the reach's edge, where the arm stands near a limit.
pub(super) const HOLD_BACKOFF_M: f64 = 0.05;
/// A part that could not be picked where a hold stood it short of its limit is held again
/// this close to the limit (a place the limit's walk found pickable), m.
pub(super) const LAST_BACKOFF_M: f64 = 0.004;
/// Allowance past the braking distance for the ticks before the brake acts and the encoder's
/// count, m.
const HOLD_MARGIN_M: f64 = 0.005;

/// One hold of the belt.
struct Hold {
    /// The part held for, by registry index.
    part: usize,
    from_s: f64,
    /// When the belt was told to run again (`None`: still held).
    to_s: Option<f64>,
}

/// The belt's holds over a tracking stream.
pub(super) struct BeltHold {
    /// Whether a hold may be made now: not while the arm follows a part on the moving belt.
    pub(super) armed: bool,
    /// Whether the belt is held (told to stop; it may still be braking).
    pub(super) held: bool,
    /// Whether the camera has looked at the belt since the hold stood it.
    pub(super) looked: bool,
    log: Vec<Hold>,
}

impl Default for BeltHold {
    fn default() -> Self {
        Self {
            armed: true,
            held: false,
            looked: false,
            log: Vec::new(),
        }
    }
}

/// The belt's travel from now to a stand if stopped now, with the margin, m.
fn stop_m(data: &CellData) -> f64 {
    let speed = f64::from(data.cell.conveyor.speed_m_s()).max(0.0);
    let dt = data.cell.world.params().dt_s;
    speed * speed / (2.0 * BELT_ACCEL_M_S2) + 2.0 * speed * dt + HOLD_MARGIN_M
}

impl BeltHold {
    /// Whether the belt, stopped now, still brings `item`'s part to a stand by its limit.
    pub(super) fn holdable(item: &Latched, data: &CellData) -> bool {
        item.limit_x
            .is_some_and(|limit| item.x_at(data.belt.encoder_counts()) + stop_m(data) <= limit)
    }

    /// Whether the belt must be stopped now for `item`'s part (holdable, and within the
    /// back-off of its limit once stood).
    fn due(item: &Latched, data: &CellData) -> bool {
        let stand = item.x_at(data.belt.encoder_counts()) + stop_m(data);
        item.limit_x
            .is_some_and(|limit| stand <= limit && stand >= limit - item.backoff_m)
    }

    /// Whether `item`'s part, holdable now, would be carried past where it can still be held
    /// within `after_s` at `speed_m_s`.
    fn would_pass(item: &Latched, data: &CellData, speed_m_s: f64, after_s: f64) -> bool {
        let stand = item.x_at(data.belt.encoder_counts()) + stop_m(data);
        item.limit_x
            .is_some_and(|limit| stand <= limit && stand + speed_m_s * after_s > limit)
    }

    /// Stops the belt for `part`.
    fn hold(&mut self, data: &mut CellData, part: usize) {
        data.belt.run_at(0.0);
        self.held = true;
        self.looked = false;
        self.log.push(Hold {
            part,
            from_s: data.cell.world.time_s(),
            to_s: None,
        });
    }

    /// Runs a held belt again at `speed_m_s`.
    pub(super) fn release(&mut self, data: &mut CellData, speed_m_s: f64) {
        if !self.held {
            return;
        }
        data.belt.run_at(speed_m_s);
        self.held = false;
        let now = data.cell.world.time_s();
        for hold in self.log.iter_mut().filter(|h| h.to_s.is_none()) {
            hold.to_s = Some(now);
        }
    }

    /// Holds made.
    pub(super) fn count(&self) -> u32 {
        u32::try_from(self.log.len()).unwrap_or(u32::MAX)
    }

    /// The holds made for `part` and how long they held the belt (up to `now_s` for one
    /// still held), s.
    pub(super) fn of_part(&self, part: usize, now_s: f64) -> (u32, f64) {
        self.log
            .iter()
            .filter(|h| h.part == part)
            .fold((0, 0.0), |(n, s), h| {
                (n + 1, s + h.to_s.unwrap_or(now_s) - h.from_s)
            })
    }

    /// Each tick: holds the belt when a part queued is due, while the arm is busy off it.
    pub(super) fn watch(&mut self, data: &mut CellData, parts: &[&Latched]) {
        if !self.armed || self.held {
            return;
        }
        if let Some(part) = parts.iter().find(|p| Self::due(p, data)).map(|p| p.part) {
            self.hold(data, part);
        }
    }
}

/// What the free arm does next.
pub(super) enum NextPick {
    /// Pick this part met so.
    Pick(Box<(Latched, Meet)>),
    /// These parts can be neither met nor held: they ride on.
    Pass(Vec<Latched>),
    /// Wait a tick (a held belt still braking).
    Tick,
    /// Choose again (the belt was held or let run).
    Again,
    /// The arm, parked over a bin, reaches no part from there: up clear of the bin first,
    /// and home when it reaches none from there either.
    Home,
}

impl Sorter<'_> {
    /// Looks at the belt once a hold has stood it, before the arm picks from it, and joins what
    /// is in view to the tracks: the arm's way down to a part near the window's start passes
    /// over the belt behind it, where items that have come into view since the last latch's
    /// look stand unseen (a tall part there was knocked over). The tracks then hold them as
    /// obstacles to the pick ([`super::tracking::BeltTracking::add_tracked_parts`]).
    pub(super) fn look_at_stand(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        hold: &mut BeltHold,
    ) -> Result<(), Failure> {
        if !hold.held || hold.looked || data.cell.conveyor.speed_m_s() > 0.0 {
            return Ok(());
        }
        hold.looked = true;
        let sighting = match self.camera {
            Some(camera) => Some((
                camera,
                self.look(model, data, camera, TargetRule::NearestStation)?,
            )),
            None => None,
        };
        if let Some(tracking) = self.tracking.as_mut() {
            match sighting {
                Some((camera, sighting)) => {
                    tracking.see_look(model, data, camera.rig(), &sighting);
                }
                None => {
                    tracking.see_truth(data);
                }
            }
        }
        Ok(())
    }

    /// The free arm's next move over the parts queued in `watch`, with the belt at
    /// `speed_m_s` when it runs: a pick (moving or standing), a hold, or parts let pass.
    pub(super) fn next_pick(
        &self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
        window: (f64, f64),
        speed_m_s: f64,
    ) -> NextPick {
        let started = std::time::Instant::now();
        let next = self.choose(model, data, watch, window, speed_m_s);
        data.timing.planning_ms += started.elapsed().as_secs_f64() * 1e3;
        next
    }

    fn choose(
        &self,
        model: &CellModel,
        data: &mut CellData,
        watch: &mut EyeWatch,
        window: (f64, f64),
        speed_m_s: f64,
    ) -> NextPick {
        let count = data.belt.encoder_counts();
        if watch.belt.held {
            if data.cell.conveyor.speed_m_s() > 0.0 {
                return NextPick::Tick;
            }
            // Stood: the part furthest along that can be picked here; one that cannot is
            // held no more.
            let mut order: Vec<usize> = (0..watch.parts.len()).collect();
            order.sort_by(|&a, &b| {
                let x = |i: usize| watch.parts[i].x_at(count);
                x(b).total_cmp(&x(a))
            });
            for &i in &order {
                if let Some(meet) = self.plan_standing(model, data, &watch.parts[i], window) {
                    let Some(item) = watch.parts.remove(i) else {
                        break;
                    };
                    return NextPick::Pick(Box::new((item, meet)));
                }
            }
            if watch.parked {
                return NextPick::Home;
            }
            // Held again at the limit itself, or no more.
            for i in order {
                let part = &mut watch.parts[i];
                let short = part
                    .limit_x
                    .is_some_and(|l| part.x_at(count) < l - LAST_BACKOFF_M);
                if short && part.backoff_m > LAST_BACKOFF_M {
                    part.backoff_m = LAST_BACKOFF_M;
                } else {
                    part.limit_x = None;
                }
            }
            watch.belt.release(data, speed_m_s);
            return NextPick::Again;
        }
        let mut met: Vec<(Latched, Option<Meet>)> = watch
            .parts
            .drain(..)
            .map(|item| {
                let meet = self.plan_intercept(model, data, &item, window, speed_m_s);
                (item, meet)
            })
            .collect();
        let first = met
            .iter()
            .enumerate()
            .filter_map(|(i, (_, m))| m.as_ref().map(|m| (i, m.lift_end_s)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let conflict = first.is_some_and(|(i, lift_end_s)| {
            met.iter().enumerate().any(|(j, (item, _))| {
                j != i && BeltHold::would_pass(item, data, speed_m_s, lift_end_s)
            })
        });
        if first.is_none() && watch.parked {
            watch.parts.extend(met.into_iter().map(|(item, _)| item));
            return NextPick::Home;
        }
        if first.is_none() || conflict {
            let furthest = met
                .iter()
                .filter(|(item, _)| BeltHold::holdable(item, data))
                .max_by(|a, b| a.0.x_at(count).total_cmp(&b.0.x_at(count)))
                .map(|(item, _)| item.part);
            if let Some(part) = furthest {
                watch.belt.hold(data, part);
                watch.parts.extend(met.into_iter().map(|(item, _)| item));
                return NextPick::Again;
            }
        }
        let chosen = first.map(|(i, _)| met.remove(i));
        let mut passed = Vec::new();
        for (item, meet) in met {
            if meet.is_some() || BeltHold::holdable(&item, data) {
                watch.parts.push_back(item);
            } else {
                passed.push(item);
            }
        }
        match chosen {
            Some((item, Some(meet))) if passed.is_empty() => NextPick::Pick(Box::new((item, meet))),
            Some((item, _)) => {
                watch.parts.push_front(item);
                NextPick::Pass(passed)
            }
            None => NextPick::Pass(passed),
        }
    }
}
