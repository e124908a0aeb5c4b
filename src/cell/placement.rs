//! Where a single-part trial's bottles go: near the part, on the belt, clear of the part and of
//! each other, with the gaps measured between true footprints (a standing bottle's disc, a lying
//! bottle's rectangle along its yaw), not between bounding discs.

use crate::rng::SimRng;
use crate::scenario::Scenario;
use crate::sim::BottlePlacement;

/// The least gap between a bottle placed by `bottle.distance_range_m` and the part, and between
/// any two bottles, m.
pub const CLEARANCE_M: f64 = 0.01;
/// Random draws per bottle before the deterministic search takes over.
const RANDOM_DRAWS: usize = 64;
/// Layouts drawn before a trial's bottles are declared to fit nowhere ([`place_bottles`]).
const LAYOUT_ATTEMPTS: usize = 16;
/// Angles around the part the deterministic search tries.
const SEARCH_ANGLES: usize = 72;
/// Yaws of a lying bottle the deterministic search tries over a half turn.
const SEARCH_YAWS: usize = 12;
/// Distances (or gaps) across the range the deterministic search tries.
const SEARCH_STEPS: usize = 9;

/// What an item covers of the belt, seen from above.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Footprint {
    /// A standing bottle or a part: a disc.
    Disc {
        /// Centre, world x and y, m.
        center: [f64; 2],
        /// Radius, m.
        radius: f64,
    },
    /// A lying bottle: a rectangle as long as the bottle and as wide as its body.
    Rect {
        /// Centre, world x and y, m.
        center: [f64; 2],
        /// Half the bottle's length, m.
        half_length: f64,
        /// The bottle's radius, m.
        half_width: f64,
        /// Direction of the bottle's axis, rad.
        yaw_rad: f64,
    },
}

impl Footprint {
    /// The footprint of a bottle of `radius` and `height` placed as `placement`.
    pub fn bottle(placement: &BottlePlacement, radius: f64, height: f64) -> Self {
        if placement.lying {
            Self::Rect {
                center: placement.xy,
                half_length: height / 2.0,
                half_width: radius,
                yaw_rad: placement.yaw_rad,
            }
        } else {
            Self::Disc {
                center: placement.xy,
                radius,
            }
        }
    }

    /// The smallest and largest world y it covers.
    pub fn y_extent(&self) -> [f64; 2] {
        let (c, half) = self.half_extents();
        [c[1] - half[1], c[1] + half[1]]
    }

    /// The smallest and largest world x it covers.
    pub fn x_extent(&self) -> [f64; 2] {
        let (c, half) = self.half_extents();
        [c[0] - half[0], c[0] + half[0]]
    }

    fn half_extents(&self) -> ([f64; 2], [f64; 2]) {
        match *self {
            Self::Disc { center, radius } => (center, [radius, radius]),
            Self::Rect {
                center,
                half_length,
                half_width,
                yaw_rad,
            } => {
                let (s, c) = yaw_rad.sin_cos();
                (
                    center,
                    [
                        half_length * c.abs() + half_width * s.abs(),
                        half_length * s.abs() + half_width * c.abs(),
                    ],
                )
            }
        }
    }

