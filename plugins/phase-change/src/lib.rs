//! Phase change for mpm.
//!
//! - Melting and solidification: each particle carries a solid volume fraction f (1 solid,
//!   0 liquid). Latent heat enters by the enthalpy method: temperature that conduction
//!   carries past the melting point is turned into a change of f at constant temperature
//!   (the enthalpy c·T + (1 − f)·L is conserved). Conductivity, specific heat and density
//!   mix as f·ψ_solid + (1 − f)·ψ_liquid; a density change becomes a free strain.
//! - Thermoset cure: degree of cure α from Kamal–Sourour kinetics with Arrhenius rate
//!   constants, heat of reaction released into the temperature, glass transition from
//!   DiBenedetto, gelation at a given α (the particle turns solid: f = 1), and chemical
//!   shrinkage proportional to α added to the free strain.
//! - The `phase_mixture` material: a stress that moves from a viscous fluid to an elastic
//!   solid as f rises (incremental, so a particle that solidifies is stress-free where it
//!   solidified).
//!
//! Scene section: `physics.phase_change` ([`PhaseChangeParameters`]); needs
//! `physics.thermal`.

mod cure;
mod cure_reference;
mod melting;
mod mixture;
mod mixture_plasticity;
mod parameters;
mod phase_change;
mod stefan;

pub use cure::{CureKinetics, CureParameters, GlassTransition, TemperaturePath};
pub use cure_reference::kamal_sourour_isothermal;
pub use melting::{Melting, PhaseProperties};
pub use mixture::{PhaseMixture, PhaseMixtureParameters};
pub use mixture_plasticity::SolidPlasticity;
pub use parameters::{PhaseChangeMaterial, PhaseChangeParameters};
pub use phase_change::PhaseChange;
pub use stefan::neumann_lambda;

use mpm_core::material::Material;
use mpm_core::physics::{Physics, PhysicsFactory, TypedPhysicsFactory};
use mpm_core::plugin::{MaterialFactory, Plugin, TypedMaterialFactory};
use mpm_core::reference::ReferenceFactory;
use mpm_core::scene::{Issue, Scene};
use std::sync::Arc;

/// The plugin: the `phase_change` physics and the `phase_mixture` material.
pub struct PhaseChangePlugin;

impl Plugin for PhaseChangePlugin {
    fn name(&self) -> &'static str {
        "phase-change"
    }

    fn description(&self) -> &'static str {
        "solid fraction with latent heat (melting, solidification), property mixing, thermoset cure kinetics, fluid-to-solid material"
    }

    fn materials(&self) -> Vec<Box<dyn MaterialFactory>> {
        vec![Box::new(TypedMaterialFactory::new(
            "phase_mixture",
            build_mixture,
        ))]
    }

    fn physics(&self) -> Vec<Box<dyn PhysicsFactory>> {
        vec![Box::new(
            TypedPhysicsFactory::new("phase_change", build).with_compact_rows(),
        )]
    }

    fn references(&self) -> Vec<Box<dyn ReferenceFactory>> {
        let mut references = vec![stefan::factory()];
        references.extend(cure_reference::factories());
        references
    }
}

fn build(
    params: PhaseChangeParameters,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Physics>, Vec<Issue>> {
    let issues = params.check(path, scene);
    if !issues.is_empty() {
        return Err(issues);
    }
    Ok(Arc::new(PhaseChange::new(params)))
}

fn build_mixture(
    params: PhaseMixtureParameters,
    path: &str,
) -> Result<Arc<dyn Material>, Vec<Issue>> {
    let issues = params.check(path);
    if !issues.is_empty() {
        return Err(issues);
    }
    Ok(Arc::new(PhaseMixture::new(params)))
}

#[cfg(test)]
mod tests;
