//! The `liquid` particle material: a generalised Newtonian liquid (the plugin's
//! [`Viscosity`] laws) for `solver.mechanics.incompressible`. It gives only the viscous,
//! deviatoric stress 2μ·dev(sym L); the pressure comes from the mode's projection, not
//! from an equation of state. Temperature and cure are read from the particles when a
//! physics creates them, else `temperature` is used and the cure is 0.

use crate::viscosity::Viscosity;
use mpm_core::material::{
    BatchStats, ConstitutiveLaw, FieldInit, FieldSpec, Material, SharedRead, StressBatch,
    ViscosityBatch,
};
use mpm_core::math::{Matrix, trace};
use mpm_core::scene::Issue;
use schemars::JsonSchema;
use serde::Deserialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Scene section of a `liquid` material.
#[derive(Clone, Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LiquidParameters {
    /// Mass density, kg/m³.
    pub density: f64,
    /// Viscosity law (`{"newtonian": 1e-3}`, `cross`, `castro_macosko`), Pa·s.
    pub viscosity: Viscosity,
    /// Temperature the viscosity is evaluated at when no physics gives the particles one, K.
    #[serde(default = "default_temperature")]
    pub temperature: f64,
    /// Surface tension against the void (air), N/m: the free surface carries the Laplace
    /// pressure σ·κ. 0 (the default) is none.
    #[serde(default)]
    pub surface_tension: f64,
}

fn default_temperature() -> f64 {
    293.15
}

const FIELDS: &[FieldSpec] = &[FieldSpec {
    name: "pressure",
    components: 1,
    initial: FieldInit::Zero,
}];

const READS: &[SharedRead] = &[
    SharedRead {
        name: "temperature",
        required: false,
    },
    SharedRead {
        name: "cure",
        required: false,
    },
];

/// A viscous liquid for the incompressible mode.
#[derive(Debug)]
pub struct Liquid {
    params: LiquidParameters,
    /// Largest viscosity of the last step's update (f64 bits; at the start, the law's at
    /// `temperature`), for the viscous step limit.
    max_viscosity: AtomicU64,
}

impl Liquid {
    /// From checked parameters.
    pub fn new(params: LiquidParameters) -> Self {
        let mu = params.viscosity.at(params.temperature, 0.0, 0.0);
        Self {
            params,
            max_viscosity: AtomicU64::new(mu.to_bits()),
        }
    }

    /// The deviatoric rate dev(sym L) of a velocity gradient and the viscosity at it, at
    /// temperature `t` and cure `a`: the one place `update_stress` and
    /// `liquid_viscosities` evaluate the law, so both give the same μ at the same state.
    #[inline]
    fn rate_and_viscosity<const D: usize>(
        &self,
        l: &Matrix<D>,
        t: f64,
        a: f64,
    ) -> (Matrix<D>, f64) {
        let rate = (l + l.transpose()) * 0.5;
        let dev = rate - Matrix::<D>::identity() * (trace(&rate) / D as f64);
        let shear_rate = (2.0 * dev.norm_squared()).sqrt();
        (dev, self.params.viscosity.at(t, shear_rate, a))
    }

    /// [`Self::rate_and_viscosity`] of particle `p` of a batch: its velocity gradient,
    /// temperature and cure where the batch has them, else zero, `temperature`, 0.
    #[inline]
    fn at_particle<const D: usize>(
        &self,
        velocity_gradient: &[Matrix<D>],
        temperature: &[f64],
        cure: &[f64],
        p: usize,
    ) -> (Matrix<D>, f64) {
        let l = velocity_gradient
            .get(p)
            .copied()
            .unwrap_or_else(Matrix::<D>::zeros);
        let t = temperature
            .get(p)
            .copied()
            .unwrap_or(self.params.temperature);
        let a = cure.get(p).copied().unwrap_or(0.0);
        self.rate_and_viscosity(&l, t, a)
    }
}

impl ConstitutiveLaw for Liquid {
    fn density(&self) -> f64 {
        self.params.density
    }

    fn state_fields(&self) -> &[FieldSpec] {
        FIELDS
    }

    fn needs_velocity_gradient(&self) -> bool {
        true
    }

    fn shared_reads(&self) -> &[SharedRead] {
        READS
    }

    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats {
        let [temperature, cure, ..] = batch.shared;
        let mut largest = 0.0f64;
        for (p, stress) in batch.stress.iter_mut().enumerate() {
            let (dev, mu) = self.at_particle(batch.velocity_gradient, temperature, cure, p);
            largest = largest.max(mu);
            *stress = dev * (2.0 * mu);
        }
        if !batch.stress.is_empty() {
            self.max_viscosity
                .fetch_max(largest.to_bits(), Ordering::Relaxed);
        }
        BatchStats {
            strain_energy: 0.0,
            max_wave_speed: 0.0,
        }
    }

    fn liquid_viscosity(&self) -> Option<f64> {
        Some(f64::from_bits(self.max_viscosity.load(Ordering::Relaxed)))
    }

    fn forget_viscosity_bound(&self) {
        self.max_viscosity
            .store(0.0f64.to_bits(), Ordering::Relaxed);
    }

    fn surface_tension(&self) -> f64 {
        self.params.surface_tension
    }

    /// The viscosity `update_stress` uses, at the particles' last velocity gradient,
    /// temperature and cure.
    fn liquid_viscosities<const D: usize>(&self, batch: ViscosityBatch<'_, D>) {
        let [temperature, cure, ..] = batch.shared;
        for (p, mu) in batch.viscosity.iter_mut().enumerate() {
            *mu = self
                .at_particle(batch.velocity_gradient, temperature, cure, p)
                .1;
        }
    }
}

/// Checks the parameters and builds the material.
pub(crate) fn build(p: LiquidParameters, path: &str) -> Result<Arc<dyn Material>, Vec<Issue>> {
    let mut issues = p.viscosity.check(&format!("{path}.viscosity"));
    if !(p.density.is_finite() && p.density > 0.0) {
        issues.push(Issue::new(
            format!("{path}.density"),
            "must be a finite number > 0",
        ));
    }
    if !(p.temperature.is_finite() && p.temperature > 0.0) {
        issues.push(Issue::new(
            format!("{path}.temperature"),
            "must be a finite number > 0 (kelvin)",
        ));
    }
    if !(p.surface_tension.is_finite() && p.surface_tension >= 0.0) {
        issues.push(Issue::new(
            format!("{path}.surface_tension"),
            "must be a finite number >= 0 (N/m)",
        ));
    }
    if issues.is_empty() {
        Ok(Arc::new(Liquid::new(p)))
    } else {
        Err(issues)
    }
}