    /// The rectangle's corners in order around it (a disc has none).
    fn corners(&self) -> Vec<[f64; 2]> {
        match *self {
            Self::Disc { .. } => Vec::new(),
            Self::Rect {
                center,
                half_length,
                half_width,
                yaw_rad,
            } => {
                let (s, c) = yaw_rad.sin_cos();
                [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
                    .iter()
                    .map(|(a, b)| {
                        let (u, v) = (a * half_length, b * half_width);
                        [center[0] + u * c - v * s, center[1] + u * s + v * c]
                    })
                    .collect()
            }
        }
    }

    /// Distance from `point` to the footprint (0 inside it), m.
    pub fn distance_to_point(&self, point: [f64; 2]) -> f64 {
        match *self {
            Self::Disc { center, radius } => {
                ((point[0] - center[0]).hypot(point[1] - center[1]) - radius).max(0.0)
            }
            Self::Rect {
                center,
                half_length,
                half_width,
                yaw_rad,
            } => {
                let (s, c) = yaw_rad.sin_cos();
                let (dx, dy) = (point[0] - center[0], point[1] - center[1]);
                let (u, v) = (dx * c + dy * s, -dx * s + dy * c);
                let out_u = (u.abs() - half_length).max(0.0);
                let out_v = (v.abs() - half_width).max(0.0);
                out_u.hypot(out_v)
            }
        }
    }

    /// The gap between two footprints (0 when they touch or overlap), m.
    pub fn gap(&self, other: &Self) -> f64 {
        match (*self, *other) {
            (Self::Disc { center, radius }, _) => {
                (other.distance_to_point(center) - radius).max(0.0)
            }
            (_, Self::Disc { center, radius }) => {
                (self.distance_to_point(center) - radius).max(0.0)
            }
            _ => rect_gap(self, other),
        }
    }
}

/// The gap between two rectangles: 0 when they overlap, else the least distance from a corner
/// of one to the other (for two convex polygons that do not overlap, the closest pair of points
/// has a corner of one of them).
fn rect_gap(a: &Footprint, b: &Footprint) -> f64 {
    let (ca, cb) = (a.corners(), b.corners());
    if !separated(&ca, &cb) {
        return 0.0;
    }
    let from_a = ca.iter().map(|p| b.distance_to_point(*p));
    let from_b = cb.iter().map(|p| a.distance_to_point(*p));
    from_a.chain(from_b).fold(f64::INFINITY, f64::min)
}

/// Whether some edge normal of either polygon separates them (the separating axis test).
fn separated(a: &[[f64; 2]], b: &[[f64; 2]]) -> bool {
    let axes = |poly: &[[f64; 2]]| -> Vec<[f64; 2]> {
        (0..poly.len())
            .map(|i| {
                let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
                [-(q[1] - p[1]), q[0] - p[0]]
            })
            .collect()
    };
    let project = |poly: &[[f64; 2]], axis: [f64; 2]| {
        poly.iter()
            .map(|p| p[0] * axis[0] + p[1] * axis[1])
            .fold([f64::INFINITY, f64::NEG_INFINITY], |r, d| {
                [r[0].min(d), r[1].max(d)]
            })
    };
    axes(a).into_iter().chain(axes(b)).any(|axis| {
        let (pa, pb) = (project(a, axis), project(b, axis));
        pa[1] < pb[0] || pb[1] < pa[0]
    })
}

/// Why the bottles could not be placed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("bottle {index} of {count} fits nowhere on the belt near the part: {reason}")]
pub struct PlacementError {
    /// Which bottle, from 0.
    pub index: usize,
    /// How many the trial wanted.
    pub count: usize,
    /// The constraints it could not meet.
    pub reason: String,
}

/// The part a trial's bottles are placed around.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartSpot {
    /// The part's centre, world x and y, m.
    pub xy: [f64; 2],
    /// Its outer radius, m.
    pub radius: f64,
}

/// One bottle's constraints while it is placed.
struct Slot<'a> {
    scenario: &'a Scenario,
    part: PartSpot,
    placed: &'a [BottlePlacement],
    /// The gap range to the part when this is the near bottle.
    near_gap: Option<[f64; 2]>,
}

