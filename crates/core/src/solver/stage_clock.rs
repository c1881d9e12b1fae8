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
    /// Averaging a material's state over its length (nonlocal damage), after the step.
    StateAverage,
    /// The rest of the time-integration mode's step: the implicit mode's Newton–Krylov
    /// solve, the incompressible mode's projection; for an explicit step, clearing the grid
    /// and the contact laws.
    Solve,
}

/// Names of the stages in `metrics.stage_seconds`, in step order.
pub const NAMES: [&str; 10] = [
    "sort",
    "bin",
    "p2g",
    "grid_update",
    "g2p",
    "volume_average",
    "physics",
    "stress",
    "state_average",
    "solve",
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

    /// Adds `seconds` to `stage`.
    #[inline]
    pub fn add_seconds(&mut self, stage: StepStage, seconds: f64) {
        self.seconds[stage as usize] += seconds;
    }

    /// Seconds of every stage together.
    pub fn total(&self) -> f64 {
        self.seconds.iter().sum()
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
