//! CPU time as a criterion measurement, shared by the benches that report it.

use criterion::measurement::{Measurement, ValueFormatter, WallTime};

/// CPU time of the whole process (all its threads), from Linux's per-thread scheduler
/// statistics, in nanoseconds.
pub struct ProcessCpuTime;

fn process_cpu_ns() -> u64 {
    let tasks = match std::fs::read_dir("/proc/self/task") {
        Ok(tasks) => tasks,
        Err(e) => panic!("the CPU-time bench needs Linux: /proc/self/task: {e}"),
    };
    tasks
        .flatten()
        .filter_map(|task| std::fs::read_to_string(task.path().join("schedstat")).ok())
        .filter_map(|stat| stat.split(' ').next()?.parse::<u64>().ok())
        .sum()
}

impl Measurement for ProcessCpuTime {
    type Intermediate = u64;
    type Value = u64;

    fn start(&self) -> u64 {
        process_cpu_ns()
    }
    fn end(&self, start: u64) -> u64 {
        process_cpu_ns().saturating_sub(start)
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, value: &u64) -> f64 {
        *value as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        // Nanoseconds, shown as durations.
        static WALL: WallTime = WallTime;
        WALL.formatter()
    }
}