impl Slot<'_> {
    fn footprint(&self, placement: &BottlePlacement) -> Footprint {
        let bottle = &self.scenario.bottle;
        Footprint::bottle(placement, bottle.radius_m, bottle.height_m)
    }

    /// Whether a candidate lies on the belt, at its gap from the part, and clear of every bottle
    /// placed before it.
    fn fits(&self, placement: &BottlePlacement) -> bool {
        let belt = &self.scenario.conveyor;
        let bottle = &self.scenario.bottle;
        let footprint = self.footprint(placement);
        let [y0, y1] = footprint.y_extent();
        let [x0, x1] = footprint.x_extent();
        let half_w = belt.width_m / 2.0;
        let half_l = belt.length_m / 2.0;
        let on_belt = y0 >= belt.belt_center_m[1] - half_w
            && y1 <= belt.belt_center_m[1] + half_w
            && x0 >= belt.belt_center_m[0] - half_l
            && x1 <= belt.belt_center_m[0] + half_l;
        let part = Footprint::Disc {
            center: self.part.xy,
            radius: self.part.radius,
        };
        let gap = part.gap(&footprint);
        let gap_ok = match self.near_gap {
            // The near bottle is put at its gap by construction; allow for rounding.
            Some([low, high]) => gap >= low - 1e-9 && gap <= high + 1e-9,
            None => {
                let d =
                    (placement.xy[0] - self.part.xy[0]).hypot(placement.xy[1] - self.part.xy[1]);
                let [near, far] = bottle.distance_range_m;
                gap > CLEARANCE_M && d >= near - 1e-9 && d <= far + 1e-9
            }
        };
        on_belt
            && gap_ok
            && self
                .placed
                .iter()
                .all(|other| self.footprint(other).gap(&footprint) > CLEARANCE_M)
    }

    /// The bottle at `gap` from the part in direction `angle`, lying at `yaw` or standing.
    fn at_gap(&self, lying: bool, yaw: f64, angle: f64, gap: f64) -> BottlePlacement {
        let bottle = &self.scenario.bottle;
        let (s, c) = angle.sin_cos();
        let place = |d: f64| BottlePlacement {
            xy: [self.part.xy[0] + d * c, self.part.xy[1] + d * s],
            lying,
            yaw_rad: yaw,
        };
        if !lying {
            return place(self.part.radius + bottle.radius_m + gap);
        }
        // The distance from the part's centre to the rectangle grows with d along the ray (0 at
        // d = 0, the centre inside it, then convex): bisect for the wanted gap.
        let want = self.part.radius + gap;
        let (mut low, mut high) = (0.0, want + bottle.height_m / 2.0 + bottle.radius_m);
        for _ in 0..60 {
            let mid = 0.5 * (low + high);
            if self.footprint(&place(mid)).distance_to_point(self.part.xy) < want {
                low = mid;
            } else {
                high = mid;
            }
        }
        place(high)
    }

    /// The first candidate of a fixed scan that fits, when the random draws found none.
    fn search(&self, lying: bool) -> Option<BottlePlacement> {
        let steps = (0..SEARCH_STEPS).map(|k| k as f64 / (SEARCH_STEPS - 1) as f64);
        let yaws: Vec<f64> = if lying {
            (0..SEARCH_YAWS)
                .map(|k| std::f64::consts::PI * k as f64 / SEARCH_YAWS as f64)
                .collect()
        } else {
            vec![0.0]
        };
        for t in steps {
            for k in 0..SEARCH_ANGLES {
                let angle = std::f64::consts::TAU * k as f64 / SEARCH_ANGLES as f64;
                for &yaw in &yaws {
                    let candidate = match self.near_gap {
                        Some([low, high]) => self.at_gap(lying, yaw, angle, low + t * (high - low)),
                        None => {
                            let [near, far] = self.scenario.bottle.distance_range_m;
                            let d = near + t * (far - near);
                            BottlePlacement {
                                xy: [
                                    self.part.xy[0] + d * angle.cos(),
                                    self.part.xy[1] + d * angle.sin(),
                                ],
                                lying,
                                yaw_rad: yaw,
                            }
                        }
                    };
                    if self.fits(&candidate) {
                        return Some(candidate);
                    }
                }
            }
        }
        None
    }
}

