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

#[cfg(test)]
mod tests {
    use rapier3d::prelude::*;

    use crate::sim::{Tag, World, WorldParams};

    /// How far a light standing cylinder (a 30 g bottle, 33 mm in radius, 200 mm tall) is moved
    /// by a 60 x 60 x 40 mm block that descends past it at 0.42 m/s, its near face `gap_m` from
    /// the cylinder's side and starting just above its top, in a world as [`World::new`] makes
    /// it or with rapier's contact recycling switched back on, m.
    fn cylinder_moved_by_passing_block(gap_m: f32, recycling: bool) -> f32 {
        let mut world = World::new(WorldParams::default());
        if recycling {
            world.physics.integration_parameters.contact_recycling = true;
        }
        let physics = &mut world.physics;
        let ground = physics.bodies.insert(RigidBodyBuilder::fixed());
        physics.colliders.insert_with_parent(
            ColliderBuilder::cuboid(1.0, 1.0, 0.01).translation(Vector::new(0.0, 0.0, -0.01)),
            ground,
            &mut physics.bodies,
        );
        let (radius, half_height) = (0.033, 0.1);
        let bottle = physics
            .bodies
            .insert(RigidBodyBuilder::dynamic().translation(Vector::new(0.0, 0.0, half_height)));
        physics.colliders.insert_with_parent(
            ColliderBuilder::cylinder(half_height, radius)
                .rotation(Vector::new(std::f32::consts::FRAC_PI_2, 0.0, 0.0))
                .mass(0.03)
                .user_data(Tag::Bottle.bits()),
            bottle,
            &mut physics.bodies,
        );
        let half = [0.03, 0.03, 0.02];
        let x = radius + gap_m + half[0];
        let mut z = 2.0 * half_height + half[2] + 0.005;
        let block = physics.bodies.insert(
            RigidBodyBuilder::kinematic_position_based().translation(Vector::new(x, 0.0, z)),
        );
        physics.colliders.insert_with_parent(
            ColliderBuilder::cuboid(half[0], half[1], half[2]).user_data(Tag::Robot.bits()),
            block,
            &mut physics.bodies,
        );
        // Let the bottle settle, then sweep the block down past it.
        for _ in 0..60 {
            world.step();
        }
        let rest = world.physics.bodies[bottle].translation();
        let dt = world.physics.integration_parameters.dt;
        for _ in 0..120 {
            z -= 0.42 * dt;
            world.physics.bodies[block].set_next_kinematic_translation(Vector::new(x, 0.0, z));
            world.step();
        }
        (world.physics.bodies[bottle].translation() - rest).length()
    }

    #[test]
    fn a_body_passing_clear_of_a_light_one_leaves_it_standing() {
        // With recycling, the block's corner, come within the 2 cm prediction above the
        // cylinder's rim, goes on pushing along that stale diagonal normal as it slides down
        // past the side: the cylinder is knocked over from 3 mm clear.
        let knocked = cylinder_moved_by_passing_block(0.003, true);
        assert!(
            knocked > 0.01,
            "a recycled block 3 mm clear moved the cylinder {knocked} m: the sweep no longer \
             shows stale contacts (has rapier changed?)"
        );
        for gap_m in [0.001, 0.003, 0.005, 0.008, 0.01, 0.012, 0.014, 0.016, 0.018] {
            let moved = cylinder_moved_by_passing_block(gap_m, false);
            assert!(moved < 2e-5, "{gap_m} m clear: moved {moved} m");
        }
    }
}
