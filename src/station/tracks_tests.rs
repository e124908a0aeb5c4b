//! The association's cases: neighbours a spacing apart, empty looks, a missed look, a false
//! sighting, the kind's vote, and the assignment against brute force.

use super::*;

const M_PER_COUNT: f64 = 0.000_032;

fn params(gate_m: f64) -> TrackerParams {
    TrackerParams {
        m_per_count: M_PER_COUNT,
        gate_m,
        max_missed_looks: 1,
    }
}

fn counts(travel_m: f64) -> i64 {
    (travel_m / M_PER_COUNT).round() as i64
}

fn seen(kind: ItemKind, along_m: f64, across_m: f64) -> ItemSighting {
    ItemSighting {
        kind,
        score: 0.9,
        at: BeltPoint { along_m, across_m },
        half_length_m: 0.02,
    }
}

const VIEW: ViewSpan = ViewSpan {
    from_m: -0.23,
    to_m: 0.23,
};

#[test]
fn two_items_a_spacing_apart_keep_their_identities_as_the_belt_carries_them_on() {
    // Between looks the belt carries each item to where the one ahead of it stood: only
    // the encoder's prediction tells them apart.
    let mut tracks = TrackSet::new(params(0.06));
    let first = tracks.update(
        0,
        &[
            seen(ItemKind::Part, 0.0, 0.02),
            seen(ItemKind::Bottle, -0.15, -0.03),
        ],
        &VIEW,
    );
    let second = tracks.update(
        counts(0.15),
        &[
            seen(ItemKind::Bottle, 0.002, -0.031),
            seen(ItemKind::Part, 0.151, 0.018),
            seen(ItemKind::Part, -0.149, 0.05),
        ],
        &VIEW,
    );
    assert_eq!(second[0], first[1], "the bottle keeps its track");
    assert_eq!(second[1], first[0], "the part keeps its track");
    assert_eq!(second[2], TrackId(2), "a new item opens a track");
    let part = tracks.track(first[0]).map(Track::kind);
    assert_eq!(part, Some(ItemKind::Part));
    // Carried out of view, the part's track closes; the others stay open.
    tracks.update(counts(0.45), &[seen(ItemKind::Part, 0.151, 0.05)], &VIEW);
    let ends: Vec<_> = tracks.tracks().iter().map(|t| t.end).collect();
    assert_eq!(
        ends,
        vec![Some(TrackEnd::LeftView), Some(TrackEnd::LeftView), None]
    );
}

#[test]
fn a_look_that_sees_nothing_opens_nothing_and_counts_a_miss_only_in_view() {
    let mut tracks = TrackSet::new(params(0.05));
    assert!(tracks.update(0, &[], &VIEW).is_empty());
    assert!(tracks.tracks().is_empty());
    let id = tracks.update(0, &[seen(ItemKind::Part, 0.1, 0.0)], &VIEW)[0];
    // Seen nowhere, still predicted in view: one miss is allowed, the second loses it.
    tracks.update(counts(0.05), &[], &VIEW);
    assert_eq!(tracks.track(id).map(|t| (t.missed, t.end)), Some((1, None)));
    tracks.update(counts(0.06), &[], &VIEW);
    assert_eq!(tracks.track(id).and_then(|t| t.end), Some(TrackEnd::Lost));
    // An item carried out of view is not missed: it left.
    let mut tracks = TrackSet::new(params(0.05));
    let id = tracks.update(0, &[seen(ItemKind::Bottle, 0.2, 0.0)], &VIEW)[0];
    tracks.update(counts(0.1), &[], &VIEW);
    assert_eq!(
        tracks.track(id).and_then(|t| t.end),
        Some(TrackEnd::LeftView)
    );
}

