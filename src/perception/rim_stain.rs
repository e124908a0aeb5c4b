//! Oil smeared along a tube's end face: an arc of the rim (up to a third of it and more) darkened
//! by a factor, across part of the wall or all of it, for the synthetic scenes
//! ([`crate::perception::synthetic::Scene::rim_stains`]).
//!
//! Unlike a round [`crate::perception::synthetic::Stain`], which darkens whatever lies under it,
//! a rim stain lies on the machined face only: it stops at the bore edge and at the face's outer
//! edge, as oil on the face does, and follows the bore's outline when it reaches it.

use crate::perception::synthetic::Tube;
use std::f64::consts::{PI, TAU};

/// Oil on an arc of one tube's end face.
#[derive(Debug, Clone, PartialEq)]
pub struct RimStain {
    /// Index of the tube in `Scene::tubes`.
    pub tube: usize,
    /// Direction of the arc's middle about the bore centre, radians from +x towards +y.
    pub middle_rad: f64,
    /// Angle the arc spans, radians (`TAU / 3` for a third of the rim).
    pub span_rad: f64,
    /// Where the stain starts across the wall, pixels out from the bore edge (0: at the edge).
    pub inner_px: f64,
    /// Where it ends across the wall, pixels out from the bore edge (the wall or more: at the
    /// face's outer edge).
    pub outer_px: f64,
    /// Factor applied to the face's reflectance under the stain.
    pub transmission: f64,
    /// Width of the stain's soft rim, pixels, along its own boundaries (not along the bore edge
    /// or the face's outer edge, where the face itself ends); 0 for a sharp edge.
    pub soft_px: f64,
}

impl RimStain {
    /// The factor this stain applies at `(x, y)` on `tube` (1 off the stain).
    pub fn factor(&self, tube: &Tube, x: f64, y: f64) -> f64 {
        let Some(depth) = self.depth(tube, x, y) else {
            return 1.0;
        };
        if depth <= 0.0 {
            return 1.0;
        }
        let cover = if depth >= self.soft_px {
            1.0
        } else {
            let u = depth / self.soft_px;
            u * u * (3.0 - 2.0 * u)
        };
        1.0 + cover * (self.transmission - 1.0)
    }

    /// Whether a sharp stain's own boundary passes within `band_px` of `(x, y)`, where a
    /// renderer must supersample (a soft one varies smoothly).
    pub fn sharp_boundary_near(&self, tube: &Tube, x: f64, y: f64, band_px: f64) -> bool {
        self.soft_px < 1.0 && self.depth(tube, x, y).is_some_and(|d| d.abs() < band_px)
    }

    /// Signed distance into the stain from its own boundaries (negative outside), pixels; `None`
    /// off the tube's face, where the stain never lies.
    fn depth(&self, tube: &Tube, x: f64, y: f64) -> Option<f64> {
        let (dx, dy) = (x - tube.centre_px[0], y - tube.centre_px[1]);
        let rho = dx.hypot(dy);
        let theta = dy.atan2(dx);
        let bore = tube.bore.radius_at(theta);
        if rho < bore || rho >= tube.outer_radius_px {
            return None;
        }
        let wall = tube.outer_radius_px - bore;
        // Angular distance from the arc's middle, in [0, PI].
        let off = PI - ((theta - self.middle_rad).rem_euclid(TAU) - PI).abs();
        let along = (self.span_rad / 2.0 - off) * rho;
        let mut depth = along;
        if self.inner_px > 0.0 {
            depth = depth.min(rho - bore - self.inner_px);
        }
        if self.outer_px < wall {
            depth = depth.min(bore + self.outer_px - rho);
        }
        Some(depth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::synthetic::BoreShape;

    fn tube() -> Tube {
        Tube {
            centre_px: [100.0, 100.0],
            bore: BoreShape::Circle { radius_px: 30.0 },
            outer_radius_px: 50.0,
            rim_level: 200.0,
            bore_level: 20.0,
        }
    }

    #[test]
    fn the_stain_lies_on_its_arc_of_the_face_only() {
        let stain = RimStain {
            tube: 0,
            middle_rad: 0.0,
            span_rad: TAU / 3.0,
            inner_px: 0.0,
            outer_px: 100.0,
            transmission: 0.6,
            soft_px: 0.0,
        };
        let t = tube();
        let at = |r: f64, a: f64| stain.factor(&t, 100.0 + r * a.cos(), 100.0 + r * a.sin());
        // On the face within the arc, on both sides of +x.
        assert_eq!(at(31.0, 0.0), 0.6);
        assert_eq!(at(49.0, 1.0), 0.6);
        assert_eq!(at(40.0, -1.0), 0.6);
        // Past the arc's ends, in the bore, past the face.
        assert_eq!(at(40.0, 1.1), 1.0);
        assert_eq!(at(40.0, PI), 1.0);
        assert_eq!(at(29.0, 0.0), 1.0);
        assert_eq!(at(51.0, 0.0), 1.0);
    }

    #[test]
    fn a_soft_stain_across_part_of_the_wall_fades_in() {
        let stain = RimStain {
            tube: 0,
            middle_rad: PI,
            span_rad: 1.0,
            inner_px: 4.0,
            outer_px: 14.0,
            transmission: 0.5,
            soft_px: 2.0,
        };
        let t = tube();
        let at = |r: f64| stain.factor(&t, 100.0 - r, 100.0);
        assert_eq!(at(33.0), 1.0);
        assert!((at(35.0) - 0.75).abs() < 1e-12);
        assert_eq!(at(39.0), 0.5);
        assert_eq!(at(45.0), 1.0);
    }
}
