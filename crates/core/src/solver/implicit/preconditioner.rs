//! The preconditioner of the implicit solver's Krylov iterations: an estimate of the
//! tangent, K = Σ_p Vₙ (Bᵀ C B + the initial-stress term ∇wₐ·σ∇w_b I) with an isotropic C
//! (each particle's λ, μ measured from its material's own stress update), plus the Newmark
//! mass term,
//! assembled at every Newton iteration from the particles' current stress and factored by a
//! sparse Cholesky. The initial-stress term matters for thin, prestressed bodies (a
//! bimaterial strip's bending mode is as soft as its geometric stiffness); when it makes the
//! estimate indefinite the material part alone is factored. Ghost nodes are folded onto their mirrors and fixed components
//! dropped, as in the residual. Jacobi (the same estimate's diagonal) is the fallback when
//! the assembly would be too large or the factorisation fails.

use super::super::DimensionDispatch;
use super::super::simulation::Simulation;
use super::residual::Inertia;
use super::workspace::{INACTIVE, Workspace};
use crate::kernels::Kernel;
use crate::linear_solvers::sparse_cholesky::SparseCholesky;
use crate::material::Material;
use faer::sparse::Triplet;

/// Most matrix entries (before summing duplicates) the assembly may make (~24 bytes each).
const MAX_TRIPLETS: usize = 20_000_000;

/// The unknown a component maps to (following ghost mirrors) with its sign, or `None` when
/// it is fixed.
fn target<const D: usize>(work: &Workspace<D>, mut dof: usize, d: usize) -> Option<(usize, f64)> {
    let mut sign = 1.0;
    for _ in 0..8 {
        let mirror = work.ghost_mirror[dof];
        if mirror == INACTIVE {
            let i = dof * D + d;
            return (work.mask[i] > 0.0).then_some((i, sign));
        }
        let m = work.mirrors[mirror as usize];
        if !m.symmetry || d == m.axis as usize {
            sign = -sign;
        }
        dof = m.front as usize;
    }
    None
}

/// Assembles and factors the elastic estimate; `None` when it is too large or not
/// positive definite (the caller then uses Jacobi).
pub(super) fn factor<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    inertia: Option<Inertia>,
    dt: f64,
) -> Option<SparseCholesky>
where
    dyn Material: DimensionDispatch<D>,
{
    let n = work.len();
    let stencil = work.interp.stencil;
    let estimate = sim.particles.len() * stencil * stencil * D * D / 2 + n;
    if n == 0 || estimate > MAX_TRIPLETS {
        return None;
    }
    super::residual::linearise_at(sim, work);
    super::residual::probe_moduli(sim, work, dt);
    assemble_and_factor(sim, work, inertia, true)
        .or_else(|| assemble_and_factor(sim, work, inertia, false))
}

fn assemble_and_factor<const D: usize, K: Kernel>(
    sim: &Simulation<D, K>,
    work: &mut Workspace<D>,
    inertia: Option<Inertia>,
    geometric: bool,
) -> Option<SparseCholesky>
where
    dyn Material: DimensionDispatch<D>,
{
    let n = work.len();
    let mut triplets = std::mem::take(&mut work.triplets);
    triplets.clear();
    {
        for p in 0..sim.particles.len() {
            let [lambda, mu] = work.moduli[p];
            let v = work.volume_n[p];
            let stress = sim.particles.stress[p];
            let entries = work.interp.entries(p);
            for a in entries.clone() {
                let ga = work.interp.gradient[a];
                let dof_a = work.entry_dof[a] as usize;
                let sa = stress * ga;
                for b in entries.clone() {
                    let gb = work.interp.gradient[b];
                    let dof_b = work.entry_dof[b] as usize;
                    let dot = ga.dot(&gb) * mu + if geometric { sa.dot(&gb) } else { 0.0 };
                    for i in 0..D {
                        let Some((row, si)) = target(work, dof_a, i) else {
                            continue;
                        };
                        for j in 0..D {
                            let Some((col, sj)) = target(work, dof_b, j) else {
                                continue;
                            };
                            if col > row {
                                continue;
                            }
                            let mut k = lambda * ga[i] * gb[j] + mu * ga[j] * gb[i];
                            if i == j {
                                k += dot;
                            }
                            triplets.push(Triplet::new(row, col, v * k * si * sj));
                        }
                    }
                }
            }
        }
    }
    for i in 0..n {
        let inv = work.inverse_diagonal[i];
        if inv > 0.0 {
            // Mass term, and a small shift so a body held only in part stays factorable.
            let mut diag = 1e-8 / inv;
            if let Some(c) = inertia {
                diag += c.c_u * work.mass[i / D];
            }
            triplets.push(Triplet::new(i, i, diag));
        } else {
            triplets.push(Triplet::new(i, i, 1.0));
        }
    }
    let result = SparseCholesky::factor(n, &triplets).ok();
    work.triplets = triplets;
    result
}
