//! Items tracked along the belt. Each item the camera sees gets an identity (a [`TrackId`]) and a
//! belt position: the encoder's count at the look and the item's place on the belt then. The
//! position is carried forward by the encoder as the belt moves, never by the truth. A new
//! look's sightings join the open tracks by predicted position, one to one (the assignment of
//! least total distance) and only within a gate; a sighting that joins none opens a track, a
//! track missed by too many looks in a row is lost, and one whose prediction has run out of view
//! downstream closes. The module knows nothing of cameras or worlds: sightings come in belt
//! coordinates, so the moving-belt pick can track by the same rules.

/// What an item is seen as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ItemKind {
    /// An axle part.
    Part,
    /// A foreign object (a bottle).
    Bottle,
}

impl ItemKind {
    /// The kind's name as records write it.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Part => "part",
            Self::Bottle => "bottle",
        }
    }
}

/// A track's identity: unique in its [`TrackSet`], from 0 in the order tracks open.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TrackId(pub u32);

/// A place on the belt's top: along the belt's travel from the station (the photo-eye's beam on
/// the centre line; downstream positive) and across it from the centre line, m.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BeltPoint {
    /// Along the travel, m.
    pub along_m: f64,
    /// Across the belt, m.
    pub across_m: f64,
}

impl BeltPoint {
    /// Distance to `other` on the belt, m.
    pub fn distance_m(&self, other: &BeltPoint) -> f64 {
        (self.along_m - other.along_m).hypot(self.across_m - other.across_m)
    }
}

/// One item in one look: what it was seen as, how sure the detector was, and where it stood.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ItemSighting {
    /// What the item was seen as.
    pub kind: ItemKind,
    /// The detector's confidence, 0..1: the weight of this sighting's vote on the track's kind.
    pub score: f64,
    /// Its footprint's centre on the belt.
    pub at: BeltPoint,
    /// Half its footprint's length along the belt, m (from its box, so a tall item's is long).
    pub half_length_m: f64,
}

/// The stretch of belt the camera sees, along the travel, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewSpan {
    /// Upstream end, m.
    pub from_m: f64,
    /// Downstream end, m.
    pub to_m: f64,
}

impl ViewSpan {
    /// Whether `along_m` lies within the span.
    pub fn contains(&self, along_m: f64) -> bool {
        (self.from_m..=self.to_m).contains(&along_m)
    }
}

/// How tracks are kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerParams {
    /// Belt travel per encoder count, m.
    pub m_per_count: f64,
    /// The farthest a sighting may lie from a track's predicted position and still join it, m.
    pub gate_m: f64,
    /// Looks in a row that may miss a track in view before it is counted lost.
    pub max_missed_looks: u32,
}

/// How a track ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackEnd {
    /// Its prediction ran out of view downstream: the belt carried it on.
    LeftView,
    /// Missed by more looks in a row than allowed while in view (a false sighting, or an item
    /// gone from the belt without the cell's knowing).
    Lost,
    /// The robot took it off the belt.
    Picked,
}

/// One tracked item.
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Its identity.
    pub id: TrackId,
    /// The encoder's count at its last sighting.
    pub seen_count: i64,
    /// Where it stood at its last sighting.
    pub seen_at: BeltPoint,
    /// Half its footprint's length along the belt at its last sighting, m.
    pub half_length_m: f64,
    /// The looks that saw it.
    pub looks: u32,
    /// Looks in a row since then that had it in view and missed it.
    pub missed: u32,
    /// Sum of the detector's confidence over the sightings that saw a part, and a bottle.
    votes: [f64; 2],
    /// What its latest sighting saw (the tie-break of the votes).
    latest: ItemKind,
    /// How it ended; `None` while open.
    pub end: Option<TrackEnd>,
}

impl Track {
    /// What the item is, by its sightings' votes weighted by the detector's confidence (one
    /// look that took a part at the frame's edge for a bottle does not outvote two that saw a
    /// part).
    pub fn kind(&self) -> ItemKind {
        let [part, bottle] = self.votes;
        if part > bottle {
            ItemKind::Part
        } else if bottle > part {
            ItemKind::Bottle
        } else {
            self.latest
        }
    }

