//! The volume source (scenes with inlets or enclosed air, or `volume_correction`): a cell
//! whose particles' volume differs from its own gives (or takes) a share of the difference
//! through the pressure equation's right-hand side. The divergence-free projection alone
//! keeps the grid velocity's divergence zero, not the particles' volume per cell, so
//! entering particles pile up at an inlet, the liquid's particles cluster (mod.rs,
//! inflow.rs), and a liquid pulled by a meniscus thins (a capillary fill).
//!
//! The share is per velocity-CFL step (the step the flow alone would take at the scene's
//! `cfl`, or at `SOURCE_CFL` if that is larger): a shorter step (a capillary or viscous
//! bound, a frame time, a `cfl` under `SOURCE_CFL`) gives less, in proportion, so the
//! correction's velocity does not grow as 1/dt. With implicit viscosity the projection is
//! incremental and the source's right-hand side is also kept apart, solved on its own and
//! left out of the pressure that comes back as next step's force (`incremental_pressure`).

use super::Incompressible;

/// Share of a cell's excess particle volume the pressure equation removes per velocity-CFL
/// step.
pub(super) const VOLUME_CORRECTION: f64 = 0.3;

/// The least CFL number of the velocity-CFL step the share is given per (the default
/// `cfl`): a scene with a smaller `cfl` does not correct faster in time. At `cfl` 0.1 a
/// share per step of its own closed a gap of one cell in a few steps at several times the
/// flow's speed, and those speeds shrank the step until it collapsed.
pub(super) const SOURCE_CFL: f64 = 0.3;

impl<const D: usize> Incompressible<D> {
    /// Adds the source to the right-hand side (and, when `source_solved`, to its own);
    /// `rate` = min(1, dt / velocity-CFL step).
    pub(super) fn add_volume_source(&mut self, dx: f64, dt: f64, rate: f64) {
        let corners = 1 << D;
        if self.source_solved {
            self.source_rhs.resize(self.rhs.len(), 0.0);
            self.source_rhs.fill(0.0);
            self.source_pressure.resize(self.rhs.len(), 0.0);
        }
        let share = rate / (corners as f64 * dt * dt);
        self.source_volume.resize(self.rhs.len(), 0.0);
        self.source_volume.fill(0.0);
        for c in 0..self.cell_volume.len() {
            if let Some(volume) = self.volume_source(c, dx) {
                let base = self.cell_node[c];
                for a in 0..corners {
                    let node = base + self.corner_offset[a];
                    self.rhs[node] += volume * share;
                    self.source_volume[node] += volume * rate / corners as f64;
                    if self.source_solved {
                        self.source_rhs[node] += volume * share;
                    }
                }
            }
        }
    }

    /// The work the pressure does through this step's source: Σ_i p_i ΔV_i over the nodes,
    /// ΔV_i their share of the volume the source lets the cells gain (or lose) in the step
    /// and p_i the total pressure just solved for (with implicit viscosity the increment
    /// plus the pressure kept from the last step), J (J/m in 2D). The kinetic energy
    /// equation's ∫ p ∇·v dV, which a divergence-free velocity does not have.
    pub(super) fn volume_source_work(&self) -> f64 {
        let kept = |i: usize| self.viscosity.as_ref().map_or(0.0, |v| v.last_pressure(i));
        self.source_volume
            .iter()
            .enumerate()
            .filter(|(_, dv)| **dv != 0.0)
            .map(|(i, dv)| (self.pressure[i] + kept(i)) * dv)
            .sum()
    }

    /// The volume cell `c` is to give (or take, negative) in a velocity-CFL step: the share
    /// `VOLUME_CORRECTION` of the difference between its particles' volume and its own, in
    /// cells inside the liquid (every corner a pressure unknown), and only what it holds
    /// too much in cells on the free surface.
    fn volume_source(&self, c: usize, dx: f64) -> Option<f64> {
        let corners = 1 << D;
        let base = self.cell_node[c];
        let inside =
            (0..corners).all(|a| self.inverse_diagonal[base + self.corner_offset[a]] > 0.0);
        let excess = self.cell_volume[c] - dx.powi(D as i32);
        (self.cell_volume[c] > 0.0 && (inside || excess > 0.0))
            .then_some(VOLUME_CORRECTION * excess)
    }
}
