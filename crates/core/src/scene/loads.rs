//! The `loads` section: a total force on the particles that start inside a box (a tip
//! load, a traction over a face), split over them by volume. The force keeps its
//! direction and size for the whole run (a dead load, so it has the potential −f·x that
//! the energy balance counts). 2D forces are per unit thickness (N/m).

use super::validator::Validator;
use super::{BodyParticles, Mechanics, Scene};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A dead load on the particles that start inside a box.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Load {
    /// Name for people.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// Lower corner of the box that picks the particles at time 0, m.
    pub min: Vec<f64>,
    /// Upper corner of the box, m.
    pub max: Vec<f64>,
    /// Total force on those particles, N (N/m in 2D), one number per dimension, split over
    /// them by volume.
    pub force: Vec<f64>,
}

/// Whether `x` (one particle's coordinates) lies in the load's box.
pub fn in_box(load: &Load, x: &[f64]) -> bool {
    x.iter()
        .zip(load.min.iter().zip(&load.max))
        .all(|(c, (lo, hi))| *c >= *lo && *c <= *hi)
}

impl Validator {
    /// Checks every load's box and force, that it picks at least one particle, and that the
    /// mechanics can carry it.
    pub(super) fn check_loads(&mut self, s: &Scene, bodies: &[BodyParticles]) {
        let dim = s.dimension as usize;
        for (k, load) in s.loads.iter().enumerate() {
            let path = format!("loads[{k}]");
            let mut shape_ok = true;
            for (name, values) in [
                ("min", &load.min),
                ("max", &load.max),
                ("force", &load.force),
            ] {
                if values.len() != dim || !values.iter().all(|v| v.is_finite()) {
                    self.err(
                        format!("{path}.{name}"),
                        format!("must be {dim} finite numbers (one per dimension)"),
                    );
                    shape_ok = false;
                }
            }
            if !shape_ok {
                continue;
            }
            if load.min.iter().zip(&load.max).any(|(lo, hi)| lo > hi) {
                self.err(
                    format!("{path}.max"),
                    "must be at least `min` along every axis",
                );
                continue;
            }
            let picked: usize = bodies
                .iter()
                .map(|b| {
                    b.positions
                        .chunks_exact(dim)
                        .filter(|x| in_box(load, x))
                        .count()
                })
                .sum();
            if picked == 0 && !bodies.is_empty() {
                self.err(
                    format!("{path}.min"),
                    "the box holds no particle at time 0: the load would act on nothing",
                );
            }
        }
        if s.loads.is_empty() {
            return;
        }
        let refusal = match &s.solver.mechanics {
            Mechanics::Implicit(_) => Some("`implicit`"),
            Mechanics::Incompressible(_) => Some("`incompressible`"),
            Mechanics::Off => Some("`off`"),
            _ => None,
        };
        if let Some(mode) = refusal {
            self.err(
                "loads",
                format!(
                    "loads act in the explicit steps (`dynamic`, `quasi_static`, \
                     `total_lagrangian`), not in {mode} mechanics"
                ),
            );
        }
        if s.contact.is_some() {
            self.err(
                "loads",
                "loads are not carried by contact's velocity fields yet: remove `contact` or \
                 the loads",
            );
        }
    }
}