    /// Where the encoder says the item stands now, at count `count`.
    pub fn predicted(&self, count: i64, m_per_count: f64) -> BeltPoint {
        BeltPoint {
            along_m: self.seen_at.along_m + (count - self.seen_count) as f64 * m_per_count,
            across_m: self.seen_at.across_m,
        }
    }

    /// How far its predicted footprint lies from the line `along_m` across the belt at count
    /// `count`, m (0 when the footprint spans it).
    pub fn distance_along_m(&self, count: i64, m_per_count: f64, along_m: f64) -> f64 {
        let centre = self.predicted(count, m_per_count).along_m;
        ((centre - along_m).abs() - self.half_length_m).max(0.0)
    }

    /// Whether it is still open.
    pub fn is_open(&self) -> bool {
        self.end.is_none()
    }

    fn vote(&mut self, sighting: &ItemSighting) {
        let slot = match sighting.kind {
            ItemKind::Part => 0,
            ItemKind::Bottle => 1,
        };
        self.votes[slot] += sighting.score.max(0.0);
        self.latest = sighting.kind;
    }
}

/// A trial's tracks, open and closed, in the order they opened.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackSet {
    params: TrackerParams,
    tracks: Vec<Track>,
}

impl TrackSet {
    /// No tracks yet.
    pub fn new(params: TrackerParams) -> Self {
        Self {
            params,
            tracks: Vec::new(),
        }
    }

    /// How tracks are kept.
    pub fn params(&self) -> &TrackerParams {
        &self.params
    }

    /// Every track, in the order they opened.
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// The track `id`.
    pub fn track(&self, id: TrackId) -> Option<&Track> {
        self.tracks.get(id.0 as usize)
    }

    /// Where track `id` stands at encoder count `count`.
    pub fn predicted(&self, id: TrackId, count: i64) -> Option<BeltPoint> {
        self.track(id)
            .map(|t| t.predicted(count, self.params.m_per_count))
    }

    /// Ends track `id` (no effect on one already ended).
    pub fn close(&mut self, id: TrackId, end: TrackEnd) {
        if let Some(track) = self.tracks.get_mut(id.0 as usize) {
            track.end.get_or_insert(end);
        }
    }

    /// The open track predicted nearest `point` at count `count`, when one lies within the gate.
    pub fn nearest_open(&self, count: i64, point: &BeltPoint) -> Option<TrackId> {
        let m = self.params.m_per_count;
        self.tracks
            .iter()
            .filter(|t| t.is_open())
            .map(|t| (t.predicted(count, m).distance_m(point), t.id))
            .filter(|(d, _)| *d <= self.params.gate_m)
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, id)| id)
    }

    /// One look at count `count` that saw `sightings` over the stretch `view`: closes the tracks
    /// predicted past the view's downstream end, joins each sighting to an open track or opens
    /// one, and counts a miss against every open track in view (clear of its edges by the gate)
    /// that no sighting joined. Returns each sighting's track.
    pub fn update(
        &mut self,
        count: i64,
        sightings: &[ItemSighting],
        view: &ViewSpan,
    ) -> Vec<TrackId> {
        let params = self.params;
        for track in self.tracks.iter_mut().filter(|t| t.end.is_none()) {
            if track.predicted(count, params.m_per_count).along_m > view.to_m + params.gate_m {
                track.end = Some(TrackEnd::LeftView);
            }
        }
        let candidates: Vec<usize> = (0..self.tracks.len())
            .filter(|&i| self.tracks[i].is_open())
            .collect();
        let cost: Vec<Vec<Option<f64>>> = sightings
            .iter()
            .map(|s| {
                candidates
                    .iter()
                    .map(|&i| {
                        let d = self.tracks[i]
                            .predicted(count, params.m_per_count)
                            .distance_m(&s.at);
                        (d <= params.gate_m).then_some(d)
                    })
                    .collect()
            })
            .collect();
        let assigned = assign(&cost, params.gate_m);
        let mut joined = vec![false; candidates.len()];
        let mut ids = Vec::with_capacity(sightings.len());
        for (sighting, column) in sightings.iter().zip(assigned) {
            let index = match column {
                Some(c) => {
                    joined[c] = true;
                    candidates[c]
                }
                None => {
                    let id = TrackId(u32::try_from(self.tracks.len()).unwrap_or(u32::MAX));
                    self.tracks.push(Track {
                        id,
                        seen_count: count,
                        seen_at: sighting.at,
                        half_length_m: sighting.half_length_m,
                        looks: 0,
                        missed: 0,
                        votes: [0.0; 2],
                        latest: sighting.kind,
                        end: None,
                    });
                    self.tracks.len() - 1
                }
            };
            let track = &mut self.tracks[index];
            track.seen_count = count;
            track.seen_at = sighting.at;
            track.half_length_m = sighting.half_length_m;
            track.looks += 1;
            track.missed = 0;
            track.vote(sighting);
            ids.push(track.id);
        }
        for (c, &i) in candidates.iter().enumerate() {
            let track = &mut self.tracks[i];
            // Within the gate of the view's edge the item may lie just outside it: no miss.
            let along_m = track.predicted(count, params.m_per_count).along_m;
            let in_view =
                (view.from_m + params.gate_m..=view.to_m - params.gate_m).contains(&along_m);
            if joined[c] || !in_view {
                continue;
            }
            track.missed += 1;
            if track.missed > params.max_missed_looks {
                track.end = Some(TrackEnd::Lost);
            }
        }
        ids
    }
}

