//! Heat conduction for mpm.
//!
//! Particles carry temperature, conductivity and specific heat; conduction is solved on the
//! MPM grid through the same shape functions as mechanics: heat capacity and thermal energy
//! go to the nodes (P2G), the conductance comes from the shape-function gradients, and the
//! nodal temperature change comes back to the particles (G2P). Two integrators: explicit
//! (its stable step enters the run's step choice) and implicit backward Euler solved with
//! matrix-free conjugate gradients preconditioned by a sparse Cholesky of the step's
//! matrix (`factored.rs`), stable at any step.
//!
//! Contact between bodies conducts perfectly unless `contact_conductance` gives a pair a
//! heat transfer coefficient (`interface.rs`: one nodal temperature per thermal group).
//!
//! Scene section: `physics.thermal` ([`ThermalParameters`]).

mod boundary;
mod conduction;
mod factored;
mod interface;
mod interface_reference;
mod parameters;
mod reference;

pub use boundary::{Convection, ThermalBoundary};
pub use conduction::Thermal;
pub use interface::ContactConductance;
pub use interface_reference::{InterfaceTemperatureParams, convecting_slab};
pub use parameters::{HeatPreconditioner, Integrator, ThermalMaterial, ThermalParameters};
pub use reference::{semi_infinite_temperature, slab_temperature};

use mpm_core::physics::{Physics, PhysicsFactory, TypedPhysicsFactory};
use mpm_core::plugin::{MaterialFactory, Plugin};
use mpm_core::reference::ReferenceFactory;
use mpm_core::scene::{Issue, Scene};
use std::sync::Arc;

/// The plugin: registers the `thermal` physics.
pub struct ThermalPlugin;

impl Plugin for ThermalPlugin {
    fn name(&self) -> &'static str {
        "thermal"
    }

    fn description(&self) -> &'static str {
        "heat conduction (explicit or implicit), wall temperature/flux/convection, heat sources, plastic heating, thermal expansion"
    }

    fn materials(&self) -> Vec<Box<dyn MaterialFactory>> {
        Vec::new()
    }

    fn physics(&self) -> Vec<Box<dyn PhysicsFactory>> {
        vec![Box::new(
            TypedPhysicsFactory::new("thermal", build).with_compact_rows(),
        )]
    }

    fn references(&self) -> Vec<Box<dyn ReferenceFactory>> {
        reference::factories()
    }
}

fn build(
    params: ThermalParameters,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Physics>, Vec<Issue>> {
    let mut issues = params.check(path, scene);
    let interfaces = interface::Interfaces::new(
        &params.contact_conductance,
        &format!("{path}.contact_conductance"),
        scene,
    );
    match interfaces {
        Ok(interfaces) if issues.is_empty() => {
            Ok(Arc::new(Thermal::new(params, scene, interfaces)))
        }
        Ok(_) => Err(issues),
        Err(more) => {
            issues.extend(more);
            Err(issues)
        }
    }
}
