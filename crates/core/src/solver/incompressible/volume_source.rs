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
        self.balance_sealed_regions(dt);
    }

    /// Takes each sealed liquid region's net source out of it: a region whose free nodes
    /// reach no node of fixed pressure (no free surface, no gas pocket), walled all round,
    /// has a pressure equation that only a right-hand side summing to zero over it can
    /// satisfy. The projection's own divergence does (no flux through walls); the source's
    /// need not, and CG then broke down (the capillary rise's pressure solve at 0.53 s with
    /// `volume_correction`). Such a region keeps the source's redistribution within it.
    fn balance_sealed_regions(&mut self, dt: f64) {
        let corners = 1 << D;
        let nodes = self.source_volume.len();
        let b = &mut self.balance;
        b.root.clear();
        b.root.extend(0..nodes);
        b.anchored.clear();
        b.anchored.resize(nodes, false);
        b.sum.clear();
        b.sum.resize(nodes, 0.0);
        b.count.clear();
        b.count.resize(nodes, 0);
        let free = |i: usize| self.inverse_diagonal[i] > 0.0;
        // Free nodes joined through the liquid cells they share.
        for c in 0..self.cell_volume.len() {
            if self.cell_volume[c] <= 0.0 {
                continue;
            }
            let base = self.cell_node[c];
            let mut first = None;
            for a in 0..corners {
                let i = base + self.corner_offset[a];
                if free(i) {
                    match first {
                        None => first = Some(i),
                        Some(f) => b.join(f, i),
                    }
                }
            }
        }
        // A region with a liquid cell on a node of fixed pressure is anchored.
        for c in 0..self.cell_volume.len() {
            if self.cell_volume[c] <= 0.0 {
                continue;
            }
            let base = self.cell_node[c];
            let corner = |a: usize| base + self.corner_offset[a];
            if let Some(f) = (0..corners).map(corner).find(|&i| free(i))
                && (0..corners).map(corner).any(|i| !free(i))
            {
                let r = b.find(f);
                b.anchored[r] = true;
            }
        }
        for i in (0..nodes).filter(|&i| free(i)) {
            let r = b.find(i);
            b.sum[r] += self.source_volume[i];
            b.count[r] += 1;
        }
        for i in (0..nodes).filter(|&i| free(i)) {
            let r = b.find(i);
            if b.anchored[r] || b.sum[r] == 0.0 {
                continue;
            }
            let mean = b.sum[r] / f64::from(b.count[r]);
            self.source_volume[i] -= mean;
            // The right-hand side took the volume over dt² (the share's 1/(2^D·dt²) on
            // the rate's volume / 2^D per corner).
            let rate_to_rhs = 1.0 / (dt * dt);
            self.rhs[i] -= mean * rate_to_rhs;
            if self.source_solved {
                self.source_rhs[i] -= mean * rate_to_rhs;
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

/// Scratch of [`Incompressible::balance_sealed_regions`], kept between steps: a union-find
/// over the nodes, and per region whether it is anchored, its source and its node count.
#[derive(Default)]
pub(super) struct SourceBalance {
    root: Vec<usize>,
    anchored: Vec<bool>,
    sum: Vec<f64>,
    count: Vec<u32>,
}

impl SourceBalance {
    /// The region of node `i` (path halving).
    fn find(&mut self, mut i: usize) -> usize {
        while self.root[i] != i {
            self.root[i] = self.root[self.root[i]];
            i = self.root[i];
        }
        i
    }

    /// Puts nodes `i` and `j` in one region.
    fn join(&mut self, i: usize, j: usize) {
        let (a, b) = (self.find(i), self.find(j));
        if a != b {
            self.root[a] = b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::IncompressibleSettings;

    #[test]
    fn a_sealed_region_keeps_no_net_source_and_an_open_one_keeps_its_own() {
        // A row of four 2D cells, nodes two high (node = 2·x + y). Cell 0 is liquid with
        // every corner free: sealed. Cell 3 is liquid with its two right corners of fixed
        // pressure (a free surface): anchored. Cells 1 and 2 hold no liquid.
        let mut p = Incompressible::<2>::new(IncompressibleSettings::default());
        p.corner_offset[..4].copy_from_slice(&[0, 1, 2, 3]);
        p.cell_node = vec![0, 2, 4, 6];
        p.cell_volume = vec![1.0, 0.0, 0.0, 1.0];
        p.inverse_diagonal = vec![1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0];
        p.source_volume = vec![1.0, 2.0, 3.0, 4.0, 0.0, 0.0, 5.0, 6.0, 0.0, 0.0];
        let dt = 0.5;
        p.rhs = p.source_volume.iter().map(|v| v / (dt * dt)).collect();
        p.balance_sealed_regions(dt);
        // The sealed cell's source, 10 over four nodes, loses its mean of 2.5.
        assert_eq!(&p.source_volume[..4], &[-1.5, -0.5, 0.5, 1.5]);
        assert_eq!(&p.rhs[..4], &[-6.0, -2.0, 2.0, 6.0]);
        // The anchored cell keeps its source.
        assert_eq!(&p.source_volume[6..8], &[5.0, 6.0]);
        assert_eq!(&p.rhs[6..8], &[20.0, 24.0]);
    }
}
