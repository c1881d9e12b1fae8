//! The `physics.thermal` scene section and its checks.

use crate::boundary::ThermalBoundary;
use crate::interface::ContactConductance;
use mpm_core::physics::Property;
use mpm_core::scene::{Issue, Scene};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Scene section `physics.thermal`.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ThermalParameters {
    /// Time integration of conduction.
    #[serde(default)]
    pub integrator: Integrator,
    /// Thermal properties of every material a body uses, by material name.
    pub materials: BTreeMap<String, ThermalMaterial>,
    /// Conditions on the domain faces; a face without one is insulated. They act where the
    /// body touches the face.
    #[serde(default)]
    pub boundaries: Vec<ThermalBoundary>,
    /// Implicit solve: relative residual at which conjugate gradients stop.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Implicit solve: most iterations; more stops the run with a diagnostic.
    #[serde(default = "default_max_iterations")]
    pub max_iterations: u32,
    /// Implicit solve: preconditioner of the conjugate gradients.
    #[serde(default)]
    pub preconditioner: HeatPreconditioner,
    /// Imperfect thermal interfaces between contact bodies (`contact.pairs`), each with a
    /// heat transfer coefficient; contact without one conducts perfectly. Implicit
    /// integrator only.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contact_conductance: Vec<ContactConductance>,
}

/// The preconditioner of the implicit heat solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum HeatPreconditioner {
    /// A sparse Cholesky of the step's matrix (one or two iterations) where its assembly
    /// has at most 2·10⁷ entries, else Jacobi.
    #[default]
    Auto,
    /// The diagonal (no factorisation; iterations grow with the grid).
    Jacobi,
}

fn default_tolerance() -> f64 {
    1e-10
}
fn default_max_iterations() -> u32 {
    5000
}

/// How conduction advances in time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// Forward Euler: cheap per step, stable only below ρc·dx²/(2·dim·k), which enters the
    /// run's step choice.
    Explicit,
    /// Backward Euler on the grid (matrix-free conjugate gradients): stable at any step, for
    /// slow processes (curing, soaking) whose time scales are seconds to hours.
    #[default]
    Implicit,
}

/// Thermal properties of one material.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ThermalMaterial {
    /// Thermal conductivity, W/(m K): a number or a `[[T, k], ...]` table in kelvin.
    pub conductivity: Property,
    /// Specific heat, J/(kg K): a number or a `[[T, c], ...]` table in kelvin.
    pub specific_heat: Property,
    /// Temperature at t = 0, K.
    pub initial_temperature: f64,
    /// Linear thermal expansion coefficient, 1/K (0: none). Gives the free strain
    /// `expansion · (T − reference_temperature)` every material law sees removed from F.
    #[serde(default)]
    pub expansion: f64,
    /// Stress-free temperature for the expansion, K (default: the initial temperature).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_temperature: Option<f64>,
    /// Volumetric heat source, W/m³ of current volume.
    #[serde(default)]
    pub heat_source: f64,
    /// Share of the plastic work a material reports that turns into heat (Taylor–Quinney
    /// factor, typically 0.9); unset: plastic work does not heat.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taylor_quinney: Option<f64>,
}

impl ThermalParameters {
    /// Every problem with the section, with JSON paths below `path`.
    pub fn check(&self, path: &str, scene: &Scene) -> Vec<Issue> {
        let mut issues = Vec::new();
        let used: std::collections::BTreeSet<&str> =
            scene.bodies.iter().map(|b| b.material.as_str()).collect();
        for name in &used {
            if !self.materials.contains_key(*name) {
                issues.push(Issue::new(
                    format!("{path}.materials"),
                    format!("missing the thermal properties of material `{name}` (every material a body uses needs them)"),
                ));
            }
        }
        for (name, m) in &self.materials {
            let p = format!("{path}.materials.{name}");
            if !scene.materials.contains_key(name) {
                issues.push(Issue::new(
                    &p,
                    format!("no material `{name}` in the scene's `materials`"),
                ));
            }
            let positive = |v: f64| v.is_finite() && v > 0.0;
            issues.extend(m.conductivity.check(
                &format!("{p}.conductivity"),
                "a finite number > 0",
                positive,
            ));
            issues.extend(m.specific_heat.check(
                &format!("{p}.specific_heat"),
                "a finite number > 0",
                positive,
            ));
            if !positive(m.initial_temperature) {
                issues.push(Issue::new(
                    format!("{p}.initial_temperature"),
                    format!(
                        "must be a finite number > 0 K (got {})",
                        m.initial_temperature
                    ),
                ));
            }
            if !(m.expansion.is_finite() && m.expansion.abs() < 1e-2) {
                issues.push(Issue::new(
                    format!("{p}.expansion"),
                    format!(
                        "must be a finite coefficient per kelvin below 1e-2 in size (got {})",
                        m.expansion
                    ),
                ));
            }
            if let Some(t) = m.reference_temperature
                && !positive(t)
            {
                issues.push(Issue::new(
                    format!("{p}.reference_temperature"),
                    format!("must be a finite number > 0 K (got {t})"),
                ));
            }
            if !m.heat_source.is_finite() {
                issues.push(Issue::new(format!("{p}.heat_source"), "must be finite"));
            }
            if let Some(b) = m.taylor_quinney
                && !(0.0..=1.0).contains(&b)
            {
                issues.push(Issue::new(
                    format!("{p}.taylor_quinney"),
                    format!("must lie in [0, 1] (got {b})"),
                ));
            }
        }
        for (i, b) in self.boundaries.iter().enumerate() {
            issues.extend(b.check(&format!("{path}.boundaries[{i}]"), scene.dimension as usize));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            issues.push(Issue::new(
                format!("{path}.tolerance"),
                format!("must lie in (0, 1) (got {})", self.tolerance),
            ));
        }
        if !self.contact_conductance.is_empty() && self.integrator == Integrator::Explicit {
            issues.push(Issue::new(
                format!("{path}.integrator"),
                "contact conductance needs the implicit integrator (a thermal group's capacity at the edge of its kernel's reach is tiny, so the explicit step has no useful bound)",
            ));
        }
        if self.max_iterations == 0 {
            issues.push(Issue::new(
                format!("{path}.max_iterations"),
                "must be at least 1",
            ));
        }
        issues
    }
}
