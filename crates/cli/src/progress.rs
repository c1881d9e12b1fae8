//! Progress reporting for `mpm run`: a bar on a terminal, plain lines otherwise.

use indicatif::{ProgressBar, ProgressStyle};
use mpm_core::solver::{Control, Progress, RunObserver};
use std::io::IsTerminal;

/// Shows progress at a bounded rate.
pub struct ProgressReporter {
    bar: Option<ProgressBar>,
    next_line_fraction: f64,
    quiet: bool,
    /// The end time and start time of the run or stage being reported: a staged run's
    /// stages each count from 0 to 100%.
    span: (f64, f64),
}

impl ProgressReporter {
    /// A bar when stderr is a terminal; lines every 10% otherwise; nothing when quiet.
    pub fn new(quiet: bool) -> Self {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let bar = ProgressBar::new(1000);
            bar.set_style(
                ProgressStyle::with_template(
                    "{bar:40} {percent:>3}% {msg} [{elapsed_precise} < {eta_precise}]",
                )
                .expect("valid template"),
            );
            bar
        });
        Self {
            bar,
            next_line_fraction: 0.1,
            quiet,
            span: (f64::NAN, 0.0),
        }
    }

    /// Clears the bar.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

impl RunObserver for ProgressReporter {
    fn progress(&mut self, p: &Progress) -> Control {
        if p.end_time != self.span.0 {
            // A new stage (or the run's first step): count from where its first step began.
            self.span = (p.end_time, p.time - p.dt);
            self.next_line_fraction = 0.1;
        }
        let (end, start) = self.span;
        let fraction = if end > start {
            ((p.time - start) / (end - start)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        if let Some(bar) = &self.bar {
            if p.step.is_multiple_of(16) || fraction >= 1.0 {
                bar.set_position((fraction * 1000.0) as u64);
                bar.set_message(format!(
                    "t = {:.4e} s, step {}, dt = {:.2e} s",
                    p.time, p.step, p.dt
                ));
            }
        } else if !self.quiet && fraction + 1e-12 >= self.next_line_fraction {
            eprintln!(
                "progress {:>3.0}%  t = {:.4e} s  step {}  dt = {:.2e} s  wall {:.1} s",
                fraction * 100.0,
                p.time,
                p.step,
                p.dt,
                p.wall_seconds
            );
            while self.next_line_fraction <= fraction + 1e-12 {
                self.next_line_fraction += 0.1;
            }
        }
        Control::Continue
    }
}
