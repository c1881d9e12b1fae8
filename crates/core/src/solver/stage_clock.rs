//! Where a run's wall time goes: seconds spent in each stage of the step, summed over the
//! run (or, after a resume, over this process's part of it), reported as
//! `metrics.stage_seconds` and by `mpm bench`. Reading the clock costs tens of nanoseconds
//! per stage against milliseconds per step.

use std::collections::BTreeMap;
use std::time::Instant;

/// A timed stage of the step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StepStage {
    /// Reordering the particles by cell (every `solver.sort_interval` steps).
    Sort,
    /// Binning the particles into the slabs of P2G.
    Bin,
    /// Particle to grid.
    P2g,
    /// Momentum to velocity, forces, walls and obstacles.
    GridUpdate,
    /// Grid to particle.
    G2p,
    /// F-bar's volume averaging.
    VolumeAverage,
    /// The physics operators (thermal, phase change, underfill, ...).
    Physics,
    /// The materials' stress update.
    Stress,
}

/// Names of the stages in `metrics.stage_seconds`, in [`StepStage`] order.
const NAMES: [&str; 8] = [
    "sort",
    "bin",
    "p2g",
    "grid_update",
    "g2p",
    "volume_average",
    "physics",
    "stress",
];

/// Seconds per stage.
#[derive(Clone, Debug, Default)]
pub(crate) struct StageClock {
    seconds: [f64; NAMES.len()],
}

impl StageClock {
    /// Adds the time since `start` to `stage`.
    #[inline]
    pub fn add(&mut self, stage: StepStage, start: Instant) {
        self.seconds[stage as usize] += start.elapsed().as_secs_f64();
    }

    /// The stages that took any time, by name.
    pub fn figures(&self) -> BTreeMap<String, f64> {
        NAMES
            .iter()
            .zip(self.seconds)
            .filter(|(_, s)| *s > 0.0)
            .map(|(n, s)| (n.to_string(), s))
            .collect()
    }
}
