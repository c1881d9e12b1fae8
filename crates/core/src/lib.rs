//! Solver core of the `mpm` material point method simulator.
//!
//! The core knows no plugin: materials come in through [`plugin::Registry`]. Hot loops are
//! generic over the dimension and the kernel; particle data is structure-of-arrays. See
//! `docs/ARCHITECTURE.md` for the step pipeline.

pub mod boundary;
mod cell_hash;
pub mod checkpoint;
pub mod damage_measures;
pub mod energy_ledger;
pub mod fatigue_measures;
pub mod grid;
pub mod grid_activity;
pub mod kernels;
pub mod linear_solvers;
pub mod log_strain;
pub mod material;
pub mod math;
pub mod output;
pub mod paged;
pub mod particles;
pub mod physics;
pub mod plugin;
pub mod reference;
pub mod refinement;
pub mod scene;
pub mod section;
pub mod solver;
pub mod stress_measures;

/// Version of this crate, stored with every result.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