#[test]
fn a_missed_look_keeps_the_identity_and_a_false_sighting_is_lost_without_harm() {
    let mut tracks = TrackSet::new(params(0.05));
    let ids = tracks.update(
        0,
        &[
            seen(ItemKind::Part, -0.1, 0.0),
            seen(ItemKind::Part, -0.2, 0.04),
        ],
        &VIEW,
    );
    // The detector misses the first item and sees a reflection between them.
    let second = tracks.update(
        counts(0.05),
        &[
            seen(ItemKind::Part, -0.149, 0.041),
            seen(ItemKind::Bottle, -0.08, -0.1),
        ],
        &VIEW,
    );
    assert_eq!(second[0], ids[1]);
    let ghost = second[1];
    assert!(ghost != ids[0] && ghost != ids[1]);
    let third = tracks.update(
        counts(0.1),
        &[
            seen(ItemKind::Part, 0.0, 0.001),
            seen(ItemKind::Part, -0.099, 0.04),
        ],
        &VIEW,
    );
    assert_eq!(third, vec![ids[0], ids[1]], "the missed item keeps its id");
    tracks.update(
        counts(0.12),
        &[
            seen(ItemKind::Part, 0.02, 0.0),
            seen(ItemKind::Part, -0.08, 0.04),
        ],
        &VIEW,
    );
    assert_eq!(
        tracks.track(ghost).and_then(|t| t.end),
        Some(TrackEnd::Lost)
    );
    assert!(
        ids.iter()
            .all(|&id| tracks.track(id).is_some_and(Track::is_open))
    );
}

#[test]
fn the_kind_is_the_confidence_weighted_vote_of_the_sightings() {
    let mut tracks = TrackSet::new(params(0.05));
    let mut edge = seen(ItemKind::Bottle, -0.2, 0.0);
    edge.score = 0.45;
    let id = tracks.update(0, &[edge], &VIEW)[0];
    assert_eq!(tracks.track(id).map(Track::kind), Some(ItemKind::Bottle));
    tracks.update(counts(0.1), &[seen(ItemKind::Part, -0.1, 0.0)], &VIEW);
    assert_eq!(tracks.track(id).map(Track::kind), Some(ItemKind::Part));
    let nearest = tracks.nearest_open(counts(0.2), &BeltPoint::default());
    assert_eq!(nearest, Some(id));
    tracks.close(id, TrackEnd::Picked);
    assert_eq!(
        tracks.nearest_open(counts(0.2), &BeltPoint::default()),
        None
    );
}

/// Least total cost by trying every assignment (rows to distinct columns or to none).
fn brute_force(cost: &[Vec<Option<f64>>], unassigned: f64) -> f64 {
    fn go(r: usize, used: &mut Vec<bool>, cost: &[Vec<Option<f64>>], none: f64) -> f64 {
        if r == cost.len() {
            let free = used.iter().filter(|u| !**u).count();
            return free as f64 * none;
        }
        let mut best = none + go(r + 1, used, cost, none);
        for c in 0..used.len() {
            if let (false, Some(d)) = (used[c], cost[r][c]) {
                used[c] = true;
                best = best.min(d + go(r + 1, used, cost, none));
                used[c] = false;
            }
        }
        best
    }
    let cols = cost.first().map_or(0, Vec::len);
    go(0, &mut vec![false; cols], cost, unassigned)
}

#[test]
fn the_assignment_is_one_to_one_within_the_gate_and_of_least_total_cost() {
    let mut rng = crate::rng::SimRng::new(25);
    for _ in 0..400 {
        let rows = 1 + rng.below(6) as usize;
        let cols = rng.below(6) as usize;
        let gate = 0.05;
        let cost: Vec<Vec<Option<f64>>> = (0..rows)
            .map(|_| {
                (0..cols)
                    .map(|_| {
                        let d = rng.range(0.0, 0.08);
                        (d <= gate).then_some(d)
                    })
                    .collect()
            })
            .collect();
        let assigned = assign(&cost, gate);
        assert_eq!(assigned.len(), rows);
        let mut used = vec![false; cols];
        let mut total = 0.0;
        for (r, c) in assigned.iter().enumerate() {
            match c {
                Some(c) => {
                    assert!(!used[*c], "one to one");
                    used[*c] = true;
                    total += cost[r][*c].expect("within the gate");
                }
                None => total += gate,
            }
        }
        total += used.iter().filter(|u| !**u).count() as f64 * gate;
        let best = brute_force(&cost, gate);
        assert!((total - best).abs() < 1e-9, "{total} vs {best}: {cost:?}");
    }
}
