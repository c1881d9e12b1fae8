//! Local refinement: a grid with levels, each halving the spacing of the one above it over
//! a nested region, and the truncated hierarchical B-spline (THB) basis on it
//! (Giannelli, Jüttler & Speleers 2012), which keeps partition of unity and stays
//! non-negative across level boundaries, so the transfers keep mass and momentum.
//!
//! Built so far: the levels (levels.rs), the basis (thb.rs), checked against what the
//! solver needs of it (partition of unity, linear and quadratic reproduction, weights
//! ≥ 0), APIC transfers and the stress's force through it (transfer.rs), exact for an
//! affine velocity field across level boundaries, and the split and merge of particles
//! that cross one (split_merge.rs). Not yet: the solver's step on it (grid update, walls,
//! the grid solves), the split and merge inside a run, the scene section that names the
//! regions (docs/ARCHITECTURE.md, "Local refinement").

mod levels;
mod split_merge;
mod thb;
mod transfer;

pub use levels::{Levels, MAX_ELEMENTS, MAX_LEVELS};
pub use split_merge::{Kinematics, merge, merge_weights, split};
pub use thb::{ExtractionCache, ThbBasis, Weight};
pub use transfer::{
    LevelGrid, TransferScratch, grid_to_particles, internal_forces, particles_to_grid,
};

#[cfg(test)]
mod wave_check;

/// A small pseudo-random sequence in [0, 1) for the tests (an LCG; no dependency).
#[cfg(test)]
fn numbers(seed: u64, n: usize) -> Vec<f64> {
    let step = |s: u64| {
        s.wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407)
    };
    let mut s = step(seed);
    (0..n)
        .map(|_| {
            s = step(s);
            (s >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

/// What is wrong with a refinement's geometry or a point handed to its basis.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RefinementError {
    /// The base level's origin or spacing is not a finite number (spacing > 0).
    #[error("the base level's {0} must be finite (spacing > 0)")]
    Base(&'static str),
    /// The base level has no element along an axis, or more than `MAX_ELEMENTS` in all on
    /// some level.
    #[error(
        "level {level} would have {elements} elements (at least 1 per axis, at most {max} in all)"
    )]
    Elements {
        /// The level.
        level: usize,
        /// Its element count (0 if an axis has none).
        elements: u128,
        /// The limit.
        max: usize,
    },
    /// More levels than `MAX_LEVELS`.
    #[error("{0} refined levels named; at most {max} are allowed", max = levels::MAX_LEVELS)]
    TooManyLevels(usize),
    /// A region box with a coordinate that is not finite or a minimum above its maximum.
    #[error("level {level}, box {index}: min and max must be finite and min <= max")]
    Box {
        /// The refined level (1 for the first).
        level: usize,
        /// The box's index in that level's list.
        index: usize,
    },
    /// A point outside the base level's elements, or where the base level has no complete
    /// set of functions (within two elements of its edge).
    #[error("the point lies outside the basis's interior")]
    Outside,
}
