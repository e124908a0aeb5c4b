use std::path::Path;
use twincell::batch::{Perception, TrialRunner};
use twincell::cell::CellTrialRunner;
use twincell::scenario::Scenario;
fn main() {
    let path = Path::new("scenarios/paper_50.toml");
    let scenario = Scenario::load(path).unwrap();
    let runner = CellTrialRunner::new(scenario, path, Perception::Oracle).unwrap();
    let n: u32 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(5);
    let only: Option<u32> = std::env::args().nth(2).map(|s| s.parse().unwrap());
    for i in 0..n {
        if only.is_some_and(|o| o != i) {
            continue;
        }
        let seed = twincell::rng::SimRng::derive(731, i as u64).next_u64();
        let r = runner.run_trial(i, seed);
        println!(
            "{} {:?} {:?} {:?} bin={:?} part={:?} {:.2}s wall {:.0}ms phys {:.0}ms plan {:.0}ms",
            i,
            r.outcome,
            r.failure,
            r.detail,
            r.placed_bin,
            r.part
                .as_ref()
                .map(|p| (&p.part_type, p.correct_bin.clone(), p.true_roundness_mm)),
            r.sim_time_s,
            r.timing.wall_ms,
            r.timing.physics_ms,
            r.timing.planning_ms
        );
    }
}
