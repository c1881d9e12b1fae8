//! The explicit step with CPDI's domain stencils (`solver.kernel: "cpdi2"`): every step
//! each particle's stencil is built through the corners of its domain deformed by F
//! ([`super::cpdi_stencils`]); P2G gathers through the stencils' transpose, the grid update
//! (walls, obstacles, gravity) is the explicit step's, and G2P updates F as Ḟ = (Σ vᵢ ⊗ ∇wᵢ)F.
//! The internal force is −Σ V σ ∇w with V = V₀ det F. Transfers PIC, FLIP and APIC; schemes
//! USL and MUSL (validation refuses the rest, `scene::cpdi`).

use super::DimensionDispatch;
use super::cpdi_stencils::{NodeBox, build_domain_stencils};
use super::gather_transfer::{Frame, GatherStencils};
use super::mode::StepMode;
use super::simulation::Simulation;
use super::stage_clock::StepStage;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::determinant;
use crate::scene::Scheme;
use rayon::prelude::*;
use std::time::Instant;

/// CPDI's state: only buffers, rebuilt every step (so a resumed run needs nothing saved).
#[derive(Default)]
pub(super) struct Cpdi<const D: usize> {
    /// This step's stencils, their transpose and force matrices.
    gather: GatherStencils<D>,
    /// Each particle's node box (scratch).
    boxes: Vec<NodeBox>,
}

impl<const D: usize, K: Kernel> StepMode<D, K> for Cpdi<D>
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        let start = Instant::now();
        build_domain_stencils(
            &sim.grid,
            &sim.particles,
            &mut self.boxes,
            &mut self.gather.stencil,
        );
        self.gather.index(sim, &sim.particles.position);
        sim.clock.add(StepStage::Bin, start);
        let start = Instant::now();
        let p = &sim.particles;
        self.gather
            .force_matrix
            .par_iter_mut()
            .enumerate()
            .for_each(|(k, a)| {
                let volume = p.volume0[k] * determinant(&p.deformation_gradient[k]);
                *a = p.stress[k] * volume;
            });
        sim.clock.add(StepStage::Stress, start);
        sim.grid.clear();
        let g = &self.gather;
        g.p2g(sim, Frame::Domains, dt, true);
        sim.grid_update(dt, true);
        match sim.settings.scheme {
            Scheme::Musl => {
                // As the explicit MUSL: velocities first, then the new velocities mapped back
                // through the step's stencils move the particles and grow F.
                g.g2p(sim, Frame::Domains, dt, true, false, false);
                sim.grid.clear_momentum();
                g.p2g(sim, Frame::Domains, dt, false);
                sim.grid_update(dt, false);
                g.g2p(sim, Frame::Domains, dt, false, true, true);
            }
            // Validation refuses USF with CPDI.
            _ => g.g2p(sim, Frame::Domains, dt, true, true, true),
        }
        sim.update_stresses(dt);
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        sim.mechanical_dt().min(sim.physics_dt)
    }
}
