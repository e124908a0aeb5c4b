//! Tubes partly hidden by a bottle in the family shots. A camera tilted over the belt often sees
//! a bottle standing or lying between it and the part at the station; a detector that has only
//! seen tubes in the clear does not find the part then, although most of its end face is in
//! view. Some family shots therefore move one of their bottles into the line of sight of one of
//! their tubes, set down on the belt beside it (never through it); and every shot keeps only the
//! tubes whose end face the camera sees enough of to be labelled.

use nalgebra::{Point3, Vector2, Vector3};
use rapier3d::prelude::{Pose, Ray, SharedShape, Vector};

use super::scene::{ObjectKind, Scene};
use crate::rng::SimRng;

/// Share of family shots that move a bottle in front of a tube.
pub const OCCLUDED_SHOT_SHARE: f64 = 0.5;
/// Least share of its end face a labelled tube shows: a tube hidden more than this is left out of
/// the shot (a detector cannot be asked to find what the camera does not see).
pub const MIN_FACE_VISIBLE: f64 = 0.5;
/// Most share of its end face a tube shows for the bottle moved in front of it to count as
/// hiding it.
pub const MAX_OCCLUDED_VISIBLE: f64 = 0.9;
/// Points sampled on each of an end face's three circles (outer rim, middle, bore rim).
const FACE_SAMPLES: usize = 24;
/// Least horizontal gap between a moved bottle and any tube, m.
const BOTTLE_TUBE_GAP_M: f64 = 0.002;
/// Draws of a bottle's place in front of a tube before the shot keeps it where it was.
const OCCLUDE_TRIES: usize = 96;

/// A tube of a family shot, as the occlusion sees it.
#[derive(Debug, Clone, Copy)]
pub struct TubeFace {
    /// Axis position on the belt, m.
    pub centre: [f64; 2],
    /// Height of the end face, m.
    pub top_z: f64,
    /// Outer radius, m.
    pub outer_m: f64,
    /// Bore radius, m.
    pub bore_m: f64,
}

/// The belt's strip that bottles must stay on: its centre line's y and half width, m.
#[derive(Debug, Clone, Copy)]
pub struct BeltStrip {
    /// The belt's centre line, world y, m.
    pub centre_y: f64,
    /// Half the belt's width, m.
    pub half_width: f64,
}

/// The share of `tube`'s end face that a camera at `eye` sees past `occluders` (convex hulls in
/// the world frame): the points of three circles on the face (outer rim, middle and bore rim)
/// whose line of sight no occluder crosses.
pub fn face_visible_share(eye: &Point3<f64>, tube: &TubeFace, occluders: &[SharedShape]) -> f64 {
    let radii = [
        tube.outer_m * 0.97,
        (tube.outer_m + tube.bore_m) / 2.0,
        tube.bore_m * 1.03,
    ];
    let mut seen = 0usize;
    for r in radii {
        for k in 0..FACE_SAMPLES {
            let t = std::f64::consts::TAU * k as f64 / FACE_SAMPLES as f64;
            let p = Point3::new(
                tube.centre[0] + r * t.cos(),
                tube.centre[1] + r * t.sin(),
                tube.top_z,
            );
            let to_eye = eye - p;
            let ray = Ray::new(
                Vector::new(p.x as f32, p.y as f32, p.z as f32),
                Vector::new(to_eye.x as f32, to_eye.y as f32, to_eye.z as f32),
            );
            let blocked = occluders
                .iter()
                .any(|o| o.intersects_ray(&Pose::IDENTITY, &ray, 1.0));
            if !blocked {
                seen += 1;
            }
        }
    }
    seen as f64 / (radii.len() * FACE_SAMPLES) as f64
}

/// The convex hull of `points`, for lines of sight (`None` when they span no volume).
fn hull(points: impl Iterator<Item = Point3<f64>>) -> Option<SharedShape> {
    let points: Vec<Vector> = points
        .map(|p| Vector::new(p.x as f32, p.y as f32, p.z as f32))
        .collect();
    SharedShape::convex_hull(&points)
}

/// The bottles of `scene`: their indices among its objects.
fn bottle_objects(scene: &Scene) -> Vec<usize> {
    (0..scene.objects.len())
        .filter(|&i| scene.objects[i].kind == ObjectKind::Bottle)
        .collect()
}

/// Whether `points` (a bottle's, in the world) stand clear of every tube's wall and on the belt.
fn placeable(points: &[Point3<f64>], tubes: &[TubeFace], belt: &BeltStrip) -> bool {
    points.iter().all(|p| {
        (p.y - belt.centre_y).abs() <= belt.half_width
            && tubes.iter().all(|t| {
                (p.x - t.centre[0]).hypot(p.y - t.centre[1]) >= t.outer_m + BOTTLE_TUBE_GAP_M
            })
    })
}

/// Whether two point sets' horizontal boxes overlap (two bottles would pass through each other).
fn boxes_overlap(a: &[Point3<f64>], b: &[Point3<f64>]) -> bool {
    let extent = |s: &[Point3<f64>]| {
        s.iter()
            .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |e, p| {
                [e[0].min(p.x), e[1].min(p.y), e[2].max(p.x), e[3].max(p.y)]
            })
    };
    let (a, b) = (extent(a), extent(b));
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