/// The trial's bottles around `part`: `bottle.count_range` of them; the first
/// `bottle.near_count` at a gap in `bottle.near_gap_range_m` from the part when that is set,
/// the others (or all) with their
/// centres `bottle.distance_range_m` from the part's and at least [`CLEARANCE_M`] clear of it;
/// each on the belt, clear of the others by [`CLEARANCE_M`], lying with probability
/// `bottle.lying_fraction`. Up to 64 random draws a bottle, then a deterministic scan of the
/// ranges; when a bottle finds no place, the whole layout is drawn again (the count kept), up to
/// 16 layouts; an error when none fits.
pub fn place_bottles(
    scenario: &Scenario,
    part: PartSpot,
    rng: &mut SimRng,
) -> Result<Vec<BottlePlacement>, PlacementError> {
    let bottle = &scenario.bottle;
    let [low, high] = bottle.count_range;
    // A fixed count draws nothing, so the paper's one-bottle trials keep their random stream.
    // Validation keeps the counts in [1, 8].
    let (low, high) = (low.max(0) as u64, high.max(0) as u64);
    let count = if high > low {
        (low + rng.below(high - low + 1)) as usize
    } else {
        low as usize
    };
    let mut attempt = 0;
    loop {
        match try_layout(scenario, part, count, rng) {
            Ok(placed) => return Ok(placed),
            // Earlier bottles can take the only room a later one had: a fresh layout from the
            // same stream (a trial that places at once draws exactly as it always did).
            Err(_) if attempt + 1 < LAYOUT_ATTEMPTS => attempt += 1,
            Err(e) => return Err(e),
        }
    }
}

/// One layout of `count` bottles around `part`, bottle after bottle (see [`place_bottles`]).
fn try_layout(
    scenario: &Scenario,
    part: PartSpot,
    count: usize,
    rng: &mut SimRng,
) -> Result<Vec<BottlePlacement>, PlacementError> {
    let bottle = &scenario.bottle;
    let mut placed: Vec<BottlePlacement> = Vec::with_capacity(count);
    for index in 0..count {
        let slot = Slot {
            scenario,
            part,
            placed: &placed,
            near_gap: if (index as i64) < bottle.near_count {
                bottle.near_gap_range_m
            } else {
                None
            },
        };
        let lying = rng.uniform() < bottle.lying_fraction;
        let mut found = None;
        for _ in 0..RANDOM_DRAWS {
            let candidate = match slot.near_gap {
                Some([g0, g1]) => {
                    let gap = rng.range(g0, g1);
                    let angle = rng.range(0.0, std::f64::consts::TAU);
                    let yaw = rng.range(0.0, std::f64::consts::TAU);
                    slot.at_gap(lying, yaw, angle, gap)
                }
                None => {
                    let distance =
                        rng.range(bottle.distance_range_m[0], bottle.distance_range_m[1]);
                    let angle = rng.range(0.0, std::f64::consts::TAU);
                    // A lying bottle's footprint turns with its yaw, so that is drawn with its
                    // place; a standing one's yaw is drawn once it has a place.
                    let yaw = if lying {
                        rng.range(0.0, std::f64::consts::TAU)
                    } else {
                        0.0
                    };
                    BottlePlacement {
                        xy: [
                            part.xy[0] + distance * angle.cos(),
                            part.xy[1] + distance * angle.sin(),
                        ],
                        lying,
                        yaw_rad: yaw,
                    }
                }
            };
            if slot.fits(&candidate) {
                found = Some(candidate);
                break;
            }
        }
        let Some(mut placement) = found.or_else(|| slot.search(lying)) else {
            let wanted = match slot.near_gap {
                Some([g0, g1]) => format!("a gap of {g0} to {g1} m from the part"),
                None => format!(
                    "its centre {} to {} m from the part's and {CLEARANCE_M} m clear of it",
                    bottle.distance_range_m[0], bottle.distance_range_m[1]
                ),
            };
            return Err(PlacementError {
                index,
                count,
                reason: format!(
                    "{} bottle with {wanted}, on the belt and {CLEARANCE_M} m clear of the {index} \
                     placed before it",
                    if lying { "a lying" } else { "a standing" }
                ),
            });
        };
        if !lying && slot.near_gap.is_none() {
            placement.yaw_rad = rng.range(0.0, std::f64::consts::TAU);
        }
        placed.push(placement);
    }
    Ok(placed)
}

#[cfg(test)]
#[path = "placement_tests.rs"]
mod tests;
