//! Viscous underfill flow for mpm: a liquid drawn by capillary pressure into the thin gap
//! between a flip-chip die and its substrate, around the solder bumps, trapping air voids.
//!
//! - The gap is the bodies of the scene (particles, with `mechanics: off`); the liquid is a
//!   fill fraction on the grid cells they cover (a volume-of-fluid description), because
//!   liquid enters from a reservoir and a fixed set of material points cannot grow.
//!   Particles carry the gap's geometry in and the fill, pressure and velocity out, and the
//!   temperature and degree of cure from the thermal and phase-change plugins into the
//!   viscosity when a scene has them.
//! - Two modes of the same plugin: `gap_averaged` (Hele-Shaw over the die plane, pressure
//!   solve by conjugate gradients, for a whole die) and `cross_section` (incompressible
//!   Stokes flow with inertia resolved across the gap, velocity and pressure solved
//!   together, implicitly, by a banded direct solve). Neither has an explicit viscous or
//!   sound-speed step limit: the step is set by how fast the front cells fill.
//! - Capillary pressure 2σcosθ/h (plus the wetted bump walls inside a bump array) acts at
//!   the meniscus; reservoirs hold the dispensed liquid's pressure; air regions cut off
//!   from every vent are voids, reported with position, area and closing time (the
//!   `underfill_voids` table), optionally resisting as an ideal gas; the fill fraction over
//!   time is the `underfill_fill` table.
//! - Viscosity: Newtonian, Cross or Castro–Macosko ([`Viscosity`]).
//!
//! - Liquid as material points: the `liquid` material for incompressible mechanics, and
//!   `physics.liquid_voids` ([`LiquidVoidsParameters`]), the air its particles enclose,
//!   in the same `underfill_voids` table.
//!
//! Scene sections: `physics.underfill` ([`UnderfillParameters`]), `physics.liquid_voids`.

mod banded;
mod capillary_filling;
mod capillary_references;
mod capillary_rise_reference;
mod cross_section;
mod front;
mod hele_shaw;
mod lattice;
mod liquid;
mod liquid_references;
mod meniscus_reference;
mod parameters;
mod particle_cells;
mod particle_fill;
mod particle_voids;
mod pressure_filling;
mod sessile_drop_reference;
mod underfill;
mod viscosity;
mod voids;

pub use capillary_filling::{capillary_fill_time, capillary_front};
pub use liquid::{Liquid, LiquidParameters};
pub use liquid_references::{MARTIN_MOYCE_N2, martin_moyce_front};
pub use parameters::{
    Air, BumpArray, BumpPattern, FlowMode, Fluid, FluidSection, InitialFill, Reservoir,
    UnderfillParameters, VentRegion,
};
pub use particle_fill::FillRegion;
pub use particle_voids::{LiquidVoids, LiquidVoidsParameters};
pub use pressure_filling::{pressure_fill_time, pressure_front};
pub use underfill::{FILL_COLUMNS, FILL_TABLE, Underfill, VOIDS_TABLE};
pub use viscosity::{CastroMacoskoParameters, CrossParameters, MAX_VISCOSITY, Viscosity};

use mpm_core::physics::{Physics, PhysicsFactory, TypedPhysicsFactory};
use mpm_core::plugin::{MaterialFactory, Plugin, TypedMaterialFactory};
use mpm_core::reference::ReferenceFactory;
use mpm_core::scene::{Issue, Scene};
use std::sync::Arc;

/// The plugin: the `underfill` physics.
pub struct UnderfillPlugin;

impl Plugin for UnderfillPlugin {
    fn name(&self) -> &'static str {
        "underfill"
    }

    fn description(&self) -> &'static str {
        "capillary underfill flow in a thin gap: gap-averaged (Hele-Shaw) or resolved cross-section (Stokes), generalised Newtonian viscosity, solder bumps, trapped-air voids; the liquid particle material and the voids its particles enclose (liquid_voids)"
    }

    fn materials(&self) -> Vec<Box<dyn MaterialFactory>> {
        vec![Box::new(TypedMaterialFactory::new("liquid", liquid::build))]
    }

    fn physics(&self) -> Vec<Box<dyn PhysicsFactory>> {
        vec![
            Box::new(TypedPhysicsFactory::new("underfill", build)),
            Box::new(TypedPhysicsFactory::new("liquid_voids", build_liquid_voids)),
        ]
    }

    fn references(&self) -> Vec<Box<dyn ReferenceFactory>> {
        let mut references = vec![capillary_filling::factory(), pressure_filling::factory()];
        references.extend(liquid_references::factories());
        references.extend(capillary_references::factories());
        references.extend(meniscus_reference::factories());
        references.extend(capillary_rise_reference::factories());
        references.extend(sessile_drop_reference::factories());
        references
    }
}

fn build(
    params: UnderfillParameters,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Physics>, Vec<Issue>> {
    let issues = params.check(path, scene);
    if !issues.is_empty() {
        return Err(issues);
    }
    let fluid = params.resolved_fluid(scene, &format!("{path}.fluid"))?;
    Ok(Arc::new(Underfill::new(params, fluid, scene)))
}

fn build_liquid_voids(
    params: LiquidVoidsParameters,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Physics>, Vec<Issue>> {
    let issues = params.check(path, scene);
    if !issues.is_empty() {
        return Err(issues);
    }
    Ok(Arc::new(LiquidVoids::new(&params, scene)))
}

#[cfg(test)]
mod tests;
