//! Forward and inverse kinematics timings (`cargo bench --bench kinematics`).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use twincell::kinematics::{AnalyticIk, ArmModel, IkSolver, flange_pose, geometric_jacobian};
use twincell::rng::SimRng;

fn poses(arm: &ArmModel, n: usize) -> (Vec<[f64; 6]>, Vec<nalgebra::Isometry3<f64>>) {
    let mut rng = SimRng::new(1);
    let qs: Vec<[f64; 6]> = (0..n)
        .map(|_| std::array::from_fn(|i| rng.range(arm.limits[i].min_rad, arm.limits[i].max_rad)))
        .collect();
    let targets = qs.iter().map(|q| flange_pose(arm, q)).collect();
    (qs, targets)
}

fn kinematics(c: &mut Criterion) {
    let arm = ArmModel::aubo_i5();
    let ik = AnalyticIk::new(arm.clone()).expect("AUBO geometry");
    let (qs, targets) = poses(&arm, 1024);
    let mut i = 0;
    c.bench_function("fk_flange", |b| {
        b.iter(|| {
            i = (i + 1) % qs.len();
            black_box(flange_pose(&arm, black_box(&qs[i])))
        })
    });
    c.bench_function("ik_full_solve", |b| {
        b.iter(|| {
            i = (i + 1) % targets.len();
            black_box(ik.solve(black_box(&targets[i])))
        })
    });
    c.bench_function("jacobian", |b| {
        b.iter(|| {
            i = (i + 1) % qs.len();
            black_box(geometric_jacobian(&arm, black_box(&qs[i])))
        })
    });
}

criterion_group!(benches, kinematics);
criterion_main!(benches);