/// The one-to-one assignment of rows (sightings) to columns (tracks) of least total cost, where
/// `cost[r][c]` is `None` for a pair outside the gate and leaving a row or a column unassigned
/// costs `unassigned`. Returns each row's column. The Hungarian method on the square problem
/// that adds a "none" column per row and a "none" row per column.
pub fn assign(cost: &[Vec<Option<f64>>], unassigned: f64) -> Vec<Option<usize>> {
    let rows = cost.len();
    let cols = cost.first().map_or(0, Vec::len);
    let n = rows + cols;
    if rows == 0 {
        return Vec::new();
    }
    // A forbidden pair costs more than leaving every row and column alone.
    let forbidden = unassigned * (n as f64 + 1.0) * 4.0 + 1.0;
    let at = |r: usize, c: usize| -> f64 {
        match (r < rows, c < cols) {
            (true, true) => cost[r].get(c).copied().flatten().unwrap_or(forbidden),
            // Row r left unassigned: its own "none" column only.
            (true, false) => {
                if c - cols == r {
                    unassigned
                } else {
                    forbidden
                }
            }
            // Column c left unassigned: its own "none" row only.
            (false, true) => {
                if r - rows == c {
                    unassigned
                } else {
                    forbidden
                }
            }
            (false, false) => 0.0,
        }
    };
    // Potentials and matching over 1-based indices, column 0 the free start.
    let mut u = vec![0.0f64; n + 1];
    let mut v = vec![0.0f64; n + 1];
    let mut row_of = vec![0usize; n + 1];
    let mut way = vec![0usize; n + 1];
    for r in 1..=n {
        row_of[0] = r;
        let mut c0 = 0;
        let mut min_v = vec![f64::INFINITY; n + 1];
        let mut used = vec![false; n + 1];
        loop {
            used[c0] = true;
            let r0 = row_of[c0];
            let mut delta = f64::INFINITY;
            let mut c1 = 0;
            for c in 1..=n {
                if used[c] {
                    continue;
                }
                let reduced = at(r0 - 1, c - 1) - u[r0] - v[c];
                if reduced < min_v[c] {
                    min_v[c] = reduced;
                    way[c] = c0;
                }
                if min_v[c] < delta {
                    delta = min_v[c];
                    c1 = c;
                }
            }
            for c in 0..=n {
                if used[c] {
                    u[row_of[c]] += delta;
                    v[c] -= delta;
                } else {
                    min_v[c] -= delta;
                }
            }
            c0 = c1;
            if row_of[c0] == 0 {
                break;
            }
        }
        loop {
            let c1 = way[c0];
            row_of[c0] = row_of[c1];
            c0 = c1;
            if c0 == 0 {
                break;
            }
        }
    }
    let mut column = vec![None; rows];
    for (c, &r) in row_of.iter().enumerate().take(cols + 1).skip(1) {
        if (1..=rows).contains(&r) && cost[r - 1].get(c - 1).copied().flatten().is_some() {
            column[r - 1] = Some(c - 1);
        }
    }
    column
}

#[cfg(test)]
#[path = "tracks_tests.rs"]
mod tests;
