//! The particle update after a converged implicit step: velocities from the Newmark rule
//! on the grid (through the explicit path's own G2P, so PIC, FLIP and APIC behave as they
//! do there), positions moved by the interpolated increment, statistics.

use super::super::DimensionDispatch;
use super::super::grid_to_particle::measure;
use super::super::simulation::Simulation;
use super::super::stats::ParticleFault;
use super::super::stencil::stencil_fits;
use super::newton::NewtonResult;
use super::residual::{Inertia, mirror};
use super::workspace::Workspace;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector};
use crate::scene::ImplicitSettings;

/// Moves the particles by the converged increment `du` and gives them their new velocity
/// (zero in the static form); F and stress already hold the converged state.
pub(super) fn update_particles<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    du: &[f64],
    settings: &ImplicitSettings,
    dt: f64,
    inertia: Option<Inertia>,
    result: NewtonResult,
) where
    dyn Material: DimensionDispatch<D>,
{
    if let Some(e) = result.last {
        sim.stresses = e.stress;
        sim.ledger.free_strain += e.stress.free_strain_work;
        sim.ledger.plastic += e.stress.plastic_work;
    }
    mirror(work, du);
    if let Some(c) = inertia {
        // Newmark: a_{n+1} = c_u (Δu − dt vₙ) − c_a aₙ, v_{n+1} = vₙ + dt((1−γ)aₙ + γ a_{n+1}).
        let gamma = settings.gamma;
        for (k, &node) in work.node_of_dof.iter().enumerate() {
            let m = work.mass[k];
            let mut v = Vector::<D>::zeros();
            if m > 0.0 {
                for d in 0..D {
                    let i = k * D + d;
                    let a_n = work.force0[i] / m;
                    let a_next = c.c_u * (du[i] - dt * work.velocity[i]) - c.c_a * a_n;
                    v[d] = work.velocity[i] + dt * ((1.0 - gamma) * a_n + gamma * a_next);
                }
            }
            sim.grid.momentum[node as usize] = v;
        }
        sim.boundaries.mirror_stick_walls(&mut sim.grid);
        sim.g2p(dt, true, false, false);
    } else {
        sim.particles.velocity.fill(Vector::<D>::zeros());
        sim.particles.affine.fill(Matrix::<D>::zeros());
    }
    let interp = &work.interp;
    let full = &work.full;
    let entry_dof = &work.entry_dof;
    for (p, x) in sim.particles.position.iter_mut().enumerate() {
        for e in interp.entries(p) {
            let k = entry_dof[e] as usize * D;
            let w = interp.weight[e];
            for d in 0..D {
                x[d] += w * full[k + d];
            }
        }
    }
    let mut stats = measure(&sim.particles, sim.settings.gravity);
    for p in 0..sim.particles.len() {
        let half = if K::USES_PARTICLE_SIZE {
            sim.particles.half_size[p]
        } else {
            0.0
        };
        if !stencil_fits::<D, K>(&sim.grid, &sim.particles.position[p], half) {
            stats.escaped = Some(ParticleFault {
                particle: p,
                field: "position",
                value: sim.particles.position[p].norm(),
            });
            break;
        }
    }
    sim.kinematics = stats;
}
