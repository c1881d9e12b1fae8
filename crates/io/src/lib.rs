//! Result stores of mpm runs: a Zarr v3 writer (one store per run), a reader for particles
//! and metadata, and a VTK exporter for ParaView. Knows no physics: it stores what the core
//! hands it.
//!
//! Layout of a store:
//! - `time`: float64 `[frame]`
//! - `particles/<field>`: float64 `[frame, particle, components...]`, one chunk per frame,
//!   zstd-compressed
//! - `diagnostics/<name>`: float64 `[frame]` (energies, max speed, min det F, dt, step)
//! - `tables/<name>`: float64 `[row, column]`, one chunk, attribute `columns` (tables the
//!   physics operators kept, such as voids; the group exists only when there are tables)
//! - `stages/<index>-<name>/...`: in a staged run, each stage's `time`, `particles`,
//!   `diagnostics`, `tables` (instead of the root's), its scene and metrics as attributes;
//!   with `output.end_state` or `output.checkpoint`, also `end_state/<array>`, the state the stage finished with
//!   (a checkpoint's layout), from which `mpm run SCENE --from STORE --stage NEXT` starts
//! - `checkpoints/<step>/<array>`: float64 `[index]`, the latest checkpoint (only with
//!   `output.checkpoint`), its structured state in the group attribute `state`
//! - root attributes: `scene`, `mpm_version`, `dimension`, `particles`, `metrics`,
//!   `checkpoint` (where the latest checkpoint is, its step, time and frames)

mod checkpoint_store;
pub mod start_from;
mod vtk;
mod zarr_reader;
mod zarr_writer;

pub use checkpoint_store::{STAGE_END, read_checkpoint, read_stage_end};
pub use vtk::export_vtk;
pub use zarr_reader::{ResultStore, TableData, read_particles};
pub use zarr_writer::ZarrSink;

/// Failures reading or writing result stores.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// A filesystem operation failed.
    #[error("{path}: {source}")]
    File {
        /// The path involved.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The Zarr library reported a problem.
    #[error("zarr store {path}: {message}")]
    Zarr {
        /// Store path.
        path: String,
        /// What went wrong.
        message: String,
    },
    /// The store is not one this program wrote, or is damaged.
    #[error("{path}: {message}")]
    Layout {
        /// Store path.
        path: String,
        /// What is missing or wrong.
        message: String,
    },
}
