//! What a stability case is: its scene, the outcome it must have and an optional physics
//! check of its own on the run's frames, kept in memory. The case lists
//! (`stability.rs`, `stability_cohesive.rs`, `stability_implicit.rs`, `stability_peer.rs`)
//! build cases; the runner in `stability.rs` runs them. Nothing here imports either.

use mpm_core::output::{
    FRAME_DIAGNOSTICS, FieldInfo, Frame, Metrics, OutputError, OutputSink, RunInfo,
};
use serde::Serialize;
use serde_json::Value;

/// How a case must end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Expected {
    /// Runs to its end time.
    Finished,
    /// Stops itself with a diagnostic, without writing NaN.
    Stopped,
    /// Refused before the first step (a time step past stability).
    Refused,
}

/// One case of the suite.
pub struct Case {
    /// Short name.
    pub name: &'static str,
    /// What it exercises.
    pub what: &'static str,
    /// The scene.
    pub scene: Value,
    /// The outcome it must have.
    pub expected: Expected,
    /// A physics check of its own on the finished run's frames (the peer cases'), or on a
    /// stopped run's, for a case that must stop (why it stopped).
    pub check: Option<Check>,
}

impl Case {
    /// Whether the case's transfer keeps angular momentum (APIC, the default).
    pub(crate) fn keeps_angular_momentum(&self) -> bool {
        self.scene["solver"]["transfer"]
            .as_str()
            .is_none_or(|t| t == "apic")
    }
}

/// A case's own physics check on its finished run's metrics and frames: the measured
/// figure (for the note), or what is wrong.
pub type Check = fn(&Metrics, &Frames) -> Result<String, String>;

/// A run's output frames, kept in memory for a case's check.
#[derive(Default)]
pub struct Frames {
    /// The fields each frame carries, in order.
    pub fields: Vec<FieldInfo>,
    /// Every frame: its time, its field values and its diagnostics ([`FRAME_DIAGNOSTICS`]).
    pub frames: Vec<(f64, Vec<Vec<f64>>, Vec<f64>)>,
}

impl Frames {
    /// Field `name` of frame `index` (particle-major), if the run stored it.
    pub fn field(&self, index: usize, name: &str) -> Option<&[f64]> {
        let f = self.fields.iter().position(|f| f.name == name)?;
        Some(self.frames.get(index)?.1.get(f)?.as_slice())
    }

    /// Diagnostic `name` of frame `index`.
    pub fn diagnostic(&self, index: usize, name: &str) -> Option<f64> {
        let d = FRAME_DIAGNOSTICS.iter().position(|d| *d == name)?;
        self.frames.get(index)?.2.get(d).copied()
    }

    /// Field `name` of the first and of the last frame.
    pub(crate) fn first_and_last(&self, name: &str) -> Result<(&[f64], &[f64]), String> {
        let last = self.frames.len().checked_sub(1);
        match (self.field(0, name), last.and_then(|l| self.field(l, name))) {
            (Some(a), Some(b)) if a.len() == b.len() => Ok((a, b)),
            _ => Err(format!("the run kept no `{name}` frames to check")),
        }
    }
}

impl OutputSink for Frames {
    fn begin(&mut self, info: &RunInfo<'_>) -> Result<(), OutputError> {
        self.fields = info.fields.to_vec();
        self.frames.clear();
        Ok(())
    }
    fn write_frame(&mut self, frame: &Frame<'_>) -> Result<(), OutputError> {
        self.frames.push((
            frame.time,
            frame.values.to_vec(),
            frame.diagnostics.to_vec(),
        ));
        Ok(())
    }
    fn finish(&mut self, _: &Metrics) -> Result<(), OutputError> {
        Ok(())
    }
}
