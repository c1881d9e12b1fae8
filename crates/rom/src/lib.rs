//! Reduced-order MPM after Chen et al., "Model reduction for the material point method on
//! nonlinear manifolds": the whole deformation map is approximated as x = g(X, q), a
//! function of the reference position X and a few generalised coordinates q(t), learnt from
//! full-order runs; a run then advances q with ordinary MPM updates at a few sampled points
//! (hyper-reduction) and projects the result back onto the map.
//!
//! - [`snapshots`] reads the training runs (result stores) into displacement snapshots.
//! - [`pod`] and [`mode_field`] build the linear map: POD modes as continuous fields of X.
//! - [`neural`] builds the nonlinear map: a small network trained with candle.
//! - [`model`] stores either map in one safetensors file and checks it against a scene.
//! - [`reduced_run`] is the hyper-reduced time stepper; [`compare`] the position error
//!   between two result stores.

pub mod compare;
pub mod file;
pub mod map;
pub mod mode_field;
pub mod model;
pub mod neural;
pub mod pod;
pub mod reduced_run;
pub mod snapshots;

pub use map::{PointMap, ReducedMap};
pub use model::{Model, ModelInfo, ModelKind};

/// Failures of training, loading or running a reduced model.
#[derive(Debug, thiserror::Error)]
pub enum RomError {
    /// A result store could not be read.
    #[error(transparent)]
    Store(#[from] mpm_io::IoError),
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
    /// The training runs cannot be used together, or hold too little.
    #[error("training runs: {0}")]
    Training(String),
    /// The model file is not a reduced model this program wrote, or is damaged.
    #[error("model {path}: {message}")]
    BadModel {
        /// The model file.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    /// The scene does not fit the model (dimension, domain, material, physics).
    #[error("{path}: {message}")]
    Mismatch {
        /// JSON path in the scene (or the option) at fault.
        path: String,
        /// Why the model cannot run it.
        message: String,
    },
    /// An option is out of range.
    #[error("{0}")]
    Option(String),
    /// The neural-network library failed.
    #[error("neural network: {0}")]
    Network(String),
    /// The result writer failed.
    #[error(transparent)]
    Output(#[from] mpm_core::output::OutputError),
}

impl From<candle_core::Error> for RomError {
    fn from(e: candle_core::Error) -> Self {
        RomError::Network(e.to_string())
    }
}
