//! Progress of the long commands on stderr: items done of the total, the
//! rate and the time left. On a terminal it is a bar redrawn in place; in a
//! log (a batch system's output file, a pipe) it is one plain line at most
//! every [`LINE_INTERVAL`] and one at the end, e.g.
//!
//! ```text
//! vtsm: 36/108 trials (12 done before), 0.42 trials/s, 2m51s left
//! ```
//!
//! The rate and the time left count only the items done by this process, so
//! a resumed run does not report the earlier run's work as its speed.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Least time between two progress lines in a log.
pub const LINE_INTERVAL: Duration = Duration::from_secs(10);

/// Counts when writing plain lines.
struct Lines {
    done: u64,
    last: Instant,
}

/// A progress report of `total` items.
pub struct Progress {
    bar: ProgressBar,
    lines: Option<Mutex<Lines>>,
    total: u64,
    before: u64,
    unit: &'static str,
    start: Instant,
}

impl Progress {
    /// A report of `total` items named `unit` (plural), `before` of them
    /// done by an earlier run; nothing is shown unless `enabled`.
    pub fn new(total: u64, before: u64, unit: &'static str, enabled: bool) -> Self {
        let terminal = enabled && std::io::stderr().is_terminal();
        let bar = if terminal {
            let b = ProgressBar::new(total).with_position(before);
            if let Ok(style) = ProgressStyle::with_template(&format!(
                "{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {unit} ({{per_sec}}, {{eta}} left)"
            )) {
                b.set_style(style.progress_chars("=> "));
            }
            b.reset_eta();
            b
        } else {
            ProgressBar::hidden()
        };
        let start = Instant::now();
        let lines = (enabled && !terminal).then(|| {
            Mutex::new(Lines {
                done: before,
                last: start,
            })
        });
        Self {
            bar,
            lines,
            total,
            before,
            unit,
            start,
        }
    }

    /// One more item done.
    pub fn inc(&self) {
        self.bar.inc(1);
        if let Some(m) = &self.lines {
            let Ok(mut l) = m.lock() else { return };
            l.done += 1;
            let now = Instant::now();
            if now.duration_since(l.last) >= LINE_INTERVAL || l.done == self.total {
                l.last = now;
                eprintln!("vtsm: {}", self.line(l.done, now));
            }
        }
    }

    /// The plain line for `done` items at `now`.
    fn line(&self, done: u64, now: Instant) -> String {
        let ran = done.saturating_sub(self.before);
        let secs = now.duration_since(self.start).as_secs_f64();
        let before = if self.before > 0 {
            format!(" ({} done before)", self.before)
        } else {
            String::new()
        };
        let rate = if secs > 0.0 { ran as f64 / secs } else { 0.0 };
        let left = if rate > 0.0 {
            let s = (self.total.saturating_sub(done) as f64 / rate).round() as u64;
            format!("{}m{:02}s left", s / 60, s % 60)
        } else {
            "time left unknown".to_string()
        };
        format!(
            "{done}/{} {}{before}, {rate:.2} {}/s, {left}",
            self.total, self.unit, self.unit
        )
    }

    /// Run `f` with the bar hidden (to print a line of output).
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.bar.suspend(f)
    }

    /// Clear the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_counts_only_this_runs_items_in_its_rate() {
        let p = Progress::new(100, 40, "trials", false);
        let line = p.line(50, p.start + Duration::from_secs(20));
        assert_eq!(
            line,
            "50/100 trials (40 done before), 0.50 trials/s, 1m40s left"
        );
        let fresh = Progress::new(10, 0, "pairs", false);
        assert_eq!(
            fresh.line(0, fresh.start),
            "0/10 pairs, 0.00 pairs/s, time left unknown"
        );
    }
}
