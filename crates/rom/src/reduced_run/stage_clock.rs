//! Where a reduced run's wall time goes: seconds per part of the reduced step and for the
//! frames, reported as the run's `metrics.stage_seconds` (as a full run reports its own).

use std::time::Instant;

/// The parts of a reduced step, in the order the step runs them, then the frames.
#[derive(Clone, Copy, Debug)]
pub(super) enum RomStage {
    /// The samples' positions and the quadrature particles around them (the map at every
    /// candidate).
    Neighbourhood,
    /// F, velocity and affine velocity of the quadrature particles from the map.
    Kinematics,
    /// The materials' stress at the quadrature particles.
    Stress,
    /// P2G over the quadrature particles, the clearing of the grid included.
    P2g,
    /// The core's grid update (forces, damping, walls, obstacles) over the grid.
    GridUpdate,
    /// G2P to the samples.
    G2p,
    /// Least squares of the samples' new state onto the map.
    Projection,
    /// Frames: the map at every particle, and the writing.
    Frames,
}

/// The names of the [`RomStage`]s in `metrics.stage_seconds`, in the order a step runs
/// them.
pub const ROM_STAGES: [&str; 8] = [
    "neighbourhood",
    "kinematics",
    "stress",
    "p2g",
    "grid_update",
    "g2p",
    "projection",
    "frames",
];

/// Seconds spent in each [`RomStage`] so far.
#[derive(Clone, Debug, Default)]
pub(super) struct RomClock {
    seconds: [f64; ROM_STAGES.len()],
}

impl RomClock {
    /// Adds the time since `start` to `stage` and returns now, the next part's start.
    pub(super) fn lap(&mut self, stage: RomStage, start: Instant) -> Instant {
        let now = Instant::now();
        self.seconds[stage as usize] += (now - start).as_secs_f64();
        now
    }

    /// The seconds by stage name, for `Metrics::stage_seconds`.
    pub(super) fn by_name(&self) -> std::collections::BTreeMap<String, f64> {
        ROM_STAGES
            .iter()
            .zip(self.seconds)
            .map(|(name, s)| (name.to_string(), s))
            .collect()
    }
}
