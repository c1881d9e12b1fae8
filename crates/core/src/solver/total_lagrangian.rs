//! Total Lagrangian MPM (TLMPM; de Vaucorbeil, Nguyen, Sinaie & Wu 2020, "Material point
//! method after 25 years" and the TLMPM paper in CMAME 360): the grid is the reference
//! configuration, so every particle keeps the stencil it had when the mode started. Its
//! weights and their gradients with respect to the reference position X are computed once;
//! the internal force is −Σ V₀ P ∇₀w with the first Piola–Kirchhoff stress P = Jσ F⁻ᵀ, and
//! the deformation gradient grows as Ḟ = Σ vᵢ ⊗ ∇₀wᵢ. No particle crosses a cell, so there
//! is no cell-crossing noise and no numerical fracture: a bar stretched to several times its
//! length stays whole. The price: the body cannot meet another body or an obstacle (both
//! act in the current configuration) and walls hold the material that started at them.
//!
//! A stage that starts in this mode takes the positions and F it starts from as its
//! reference: X₀ and F₀, with F = F_rel·F₀, so P₀ = J σ (F₀F⁻¹)ᵀ and Ḟ = (Σ vᵢ ⊗ ∇₀wᵢ)·F₀.
//! P2G is a gather over each node's stencil entries (the transpose, built once;
//! `gather_transfer`), so no two threads write one node and the sums come out the same
//! whatever the thread count.

use super::DimensionDispatch;
use super::gather_transfer::{Frame, GatherStencils};
use super::interpolation::build_compact_interpolation;
use super::mode::StepMode;
use super::simulation::Simulation;
use super::stage_clock::StepStage;
use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector, determinant, inverse};
use crate::scene::Scheme;
use rayon::prelude::*;
use std::time::Instant;

/// The total Lagrangian mode's state: the reference configuration and its stencils.
#[derive(Default)]
pub(super) struct TotalLagrangian<const D: usize> {
    /// Positions at the mode's start (the reference configuration), particle order.
    reference: Vec<Vector<D>>,
    /// F at the mode's start (the identity for a run that starts in this mode).
    start_f: Vec<Matrix<D>>,
    /// Every particle's stencil at its reference position (compact rows, their transpose,
    /// APIC's inertia, the force matrices V₀ J σ (F₀F⁻¹)ᵀ); empty until the first step (and
    /// after a resume, rebuilt from `reference`).
    gather: GatherStencils<D>,
    /// Each wall's axis, side and the coordinate a cell behind its plane: a particle past
    /// it went through the wall (a wall holds only the material that starts at it).
    walls: Vec<(usize, bool, f64)>,
    /// Largest 1/σ_min(F_rel) over the particles after the last stress update: the most
    /// compressed direction, where a wave crosses a reference cell fastest.
    inverse_stretch: f64,
}

impl<const D: usize, K: Kernel> StepMode<D, K> for TotalLagrangian<D>
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        if self.reference.len() != sim.particles.len() {
            // The mode's first step (or particles were removed since the reference was
            // taken): the reference is where the particles are now.
            self.reference = sim.particles.position.clone();
            self.start_f = sim.particles.deformation_gradient.clone();
            self.gather = GatherStencils::default();
        }
        if self.gather.stencil.node.is_empty() && !self.reference.is_empty() {
            self.build_stencils::<K>(sim);
        }
        self.stress_to_force(sim);
        sim.grid.clear();
        let frame = Frame::Reference {
            position: &self.reference,
            start_f: &self.start_f,
            walls: &self.walls,
        };
        let g = &self.gather;
        g.p2g(sim, frame, dt, true);
        sim.grid_update(dt, true);
        match sim.settings.scheme {
            Scheme::Musl => {
                // The paper's scheme: the new particle velocities mapped back give the
                // velocity field F grows with.
                g.g2p(sim, frame, dt, true, true, false);
                sim.grid.clear_momentum();
                g.p2g(sim, frame, dt, false);
                sim.grid_update(dt, false);
                g.g2p(sim, frame, dt, false, false, true);
            }
            // Validation refuses USF with this mode.
            _ => g.g2p(sim, frame, dt, true, true, true),
        }
        sim.update_stresses(dt);
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        let wave = sim.stresses.batch.max_wave_speed * self.inverse_stretch.max(1.0);
        let mechanical = if wave > 0.0 {
            sim.grid.dx / wave
        } else {
            f64::INFINITY
        };
        mechanical.min(sim.physics_dt)
    }

    fn save(&mut self, c: &mut Checkpoint) {
        let flat = |m: &[Matrix<D>]| m.iter().flat_map(|a| a.iter().copied()).collect();
        c.put("total_lagrangian.count", vec![self.reference.len() as f64]);
        c.put(
            "total_lagrangian.reference",
            self.reference
                .iter()
                .flat_map(|x| x.iter().copied())
                .collect(),
        );
        c.put("total_lagrangian.start_f", flat(&self.start_f));
        c.put(
            "total_lagrangian.inverse_stretch",
            vec![self.inverse_stretch],
        );
    }

    fn take_over(&mut self, sim: &Simulation<D, K>, c: &Checkpoint) {
        // A total Lagrangian stage after another keeps its reference configuration, unless
        // particles were removed between them (then this stage starts from where they are:
        // `advance` checks the count again).
        let n = sim.particles.len();
        if c.get("total_lagrangian.count", 1)
            .ok()
            .map(|k| k[0] as usize)
            == Some(n)
        {
            let _ = StepMode::<D, K>::restore(self, c);
        }
    }

    fn restore(&mut self, c: &Checkpoint) -> Result<(), CheckpointError> {
        let n = c.get("total_lagrangian.count", 1)?[0] as usize;
        let x = c.get("total_lagrangian.reference", n * D)?;
        self.reference = x
            .chunks_exact(D)
            .map(crate::math::vector_from_slice)
            .collect();
        let f = c.get("total_lagrangian.start_f", n * D * D)?;
        self.start_f = f
            .chunks_exact(D * D)
            .map(Matrix::<D>::from_column_slice)
            .collect();
        self.inverse_stretch = c.get("total_lagrangian.inverse_stretch", 1)?[0];
        // The stencils are rebuilt from the reference at the next step.
        self.gather = GatherStencils::default();
        Ok(())
    }
}

