//! The extreme displacement of a point of a body over a run against a value read off a
//! published or finite-element curve: a cantilever's tip under a suddenly applied load
//! swings to its first peak, and the peak is what a reference curve pins down best.

use super::{Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory};
use crate::scene::{Issue, Scene};
use crate::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// The largest displacement (in the sign of `expected`) along `axis` of the mean of the
/// particles that start in a box, over the frames of the run; error: its relative
/// difference from `expected`.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PeakDisplacementParams {
    /// Lower corner of the box that picks the particles at time 0, m.
    pub min: Vec<f64>,
    /// Upper corner of the box, m.
    pub max: Vec<f64>,
    /// Axis of the displacement (0 = x).
    pub axis: usize,
    /// The peak displacement of the reference curve, m (signed: −0.66 is a peak downward).
    pub expected: f64,
    /// When the reference curve reaches its peak, s (compared, not part of the error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expected_time: Option<f64>,
    /// Where `expected` comes from, for people (a paper, a data file).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
}

/// The mean displacement of the picked particles, its extreme so far, and when.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct PeakDisplacement {
    min: Vec<f64>,
    max: Vec<f64>,
    axis: usize,
    expected: f64,
    expected_time: Option<f64>,
    peak: Option<f64>,
    peak_time: f64,
}

impl ReferenceLaw for PeakDisplacement {
    fn kind(&self) -> &'static str {
        "relative error of the peak displacement of the picked particles over the run"
    }

    fn needs_initial_positions(&self) -> bool {
        true
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let particles = frame.particles;
        let (mut sum, mut count) = (0.0, 0usize);
        for p in 0..particles.len() {
            let x0 = &particles.initial_position[p];
            let inside = (0..D).all(|d| x0[d] >= self.min[d] && x0[d] <= self.max[d]);
            if inside {
                sum += particles.position[p][self.axis] - x0[self.axis];
                count += 1;
            }
        }
        if count == 0 {
            return;
        }
        let mean = sum / count as f64;
        // The extreme in the direction of the expected peak.
        let further = self
            .peak
            .is_none_or(|peak| mean * self.expected.signum() > peak * self.expected.signum());
        if further {
            self.peak = Some(mean);
            self.peak_time = frame.time;
        }
    }

    fn error(&self) -> Option<f64> {
        let m = self.peak?;
        Some((m - self.expected).abs() / self.expected.abs())
    }

    fn expected(&self) -> Option<f64> {
        Some(self.expected)
    }

    fn measured(&self) -> Option<f64> {
        self.peak
    }

    fn comparisons(&self) -> Vec<super::Comparison> {
        let mut out = Vec::new();
        if let Some(m) = self.peak {
            out.push(super::compare("peak_displacement", m, self.expected));
            if let Some(t) = self.expected_time {
                out.push(super::compare("peak_time", self.peak_time, t));
            }
        }
        out
    }
}

fn build(
    p: PeakDisplacementParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let dim = scene.dimension as usize;
    let mut c = Checks::new(path);
    c.axis("axis", p.axis, dim);
    for (name, values) in [("min", &p.min), ("max", &p.max)] {
        if values.len() != dim || !values.iter().all(|v| v.is_finite()) {
            c.error(name, format!("must be {dim} finite numbers"));
        }
    }
    if p.expected == 0.0 || !p.expected.is_finite() {
        c.error("expected", "must be a finite number other than 0");
    }
    if let Some(t) = p.expected_time {
        c.positive("expected_time", t);
    }
    c.finish()?;
    Ok(Arc::new(PeakDisplacement {
        min: p.min,
        max: p.max,
        axis: p.axis,
        expected: p.expected,
        expected_time: p.expected_time,
        peak: None,
        peak_time: 0.0,
    }))
}

/// The `peak_displacement` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("peak_displacement", build))
}
