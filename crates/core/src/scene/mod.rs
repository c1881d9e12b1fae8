//! Scene files: the JSON description of one run, its parsing and its validation.
//!
//! Parsing happens in three stages so every problem is reported with the JSON path where it
//! lies: JSON syntax (line and column), structure (unknown keys, wrong types; via
//! `serde_path_to_error`), then physics and geometry checks in [`validate`]. Each section's
//! types and checks share a file (`domain`, `solver_settings`, `body`, `obstacle`,
//! `contact`, `output`); [`Scene`], the top level, is here.

mod body;
mod body_particles;
mod budget;
mod contact;
mod cpdi;
mod domain;
pub mod held_bodies;
mod inflow;
mod lattice;
mod loads;
mod obstacle;
mod output;
mod refinement;
mod solver_settings;
mod stage_conversion;
mod stages;
mod total_lagrangian;
mod validate;
mod validator;

pub use body::{Body, HeldSurface, InitialVelocity, ParticleFileFormat, Shape};
pub use body_particles::{BodyParticles, read_csv_particles};
pub use budget::{Estimate, Limits, estimate};
pub use contact::{CohesiveLaw, ContactLaw, ContactPair, ContactSection, MAX_CONTACT_FIELDS};
pub use domain::{Contact, Domain, Side, Wall};
pub use inflow::{INJECTED, Inflow, InflowLayout};
pub use loads::{Load, in_box};
pub use obstacle::{Obstacle, ObstacleShape};
pub use output::{CheckpointSchedule, FatigueLayer, Output, StopCriteria};
pub use refinement::{RefinedLevel, Refinement, RegionBox};
pub use solver_settings::{
    AntiLocking, EnclosedAirSettings, FactorPrecision, FreeStrain2d, GridStorage, ImplicitForm,
    ImplicitSettings, IncompressibleSettings, KernelName, KrylovMethod, Mechanics, Scheme, Solver,
    TangentMethod, Transfer, ViscousIntegration,
};
pub use stages::{FIXED_ACROSS_STAGES, RemoveParticles, StageSpec, ValidatedStage, merge_patch};
pub use validate::{
    CORE_FIELDS, INTERFACE_DAMAGE, STRESS_ZZ, ValidatedScene, parse_scene, parse_scene_value,
    parse_scene_value_limited,
};

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// One simulation: domain, solver settings, materials, bodies, obstacles, output and an
/// optional reference solution to report the error against.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Name of the run; the result store is `<out>/<name>.zarr`. Letters, digits, `-`, `_`, `.`.
    pub name: String,
    /// Free text for people.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// 2 (plane strain) or 3.
    pub dimension: u8,
    /// The background grid and its walls.
    pub domain: Domain,
    /// Time integration, kernel, transfer and update scheme.
    pub solver: Solver,
    /// Materials by name; each has a `type` provided by a plugin (`linear_elastic`, ...).
    pub materials: BTreeMap<String, serde_json::Value>,
    /// Bodies made of particles.
    pub bodies: Vec<Body>,
    /// Rigid obstacles acting on the grid.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub obstacles: Vec<Obstacle>,
    /// Contact between bodies: the bodies named here get grid velocity fields of their own
    /// and a law (frictionless, Coulomb friction, no-slip) where their fields meet.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactSection>,
    /// Dead loads: a total force on the particles that start inside a box, split over them
    /// by volume (a tip load, a traction over a face).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub loads: Vec<Load>,
    /// Physics beyond mechanics by name (`thermal`, `phase_change`, ...), each provided by a
    /// plugin; run in the order the plugins require (see `mpm plugins`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub physics: BTreeMap<String, serde_json::Value>,
    /// What is written and how often.
    #[serde(default)]
    pub output: Output,
    /// Criteria that stop a run which is going wrong.
    #[serde(default)]
    pub stop: StopCriteria,
    /// A reference solution, selected by its `type` among those the core and the plugins
    /// register; the run reports its error against it in `metrics.error`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<serde_json::Value>,
    /// Stages run one after another on the same particles (fill, cure, cool-down, ...),
    /// each the scene before it changed by a JSON merge patch; empty: one stage, this scene.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stages: Vec<StageSpec>,
}

/// One problem in a scene file, at a JSON path such as `materials.steel.poisson_ratio`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Issue {
    /// Dotted JSON path (`bodies[0].shape.box.min`); `$` for the whole document.
    pub path: String,
    /// What is wrong, in words a user can act on.
    pub message: String,
}

impl Issue {
    /// An issue at `path`.
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for Issue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.message)
    }
}

/// A scene that cannot be run, with every problem found.
#[derive(Clone, Debug, thiserror::Error)]
pub struct SceneError {
    /// The problems, in document order where possible.
    pub issues: Vec<Issue>,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "invalid scene ({} problem", self.issues.len())?;
        if self.issues.len() != 1 {
            write!(f, "s")?;
        }
        write!(f, "):")?;
        for issue in &self.issues {
            write!(f, "\n  {issue}")?;
        }
        Ok(())
    }
}

impl SceneError {
    /// A scene error with a single issue.
    pub fn single(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            issues: vec![Issue::new(path, message)],
        }
    }
}

/// Joins a parent JSON path and a child path from `serde_path_to_error` (`.` means the root).
pub fn join_path(parent: &str, child: &str) -> String {
    let child = child.trim_start_matches('.');
    if child.is_empty() || child == "." {
        return parent.to_string();
    }
    if parent.is_empty() || parent == "$" {
        return child.to_string();
    }
    if child.starts_with('[') {
        format!("{parent}{child}")
    } else {
        format!("{parent}.{child}")
    }
}

/// Deserialises `value` into `T`, reporting a failure at its JSON path below `parent`.
///
/// Plugins use this for their own scene sections so their errors name full paths too.
pub fn deserialize_at<T: serde::de::DeserializeOwned>(
    value: &serde_json::Value,
    parent: &str,
) -> Result<T, Issue> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = join_path(parent, &e.path().to_string());
        let message = e.into_inner().to_string();
        Issue::new(path, message)
    })
}

/// A minimal `dimension`-D scene (one unit-square domain, nothing in it), for unit tests of
/// sections that look at the scene they belong to (references, physics).
#[doc(hidden)]
pub fn test_scene(dimension: usize) -> Scene {
    let unit = vec![1.0; dimension];
    let json = serde_json::json!({
        "name": "test",
        "dimension": dimension,
        "domain": { "min": vec![0.0; dimension], "max": unit, "cell_size": 0.1 },
        "solver": { "end_time": 1.0 },
        "materials": {},
        "bodies": []
    });
    deserialize_at(&json, "$").unwrap_or_else(|issue| panic!("test scene: {issue}"))
}
