//! What every section check writes to: the problems found so far, each at its JSON path,
//! and the checks most sections share (positive numbers, vectors of the scene's dimension).

use super::Issue;

/// Collects a scene's problems; sections validate themselves into it.
pub(super) struct Validator {
    pub(super) issues: Vec<Issue>,
    pub(super) dim: usize,
    /// Most particles the scene may generate (limit `particles`), for the set-up steps
    /// that multiply them (the split into refined levels).
    pub(super) max_particles: u64,
}

impl Validator {
    pub(super) fn err(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.issues.push(Issue::new(path, message));
    }

    pub(super) fn positive(&mut self, path: &str, x: f64) {
        if !(x.is_finite() && x > 0.0) {
            self.err(path, format!("must be a finite number > 0 (got {x})"));
        }
    }

    pub(super) fn vector(&mut self, path: &str, v: &[f64]) -> bool {
        if v.len() != self.dim {
            self.err(
                path,
                format!(
                    "needs {} numbers for a {}D scene (got {})",
                    self.dim,
                    self.dim,
                    v.len()
                ),
            );
            return false;
        }
        if v.iter().any(|x| !x.is_finite()) {
            self.err(path, "every number must be finite");
            return false;
        }
        true
    }

    pub(super) fn nonzero_vector(&mut self, path: &str, v: &[f64]) {
        if self.vector(path, v) && v.iter().map(|x| x * x).sum::<f64>() == 0.0 {
            self.err(path, "must not be the zero vector");
        }
    }

    /// A box at `path` (`….box`): `min` and `max` of the scene's dimension, `max` above `min`.
    pub(super) fn box_corners(&mut self, path: &str, min: &[f64], max: &[f64]) {
        if self.vector(&format!("{path}.min"), min) && self.vector(&format!("{path}.max"), max) {
            for a in 0..self.dim {
                if max[a] <= min[a] {
                    self.err(format!("{path}.max[{a}]"), format!("must exceed min[{a}]"));
                }
            }
        }
    }

    /// A sphere at `path` (`….sphere`): a centre of the scene's dimension, a radius > 0.
    pub(super) fn sphere(&mut self, path: &str, center: &[f64], radius: f64) {
        self.vector(&format!("{path}.center"), center);
        self.positive(&format!("{path}.radius"), radius);
    }
}
