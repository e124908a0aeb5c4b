use std::path::Path;
use twincell::cell::Cell;
use twincell::scenario::Scenario;
fn main() {
    let scenario = Scenario::load(Path::new("scenarios/paper_50.toml")).unwrap();
    for seed in 0..4 {
        let mut rng = twincell::rng::SimRng::new(seed);
        let mut cell = Cell::build(&scenario, None, &mut rng).unwrap();
        println!("type {} h {}", cell.part.type_name, cell.part.height_m);
        for i in 0..1440 {
            let target = if i < 240 { 0.25 } else { 0.0 };
            cell.conveyor.ramp_towards(target, 1.0 / 240.0);
            cell.world.step_with_hooks(&cell.conveyor);
            if i % 120 == 0 {
                let p = cell.body_pose(cell.part_body).unwrap();
                let (r, pi, _) = p.rotation.euler_angles();
                println!(
                    "t={:.2} v={:.3} part {:.5} {:.5} {:.5} tilt {:.4} {:.4}",
                    cell.world.time_s(),
                    cell.conveyor.speed_m_s(),
                    p.translation.x,
                    p.translation.y,
                    p.translation.z,
                    r,
                    pi
                );
            }
        }
    }
}
