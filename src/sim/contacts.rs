//! Contact queries over the world, for stages that watch the physics without reaching into the
//! engine's narrow phase themselves.

use rapier3d::prelude::*;

use super::{Tag, World};

impl World {
    /// The contact pairs between `body`'s colliders and colliders tagged `tag`, each with the
    /// collider of `body` it involves, in the engine's order.
    fn pairs_with_tag(
        &self,
        body: RigidBodyHandle,
        tag: Tag,
    ) -> impl Iterator<Item = &ContactPair> + '_ {
        let physics = &self.physics;
        let colliders: &[ColliderHandle] =
            physics.bodies.get(body).map_or(&[], |rb| rb.colliders());
        colliders.iter().flat_map(move |&collider| {
            physics
                .narrow_phase
                .contact_pairs_with(collider)
                .filter(move |pair| {
                    let other = if pair.collider1 == collider {
                        pair.collider2
                    } else {
                        pair.collider1
                    };
                    physics
                        .colliders
                        .get(other)
                        .is_some_and(|c| c.user_data == tag.bits())
                })
        })
    }

    /// The total contact impulse between `body` and everything tagged `tag` in the last step,
    /// N s.
    pub fn contact_impulse_with(&self, body: RigidBodyHandle, tag: Tag) -> f64 {
        self.pairs_with_tag(body, tag)
            .map(|pair| f64::from(pair.total_impulse_magnitude()))
            .sum()
    }

    /// Whether `body` touches anything tagged `tag`: a contact point no further apart than
    /// `within_m` (touching, not merely within the solver's prediction distance).
    pub fn touches(&self, body: RigidBodyHandle, tag: Tag, within_m: f64) -> bool {
        self.pairs_with_tag(body, tag).any(|pair| {
            pair.manifolds()
                .iter()
                .any(|m| m.points.iter().any(|p| p.dist <= within_m as f32))
        })
    }
}