/// Moves one of `scene`'s bottles, as it stands or lies, into the line of sight from `eye` to one
/// of `tubes`, set down beside it on the belt so that it hides part of the end face
/// (at most [`MAX_OCCLUDED_VISIBLE`] of it seen) and leaves every tube at least
/// [`MIN_FACE_VISIBLE`]. Leaves the scene as it was when no draw does. Returns whether it moved
/// one.
pub fn stage_occlusion(
    scene: &mut Scene,
    tubes: &[TubeFace],
    eye: &Point3<f64>,
    belt: &BeltStrip,
    rng: &mut SimRng,
) -> bool {
    let bottles = bottle_objects(scene);
    if bottles.is_empty() || tubes.is_empty() {
        return false;
    }
    let moved = bottles[rng.below(bottles.len() as u64) as usize];
    let target = tubes[rng.below(tubes.len() as u64) as usize];
    let points: Vec<Point3<f64>> = scene.objects[moved].world_points().collect();
    let n = points.len().max(1) as f64;
    let centroid = points
        .iter()
        .fold(Vector2::zeros(), |s, p| s + p.xy().coords)
        / n;
    // The bottle's reach on the belt from its centroid, the most it can stand off the axis.
    let reach = points
        .iter()
        .map(|p| (p.xy().coords - centroid).norm())
        .fold(0.0, f64::max);
    let others: Vec<Vec<Point3<f64>>> = bottles
        .iter()
        .filter(|&&b| b != moved)
        .map(|&b| scene.objects[b].world_points().collect())
        .collect();
    let still: Vec<SharedShape> = others
        .iter()
        .filter_map(|o| hull(o.iter().copied()))
        .collect();
    let towards_eye = Vector2::new(eye.x - target.centre[0], eye.y - target.centre[1]);
    // How far in front of the face the bottle's top still crosses the line of sight.
    let top = points.iter().map(|p| p.z).fold(f64::MIN, f64::max);
    let sight_reach = (top - target.top_z) * towards_eye.norm() / (eye.z - target.top_z).max(1e-6);
    if sight_reach <= 0.0 {
        return false;
    }
    // The share of the face to leave in view, drawn; the draw of place nearest to it is kept.
    let aim = rng.range(MIN_FACE_VISIBLE, MAX_OCCLUDED_VISIBLE);
    let mut best: Option<(f64, Vector3<f64>)> = None;
    for _ in 0..OCCLUDE_TRIES {
        // Towards the camera's foot, or any way round under a camera straight overhead.
        let heading = if towards_eye.norm() > 1e-3 {
            towards_eye.normalize()
        } else {
            let a = rng.range(0.0, std::f64::consts::TAU);
            Vector2::new(a.cos(), a.sin())
        };
        let side = Vector2::new(-heading.y, heading.x);
        let along = target.outer_m + 0.5 * reach + rng.range(0.0, sight_reach.min(0.2));
        let across = rng.range(-1.0, 1.0) * (target.outer_m + 0.5 * reach);
        let place =
            Vector2::new(target.centre[0], target.centre[1]) + heading * along + side * across;
        let offset = Vector3::new(place.x - centroid.x, place.y - centroid.y, 0.0);
        let placed: Vec<Point3<f64>> = points.iter().map(|p| p + offset).collect();
        if !placeable(&placed, tubes, belt) || others.iter().any(|o| boxes_overlap(o, &placed)) {
            continue;
        }
        let Some(shape) = hull(placed.iter().copied()) else {
            continue;
        };
        let mut occluders = still.clone();
        occluders.push(shape);
        let seen = face_visible_share(eye, &target, &occluders);
        let all_seen = tubes
            .iter()
            .all(|t| face_visible_share(eye, t, &occluders) >= MIN_FACE_VISIBLE);
        if seen <= MAX_OCCLUDED_VISIBLE && all_seen {
            let miss = (seen - aim).abs();
            if best.is_none_or(|(m, _)| miss < m) {
                best = Some((miss, offset));
            }
        }
    }
    let Some((_, offset)) = best else {
        return false;
    };
    scene.objects[moved].world_from_object.translation.vector += offset;
    true
}

/// The share of each of `tubes`' end faces that a camera at `eye` sees past `scene`'s bottles.
pub fn visible_shares(scene: &Scene, tubes: &[TubeFace], eye: &Point3<f64>) -> Vec<f64> {
    let occluders: Vec<SharedShape> = bottle_objects(scene)
        .into_iter()
        .filter_map(|b| hull(scene.objects[b].world_points()))
        .collect();
    tubes
        .iter()
        .map(|t| face_visible_share(eye, t, &occluders))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn box_hull(min: [f64; 3], max: [f64; 3]) -> SharedShape {
        let corners = (0..8).map(|k| {
            Point3::new(
                if k & 1 == 0 { min[0] } else { max[0] },
                if k & 2 == 0 { min[1] } else { max[1] },
                if k & 4 == 0 { min[2] } else { max[2] },
            )
        });
        hull(corners).expect("a box spans a volume")
    }

    #[test]
    fn a_face_in_the_clear_is_seen_whole_and_one_behind_a_wall_not_at_all() {
        let tube = TubeFace {
            centre: [0.0, 0.0],
            top_z: 0.1,
            outer_m: 0.02,
            bore_m: 0.01,
        };
        let eye = Point3::new(0.5, 0.0, 0.8);
        assert_eq!(face_visible_share(&eye, &tube, &[]), 1.0);
        // A wall between the face and the camera, taller than the line of sight.
        let wall = box_hull([0.1, -0.2, 0.0], [0.12, 0.2, 0.5]);
        assert_eq!(face_visible_share(&eye, &tube, &[wall]), 0.0);
        // The same wall behind the tube hides nothing.
        let behind = box_hull([-0.12, -0.2, 0.0], [-0.1, 0.2, 0.5]);
        assert_eq!(face_visible_share(&eye, &tube, &[behind]), 1.0);
        // A wall covering the half y < 0 hides about half of the face.
        let half = box_hull([0.1, -0.2, 0.0], [0.12, 0.0, 0.5]);
        let share = face_visible_share(&eye, &tube, &[half]);
        assert!((0.4..=0.6).contains(&share), "{share}");
    }
}
