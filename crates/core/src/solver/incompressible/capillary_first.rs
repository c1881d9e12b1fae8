//! The capillary pressure before the viscous step (implicit viscosity with surface
//! tension), so that the viscous solve damps the capillary impulse of its own step.
//!
//! With the incremental projection alone (viscosity.rs) the viscous solve sees the last
//! step's pressure force, and the change of the Laplace pressure σκ since then, applied by
//! the projection after the solve, reaches the velocity undamped. For a viscous liquid
//! that change is the whole explicit capillary wave: the drop at rest broke down at the
//! same step, about √(ρdx³/σ), whatever its viscosity from 1 to 100 Pa·s.
//!
//! This stage solves first for the pressure that carries σκ at the free surface from the
//! particles' present shape: the liquid cells' Laplacian with the free surface's
//! increment σκ − p^n (the kept total pressure there) as Dirichlet values, no source inside
//! (so the increment is the harmonic extension of the surface's, the pressure σκ gives a
//! liquid at rest), 0 on every other fixed node. Its force −(dt/M_i) Σ_c ∫_c N_i ∇Δp joins
//! the velocity before the viscous solve, and Δp joins the kept pressure, so the projection
//! after the solve finds no change at the surface and corrects only the divergence the
//! viscous step left. Like the kept pressure's force, the share of this one that the
//! viscous step would not damp is taken back after the solve and left to the projection
//! (`Incompressible::add_kept_pressure_force`; none for the viscous liquids this stage
//! is for). The capillary force then goes through the backward-Euler viscous
//! step as any other force does, and the step is bounded by the viscous–capillary time
//! μdx/σ (surface_tension.rs), no longer by the capillary wave. The surface shape is still
//! the one at the start of the step (explicit in κ): this is the splitting's order, not
//! Hysing's (2006) implicit surface term. One more Poisson solve per step, on steps
//! longer than the inertial capillary bound only (within it the explicit σκ is stable).
use super::pressure::{CellOperator, report_solve};
use super::{DimensionDispatch, Incompressible, extrapolate, surface_tension};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::solver::simulation::Simulation;

/// Physics figure: the most CG iterations of the capillary solve in one step.
const ITERATIONS: &str = "incompressible.capillary_iterations";

/// The capillary stage's own workspace (sized on the first step).
#[derive(Default)]
pub(super) struct CapillaryFirst {
    /// Per node: the Dirichlet value of the increment (σκ − p^n on the free surface, else 0).
    fixed: Vec<f64>,
}

impl<const D: usize> Incompressible<D> {
    /// Solves for the Laplace pressure's increment since the last step and adds its force to
    /// the velocity before the walls and the increment to the kept pressure. Does nothing
    /// without implicit viscosity, surface tension or this stage.
    pub(super) fn capillary_first<K: Kernel>(&mut self, sim: &mut Simulation<D, K>, dt: f64)
    where
        dyn Material: DimensionDispatch<D>,
    {
        if self.surface.is_none() || self.viscosity.is_none() || self.capillary.is_none() {
            return;
        }
        // Within the inertial capillary step the projection's explicit σκ is stable and as
        // accurate (the meniscus at μ = 0.2 Pa·s: 3.3% either way), and this solve would
        // only double the pressure work.
        let dx = sim.grid.dx;
        let inertial = sim
            .particles
            .groups
            .iter()
            .map(|g| {
                surface_tension::inertial_dt(g.material.surface_tension(), g.material.density(), dx)
            })
            .fold(f64::INFINITY, f64::min);
        if dt <= sim.settings.cfl * inertial * (1.0 + 1e-9) {
            return;
        }
        let corners = 1 << D;
        let n = sim.grid.len();
        self.pressure.fill(0.0);
        self.surface_pressure(sim);
        let (Some(surface), Some(viscosity), Some(stage)) = (
            self.surface.as_ref(),
            self.viscosity.as_ref(),
            self.capillary.as_mut(),
        ) else {
            return;
        };
        stage.fixed.resize(n, 0.0);
        for i in 0..n {
            stage.fixed[i] = if self.inverse_diagonal[i] <= 0.0 && surface.touches_liquid(i) {
                self.pressure[i] - viscosity.last_pressure(i)
            } else {
                0.0
            };
        }
        // The unknowns' right-hand side is what the fixed values put on them, −A p_fixed;
        // the solve then starts from zero everywhere.
        let operator = CellOperator {
            stiffness: &self.stiffness,
            corner_offset: &self.corner_offset,
            cell_mass: &self.cell_mass,
            cell_volume: &self.cell_volume,
            cell_node: &self.cell_node,
            corners,
            air: None,
            n,
        };
        operator.apply(&stage.fixed, &mut self.rhs);
        for (b, free) in self.rhs.iter_mut().zip(&self.inverse_diagonal) {
            *b = if *free > 0.0 { -*b } else { 0.0 };
        }
        self.pressure.fill(0.0);
        let result = self.cell_solve(corners, n, false);
        report_solve(
            &mut sim.report,
            result,
            (ITERATIONS, "pressure", "capillary pressure solve"),
            self.settings.max_iterations,
        );
        let (Some(viscosity), Some(stage)) = (self.viscosity.as_mut(), self.capillary.as_ref())
        else {
            return;
        };
        for ((p, fixed), free) in self
            .pressure
            .iter_mut()
            .zip(&stage.fixed)
            .zip(&self.inverse_diagonal)
        {
            if *free <= 0.0 {
                *p = *fixed;
            }
        }
        viscosity.add_to_kept_pressure(&self.pressure);
        self.pressure_correction(dt, sim.grid.dx);
        extrapolate::extrapolate_correction(&sim.grid, &mut self.correction, &mut self.layer);
        if let Some(viscosity) = self.viscosity.as_mut() {
            viscosity.pre_apply(
                &mut self.free_velocity,
                &self.correction,
                &self.layer,
                false,
            );
        }
        self.pressure.fill(0.0);
    }
}
