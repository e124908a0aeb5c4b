use std::path::Path;
use twincell::cell::Cell;
use twincell::planning::CollisionChecker;
use twincell::scenario::Scenario;
fn main() {
    let scenario = Scenario::load(Path::new("scenarios/paper_50.toml")).unwrap();
    let mut rng = twincell::rng::SimRng::new(1);
    let cell = Cell::build(&scenario, None, &mut rng).unwrap();
    let checker = CollisionChecker::new(
        Cell::arm_model(),
        cell.robot_shapes.clone(),
        cell.finger_reference_m,
        cell.obstacles.clone(),
        0.004,
    );
    println!(
        "home: {:?}",
        checker.check_configuration(&scenario.robot.home_q_rad, 0.045, None, &[])
    );
    for s in &cell.robot_shapes {
        println!(
            "{} {:?} {:?}",
            s.link,
            s.mount,
            s.mount_from_shape.translation.vector.transpose()
        );
    }
    for o in &cell.obstacles {
        println!(
            "{} {:?}",
            o.name,
            o.base_from_shape.translation.vector.transpose()
        );
    }
}
