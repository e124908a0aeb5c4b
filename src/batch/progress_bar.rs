//! A one-line progress bar on stderr, drawn only when stderr is a terminal.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

const WIDTH: usize = 30;
const REDRAW_EVERY: Duration = Duration::from_millis(100);

/// Trials done out of planned, with failures, rate and time left; silent off a terminal.
#[derive(Debug)]
pub(crate) struct ProgressBar {
    total: usize,
    enabled: bool,
    start: Instant,
    last_draw: Option<Instant>,
}

impl ProgressBar {
    /// A bar for `total` trials; drawn only if `wanted` and stderr is a terminal.
    pub(crate) fn new(total: usize, wanted: bool) -> Self {
        Self {
            total,
            enabled: wanted && std::io::stderr().is_terminal(),
            start: Instant::now(),
            last_draw: None,
        }
    }

    /// Redraws with `done` trials finished, `failed` of them failed (at most ten times a second).
    pub(crate) fn update(&mut self, done: usize, failed: usize) {
        if !self.enabled {
            return;
        }
        let now = Instant::now();
        if done < self.total && self.last_draw.is_some_and(|t| now - t < REDRAW_EVERY) {
            return;
        }
        self.last_draw = Some(now);
        let elapsed_s = (now - self.start).as_secs_f64();
        let filled = (WIDTH * done).checked_div(self.total).unwrap_or(WIDTH);
        let rate = if elapsed_s > 0.0 {
            done as f64 / elapsed_s
        } else {
            0.0
        };
        let eta = if rate > 0.0 {
            format!("{:.0}s", (self.total - done.min(self.total)) as f64 / rate)
        } else {
            "?".to_owned()
        };
        let line = format!(
            "\r[{}{}] {done}/{} trials, {failed} failed, {rate:.1}/s, eta {eta}\x1b[K",
            "#".repeat(filled),
            "-".repeat(WIDTH - filled),
            self.total
        );
        let mut stderr = std::io::stderr().lock();
        // A progress bar that cannot be drawn is not worth failing a batch for.
        let _ = stderr.write_all(line.as_bytes());
        let _ = stderr.flush();
    }

    /// Clears the bar so the summary starts on a clean line.
    pub(crate) fn finish(&mut self) {
        if self.enabled && self.last_draw.is_some() {
            let mut stderr = std::io::stderr().lock();
            let _ = stderr.write_all(b"\r\x1b[K");
            let _ = stderr.flush();
        }
    }
}
