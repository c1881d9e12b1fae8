//! A checkpoint: the whole state of a run at the end of one step (particles with every
//! field, material and physics state, the clock, the run's running figures), so that a
//! run continued from it gives the same results, bit for bit, as one never interrupted.
//! The core fills and reads it; `mpm-io` stores it in the result store.

use std::collections::BTreeMap;

/// Format of the checkpoint layout; a store written by another layout is refused.
pub const CHECKPOINT_FORMAT: u32 = 1;

/// The state of a run: named arrays of numbers (kept exactly) and structured state as JSON
/// (references, tables; JSON numbers round-trip exactly with serde_json's
/// `float_roundtrip`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Checkpoint {
    /// Particle fields, grid-node state and the run's scalars, by name.
    pub arrays: BTreeMap<String, Vec<f64>>,
    /// Everything else, as JSON.
    pub state: serde_json::Value,
}

/// A checkpoint that does not fit the run resumed from it.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// An array the run needs is not there.
    #[error("the checkpoint has no array `{0}`")]
    Missing(String),
    /// An array of the wrong length.
    #[error("the checkpoint's array `{name}` has {found} numbers where this run needs {expected}")]
    Length {
        /// Array name.
        name: String,
        /// Numbers needed.
        expected: usize,
        /// Numbers found.
        found: usize,
    },
    /// Anything else that does not fit.
    #[error("the checkpoint does not fit this run: {0}")]
    Invalid(String),
}

impl Checkpoint {
    /// Stores an array under `name`.
    pub fn put(&mut self, name: impl Into<String>, values: Vec<f64>) {
        self.arrays.insert(name.into(), values);
    }

    /// The array `name`, which must hold `len` numbers.
    pub fn get(&self, name: &str, len: usize) -> Result<&[f64], CheckpointError> {
        let values = self
            .arrays
            .get(name)
            .ok_or_else(|| CheckpointError::Missing(name.into()))?;
        if values.len() != len {
            return Err(CheckpointError::Length {
                name: name.into(),
                expected: len,
                found: values.len(),
            });
        }
        Ok(values)
    }

    /// The array of scalars `name`, to read in the order it was written.
    pub fn scalars(&self, name: &str) -> Result<Scalars, CheckpointError> {
        let values = self
            .arrays
            .get(name)
            .ok_or_else(|| CheckpointError::Missing(name.into()))?;
        Ok(Scalars::reading(values))
    }

    /// A JSON member of the structured state (`Null` when absent).
    pub fn state(&self, key: &str) -> &serde_json::Value {
        self.state.get(key).unwrap_or(&serde_json::Value::Null)
    }

    /// Sets a JSON member of the structured state.
    pub fn set_state(&mut self, key: &str, value: serde_json::Value) {
        if !self.state.is_object() {
            self.state = serde_json::Value::Object(serde_json::Map::new());
        }
        if let Some(map) = self.state.as_object_mut() {
            map.insert(key.into(), value);
        }
    }
}

/// Writes named scalars into one array, in order, and reads them back the same way: the
/// run's clock, statistics and running figures.
#[derive(Default)]
pub struct Scalars {
    values: Vec<f64>,
    at: usize,
}

impl Scalars {
    /// An empty list to push into.
    pub fn new() -> Self {
        Self::default()
    }

    /// A list to read from, in the order it was written.
    pub fn reading(values: &[f64]) -> Self {
        Self {
            values: values.to_vec(),
            at: 0,
        }
    }

    /// Appends numbers.
    pub fn push(&mut self, values: &[f64]) {
        self.values.extend_from_slice(values);
    }

    /// The next number.
    pub fn take(&mut self) -> Result<f64, CheckpointError> {
        let v =
            self.values.get(self.at).copied().ok_or_else(|| {
                CheckpointError::Invalid("the list of scalars ended early".into())
            })?;
        self.at += 1;
        Ok(v)
    }

    /// The next `N` numbers.
    pub fn take_n<const N: usize>(&mut self) -> Result<[f64; N], CheckpointError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.take()?;
        }
        Ok(out)
    }

    /// The numbers written.
    pub fn into_vec(self) -> Vec<f64> {
        self.values
    }
}
