//! The grasp search's timings (`cargo bench --bench planning`): the clearance-ranked search
//! (`GraspSearch::rank`) and the whole pick plan (`PickPlanner::plan_pick`, the search and the
//! margin check of the chosen motion) on the paper cell's real robot shapes, for percepts drawn
//! as `scenarios/suite/clutter.toml` places its bottles (2-3 bottles, the first 0-10 mm from
//! the part, half of them lying) and for a free part.
//!
//! Each benchmark plans one percept per iteration, cycling through 24 drawn ones, so
//! criterion's median is near the median per trial. Group `planning_cpu` measures the same by
//! the process's CPU time, which a shared machine inflates far less than wall time.

use std::hint::black_box;
use std::path::Path;

use criterion::measurement::Measurement;
use criterion::{BenchmarkGroup, Criterion, criterion_group, criterion_main};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use twincell::cell::{Cell, CellModel, PartSpot, place_bottles};
use twincell::kinematics::JointVector;
use twincell::planning::{GraspSearch, PickPlanner};
use twincell::rng::SimRng;
use twincell::scenario::{PartTypeId, Scenario};
use twincell::station::{Percept, bottle_obstacle};

#[path = "common/cpu_time.rs"]
mod cpu_time;
use cpu_time::ProcessCpuTime;

fn scenario(file: &str) -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    match Scenario::load(&path) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

/// The planner of the paper's cell as a trial builds it, the arm at home.
fn planner(scenario: &Scenario) -> PickPlanner {
    let Ok(model) = CellModel::with_urdf(scenario.clone(), None) else {
        panic!("the paper's cell model builds");
    };
    let Ok(cell) = Cell::build(&model, &mut SimRng::new(1)) else {
        panic!("the paper's cell builds");
    };
    PickPlanner::for_cell(&model, &cell)
}

/// `count` percepts of a 20 mm tube at the pick station with bottles placed as `clutter`
/// places them (none when `clutter` has no bottles).
fn percepts(clutter: &Scenario, belt_top_z: f64, count: u64) -> Vec<Percept> {
    let belt = &clutter.conveyor;
    let bottle = &clutter.bottle;
    (0..count)
        .map(|k| {
            let mut rng = SimRng::new(7000 + k);
            let xy = [
                belt.photo_eye_x_m + rng.range(-0.01, 0.01),
                belt.belt_center_m[1] + rng.range(-0.03, 0.03),
            ];
            let spot = PartSpot { xy, radius: 0.02 };
            let placements = place_bottles(clutter, spot, &mut rng).unwrap_or_default();
            let obstacles = placements
                .iter()
                .map(|p| {
                    let yaw = UnitQuaternion::from_euler_angles(0.0, 0.0, p.yaw_rad);
                    let world_from_bottle = if p.lying {
                        // Base centre half a length back along the axis, which lies along x.
                        Isometry3::from_parts(
                            Translation3::new(p.xy[0], p.xy[1], belt_top_z + bottle.radius_m),
                            yaw * UnitQuaternion::from_euler_angles(
                                0.0,
                                std::f64::consts::FRAC_PI_2,
                                0.0,
                            ),
                        ) * Translation3::new(0.0, 0.0, -bottle.height_m / 2.0)
                    } else {
                        Isometry3::from_parts(Translation3::new(p.xy[0], p.xy[1], belt_top_z), yaw)
                    };
                    bottle_obstacle(bottle, &world_from_bottle, p.lying, 0.004)
                })
                .collect();
            Percept {
                part_type: PartTypeId(0),
                part_xy: xy,
                part_outer_radius_m: 0.02,
                part_height_m: 0.05,
                roundness_mm: None,
                bore_diameter_mm: None,
                inconsistency: None,
                unidentified: None,
                obstacles,
            }
        })
        .collect()
}

/// The search's time per percept (the fastest of 3 runs of each), its median and maximum over
/// the percepts, and what it chose: criterion's figure below is their mean.
fn print_per_trial(
    planner: &PickPlanner,
    percepts: &[Percept],
    checkers: &[twincell::planning::CollisionChecker],
    home: &JointVector,
) {
    let mut times_ms: Vec<f64> = Vec::new();
    let mut clear = 0;
    for (percept, checker) in percepts.iter().zip(checkers) {
        let mut fastest = f64::INFINITY;
        for _ in 0..3 {
            let start = std::time::Instant::now();
            let ranking = GraspSearch::new(planner, percept, checker, home).rank();
            fastest = fastest.min(start.elapsed().as_secs_f64() * 1e3);
            black_box(&ranking);
        }
        times_ms.push(fastest);
        clear += usize::from(planner.plan_pick(percept, checker, home).is_ok());
    }
    times_ms.sort_by(f64::total_cmp);
    let median = times_ms[times_ms.len() / 2];
    let max = times_ms[times_ms.len() - 1];
    println!(
        "grasp search over {} clutter percepts: median {median:.2} ms, max {max:.2} ms; \
         {clear} with a pick clear of the margin",
        percepts.len()
    );
}

fn planning_benches<M: Measurement>(group: &mut BenchmarkGroup<'_, M>) {
    let paper = scenario("scenarios/paper_50.toml");
    let planner = planner(&paper);
    let home: JointVector = paper.robot.home_q_rad;
    let mut free = scenario("scenarios/suite/clutter.toml");
    let clutter = percepts(&free, planner.belt_top_z, 24);
    free.bottle.count_range = [0, 0];
    let free = percepts(&free, planner.belt_top_z, 1);
    let checkers: Vec<_> = clutter.iter().map(|p| planner.checker_for(p)).collect();
    print_per_trial(&planner, &clutter, &checkers, &home);
    let mut k = 0;
    group.bench_function("grasp_search_clutter", |b| {
        b.iter(|| {
            k = (k + 1) % clutter.len();
            let search = GraspSearch::new(&planner, &clutter[k], &checkers[k], &home);
            black_box(search.rank().candidates)
        })
    });
    group.bench_function("plan_pick_clutter", |b| {
        b.iter(|| {
            k = (k + 1) % clutter.len();
            black_box(planner.plan_pick(&clutter[k], &checkers[k], &home).is_ok())
        })
    });
    let free_checker = planner.checker_for(&free[0]);
    group.bench_function("plan_pick_free_part", |b| {
        b.iter(|| black_box(planner.plan_pick(&free[0], &free_checker, &home).is_ok()))
    });
}

fn wall_benches(c: &mut Criterion) {
    let mut group = c.benchmark_group("planning");
    group.sample_size(20);
    planning_benches(&mut group);
    group.finish();
}

fn cpu_benches(c: &mut Criterion<ProcessCpuTime>) {
    let mut group = c.benchmark_group("planning_cpu");
    group.sample_size(20);
    planning_benches(&mut group);
    group.finish();
}

criterion_group!(benches, wall_benches);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(ProcessCpuTime);
    targets = cpu_benches
}
criterion_main!(benches, cpu);
