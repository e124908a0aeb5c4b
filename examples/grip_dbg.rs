use rapier3d::prelude::*;
use twincell::sim::{World, WorldParams};
fn main() {
    let mode = std::env::args().nth(1).unwrap_or("impulse".into());
    let mut world = World::new(WorldParams::default());
    let p = &mut world.physics;
    // floor
    let floor = p.bodies.insert(RigidBodyBuilder::fixed());
    p.colliders.insert_with_parent(
        ColliderBuilder::cuboid(1.0, 1.0, 0.05).translation(Vector::new(0.0, 0.0, -0.05)),
        floor,
        &mut p.bodies,
    );
    // part: prism r 0.031 h 0.09 mass 1.06
    let part = p.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.0, 0.0, 0.045))
            .can_sleep(false),
    );
    let mut pts = vec![];
    for i in 0..32 {
        let a = std::f32::consts::TAU * i as f32 / 32.0;
        for y in [-0.045f32, 0.045] {
            pts.push(Vector::new(0.031 * a.cos(), y, 0.031 * a.sin()));
        }
    }
    let shape = SharedShape::convex_hull(&pts).unwrap();
    p.colliders.insert_with_parent(
        ColliderBuilder::new(shape)
            .rotation(Vector::new(std::f32::consts::FRAC_PI_2, 0.0, 0.0))
            .mass(1.06)
            .friction(0.6),
        part,
        &mut p.bodies,
    );
    // carrier: kinematic body at z = 0.14 (fingertips at 0.008)
    let carrier = p.bodies.insert(
        RigidBodyBuilder::kinematic_position_based().translation(Vector::new(0.0, 0.0, 0.148)),
    );
    p.colliders.insert_with_parent(
        ColliderBuilder::cuboid(0.06, 0.025, 0.025).translation(Vector::new(0.0, 0.0, 0.025)),
        carrier,
        &mut p.bodies,
    );
    let mut fingers = vec![];
    for sign in [1.0f32, -1.0] {
        let f = p.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(Vector::new(sign * 0.04, 0.0, 0.148 - 0.095))
                .can_sleep(false),
        );
        p.colliders.insert_with_parent(
            ColliderBuilder::cuboid(0.006, 0.015, 0.045)
                .translation(Vector::new(sign * 0.006, 0.0, 0.0))
                .mass(0.08)
                .friction(1.0),
            f,
            &mut p.bodies,
        );
        let joint = PrismaticJointBuilder::new(Vector::new(sign, 0.0, 0.0))
            .local_anchor1(Vector::new(0.0, 0.0, -0.095))
            .local_anchor2(Vector::new(-sign * 0.0, 0.0, 0.0))
            .limits([0.004, 0.05])
            .motor_model(MotorModel::ForceBased)
            .motor_position(0.0, 4000.0, 120.0)
            .motor_max_force(40.0);
        let _ = mode.as_str();
        p.impulse_joints.insert(carrier, f, joint, true);
        fingers.push(f);
    }
    for i in 0..960 {
        let t = i as f32 / 240.0;
        let z = 0.148
            + if t > 1.0 {
                ((t - 1.0) * 0.2).min(0.3)
            } else {
                0.0
            };
        if let Some(rb) = world.physics.bodies.get_mut(carrier) {
            rb.set_next_kinematic_translation(Vector::new(0.0, 0.0, z));
        }
        world.step();
        if i % 60 == 0 {
            let pp = world.physics.bodies[part].translation();
            let f0 = world.physics.bodies[fingers[0]].translation();
            println!(
                "t={t:.2} carrier z {z:.3} part z {:.4} rel {:.4} finger x {:.4}",
                pp.z,
                z - pp.z,
                f0.x
            );
        }
    }
}
