//! Cell physics timings (`cargo bench --bench cell`): one step of the world with the arm, the
//! belt and ten parts, and one whole oracle trial of `paper_50`, also as the physics ran it
//! before the pads' stiction (8 substeps near the arm, plain Coulomb friction on the pads).
//!
//! The step is measured three ways in the same run, so that a change of the solver schedule
//! is compared on one machine under one load: `physics_step_arm_ten_parts` with the world's
//! defaults (nothing is near the arm, so the free substeps), `..._free_4_substeps` with the
//! schedule before issue 15's cut (4 free substeps, predicted contacts counted), and
//! `..._8_substeps` with 8 substeps every step (the schedule before that). The
//! physics real-time factor per core is (1/240 s) / (time per step).
//!
//! Group `cell` measures wall-clock time; group `cell_cpu` measures the same three steps by the
//! process's CPU time, which a machine shared with other jobs inflates far less.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::measurement::Measurement;
use criterion::{BenchmarkGroup, Criterion, SamplingMode, criterion_group, criterion_main};
use rapier3d::prelude::*;
use twincell::batch::{Perception, TrialRunner, trial_seed};
use twincell::cell::{Cell, CellModel};
use twincell::rng::SimRng;
use twincell::scenario::Scenario;
use twincell::task::CellTrialRunner;

#[path = "common/cpu_time.rs"]
mod cpu_time;
use cpu_time::ProcessCpuTime;

fn scenario() -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper_50.toml");
    match Scenario::load(&path) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

/// The cell with the arm at home and nine more tubes on the belt, spaced along it (ten parts
/// in all), the belt running.
fn loaded_cell(scenario: &Scenario) -> Cell {
    let mut rng = SimRng::new(1);
    let Ok(mut cell) = Cell::build(
        &CellModel::with_urdf(scenario.clone(), None).expect("model"),
        &mut rng,
    ) else {
        panic!("cell builds")
    };
    let physics = &mut cell.world.physics;
    for i in 0..9 {
        let x = -0.7 + 0.09 * f64::from(i);
        let body = physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(Vector::new(x as f32, -0.45, 0.74))
                .can_sleep(false),
        );
        physics.colliders.insert_with_parent(
            ColliderBuilder::cylinder(0.04, 0.024)
                .rotation(Vector::new(std::f32::consts::FRAC_PI_2, 0.0, 0.0))
                .mass(0.6),
            body,
            &mut physics.bodies,
        );
    }
    cell.conveyor.set_speed_m_s(0.05);
    cell
}

/// One step of the loaded cell under each solver schedule: the world's defaults, the schedule
/// before issue 15's cut (4 free substeps, predicted contacts counted, 8 near the arm) and 8
/// substeps every step (the scenario's count before that, and until the pads' stiction).
fn step_benches<M: Measurement>(group: &mut BenchmarkGroup<'_, M>, scenario: &Scenario) {
    let schedules = [
        ("physics_step_arm_ten_parts", None),
        (
            "physics_step_arm_ten_parts_free_4_substeps",
            Some((8, 4, f64::INFINITY)),
        ),
        (
            "physics_step_arm_ten_parts_8_substeps",
            Some((8, 8, f64::INFINITY)),
        ),
    ];
    for (name, schedule) in schedules {
        let mut cell = loaded_cell(scenario);
        if let Some((full, free, margin)) = schedule {
            cell.world.set_solver_schedule(full, free, margin);
        }
        group.bench_function(name, |b| {
            b.iter(|| {
                cell.step();
                black_box(cell.world.time_s())
            })
        });
    }
}

fn cell_benches(c: &mut Criterion) {
    let scenario = scenario();
    let mut group = c.benchmark_group("cell");
    group.measurement_time(Duration::from_secs(5));
    step_benches(&mut group, &scenario);
    let runner = match CellTrialRunner::new(
        scenario.clone(),
        Path::new("paper_50.toml"),
        Perception::Oracle,
    ) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    group.sample_size(10);
    // The same trials as the physics ran them before the pads' stiction: 8 substeps near the
    // arm, plain Coulomb friction on the pads.
    let mut before = scenario.clone();
    before.physics.solver_iterations = 8;
    before.gripper.pad_preslide_mm = 0.0;
    let runner_before =
        match CellTrialRunner::new(before, Path::new("paper_50.toml"), Perception::Oracle) {
            Ok(r) => r,
            Err(e) => panic!("{e}"),
        };
    for (name, runner) in [
        ("paper_50_oracle_trial", &runner),
        (
            "paper_50_oracle_trial_8_substeps_no_stiction",
            &runner_before,
        ),
    ] {
        group.bench_function(name, |b| {
            let mut index = 0;
            b.iter(|| {
                index = (index + 1) % scenario.trials;
                black_box(runner.run_trial(index, trial_seed(scenario.seed, index)))
            })
        });
    }
    group.finish();
}

fn cpu_benches(c: &mut Criterion<ProcessCpuTime>) {
    let scenario = scenario();
    let mut group = c.benchmark_group("cell_cpu");
    group.measurement_time(Duration::from_secs(5));
    // Linux updates a running thread's CPU time at scheduler ticks (4 ms): equal samples of
    // many steps each, rather than criterion's ramp from one step up.
    group.sampling_mode(SamplingMode::Flat);
    step_benches(&mut group, &scenario);
    group.finish();
}

criterion_group!(benches, cell_benches);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(ProcessCpuTime);
    targets = cpu_benches
}
criterion_main!(benches, cpu);