impl<const D: usize> TotalLagrangian<D> {
    /// The stencils at the reference positions, their transpose and APIC's inertia.
    fn build_stencils<K: Kernel>(&mut self, sim: &mut Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let start = Instant::now();
        // The stencil builder reads the particles' positions: lend it the reference.
        std::mem::swap(&mut sim.particles.position, &mut self.reference);
        build_compact_interpolation::<D, K>(&sim.grid, &sim.particles, &mut self.gather.stencil);
        std::mem::swap(&mut sim.particles.position, &mut self.reference);
        self.gather.index(sim, &self.reference);
        let grid = &sim.grid;
        self.walls = sim
            .boundaries
            .wall_planes()
            .map(|w| {
                let plane = grid.origin[w.axis] + w.surface as f64 * grid.dx;
                let beyond = if w.upper {
                    plane + grid.dx
                } else {
                    plane - grid.dx
                };
                (w.axis, w.upper, beyond)
            })
            .collect();
        sim.clock.add(StepStage::Bin, start);
    }

    /// Each particle's V₀ J σ (F₀F⁻¹)ᵀ for this step's force, and the largest inverse
    /// stretch of F_rel = F F₀⁻¹ for the next step's bound.
    fn stress_to_force<K: Kernel>(&mut self, sim: &mut Simulation<D, K>) {
        let start = Instant::now();
        let p = &sim.particles;
        let start_f = &self.start_f;
        let inverse_stretch = self
            .gather
            .force_matrix
            .par_iter_mut()
            .enumerate()
            .map(|(k, a)| {
                let f = &p.deformation_gradient[k];
                let j = determinant(f);
                let Some(f_inv) = inverse(f) else {
                    *a = Matrix::<D>::zeros();
                    return f64::INFINITY;
                };
                let rel_inv = start_f[k] * f_inv;
                *a = p.stress[k] * rel_inv.transpose() * (p.volume0[k] * j);
                largest_singular_value_bound(&rel_inv)
            })
            .reduce(|| 0.0, f64::max);
        self.inverse_stretch = inverse_stretch;
        sim.clock.add(StepStage::Stress, start);
    }
}

/// An upper bound on the largest singular value of `m`: the square root of the largest
/// absolute row sum of mᵀm (Gershgorin), exact for a diagonal `m`.
fn largest_singular_value_bound<const D: usize>(m: &Matrix<D>) -> f64 {
    let c = m.transpose() * m;
    (0..D)
        .map(|i| (0..D).map(|j| c[(i, j)].abs()).sum::<f64>())
        .fold(0.0, f64::max)
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound is the singular value for a stretch and never below it for a shear.
    #[test]
    fn singular_value_bound_holds() {
        let stretch = Matrix::<2>::new(0.5, 0.0, 0.0, 2.0);
        assert!((largest_singular_value_bound(&stretch) - 2.0).abs() < 1e-15);
        let shear = Matrix::<3>::new(1.0, 0.7, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let exact = shear.singular_values().max();
        let bound = largest_singular_value_bound(&shear);
        assert!(bound >= exact && bound < 1.2 * exact, "{bound} vs {exact}");
    }
}
