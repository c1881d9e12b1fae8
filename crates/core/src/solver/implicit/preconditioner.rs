//! The preconditioner of the implicit solver's Krylov iterations: an estimate of the
//! tangent, K = Σ_p Vₙ (Bᵀ C B + the initial-stress term ∇wₐ·σ∇w_b I) with each particle's C
//! measured from its material's own stress update (`tangent_estimate.rs`: the whole tangent,
//! or with F-bar an isotropic λ, μ; the isotropic one also when the whole one does not
//! factor), plus the Newmark mass term,
//! assembled at every Newton iteration from the particles' current stress and factored by a
//! sparse Cholesky. The initial-stress term matters for thin, prestressed bodies (a
//! bimaterial strip's bending mode is as soft as its geometric stiffness); when it makes the
//! estimate indefinite the material part alone is factored. Ghost nodes are folded onto their mirrors and fixed components
//! dropped, as in the residual. Jacobi (the same estimate's diagonal) is the fallback when
//! the assembly would be too large or the factorisation fails.

use super::super::DimensionDispatch;
use super::super::simulation::Simulation;
use super::residual::Inertia;
use super::tangent_estimate::{add_anisotropic_block, deviatoric_part, volumetric_part};
use super::workspace::{INACTIVE, Workspace};
use crate::kernels::Kernel;
use crate::linear_solvers::sparse_cholesky::{Precision, SparseCholesky};
use crate::material::Material;
use faer::sparse::Pair;

/// Most matrix entries (before summing duplicates) the assembly may make: about 48 bytes
/// each with the pattern cache, so up to ~5 GB (a 3D strip of 138,240 particles makes 57
/// million); a larger system falls back to Jacobi.
const MAX_TRIPLETS: usize = 100_000_000;

/// The unknowns a component maps to (following ghost mirrors and weak-node ties) with their
/// factors: none when it is fixed, two for a node extrapolated from two neighbours.
fn targets<const D: usize>(work: &Workspace<D>, mut dof: usize, d: usize) -> [(usize, f64); 2] {
    const NONE: (usize, f64) = (usize::MAX, 0.0);
    let free = |dof: usize, factor: f64| {
        let i = dof * D + d;
        if work.mask[i] > 0.0 {
            (i, factor)
        } else {
            NONE
        }
    };
    let mut sign = 1.0;
    for _ in 0..8 {
        let mirror = work.ghost_mirror[dof];
        if mirror == INACTIVE {
            return [free(dof, sign), NONE];
        }
        let m = work.mirrors[mirror as usize];
        if m.second != INACTIVE {
            return [
                free(m.front as usize, 2.0 * sign),
                free(m.second as usize, -sign),
            ];
        }
        sign *= m.sign(d);
        dof = m.front as usize;
    }
    [NONE, NONE]
}

/// Assembles and factors the elastic estimate; `None` when it is too large or not
/// positive definite (the caller then uses Jacobi).
pub(super) fn factor<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    inertia: Option<Inertia>,
    dt: f64,
    damping: f64,
    precision: Precision,
) -> Option<SparseCholesky>
where
    dyn Material: DimensionDispatch<D>,
{
    if work.len() == 0 {
        return None;
    }
    super::residual::linearise_at(sim, work);
    super::tangent_estimate::probe(sim, work, dt);
    let attempt = |sim: &Simulation<D, K>, work: &mut Workspace<D>| {
        assemble_and_factor(sim, work, inertia, damping, true, precision)
            .or_else(|| assemble_and_factor(sim, work, inertia, damping, false, precision))
    };
    attempt(sim, work).or_else(|| {
        // A whole tangent that is not positive definite (a softening particle): the
        // isotropic estimate, whose moduli are floored, instead.
        if work.tangent.is_empty() {
            return None;
        }
        work.tangent.clear();
        attempt(sim, work)
    })
}

fn assemble_and_factor<const D: usize, K: Kernel>(
    sim: &Simulation<D, K>,
    work: &mut Workspace<D>,
    inertia: Option<Inertia>,
    damping: f64,
    geometric: bool,
    precision: Precision,
) -> Option<SparseCholesky>
where
    dyn Material: DimensionDispatch<D>,
{
    let n = work.len();
    let mut pairs = std::mem::take(&mut work.pairs);
    let mut values = std::mem::take(&mut work.values);
    pairs.clear();
    values.clear();
    // Particles whose stencils start at the same node share every node pair: their element
    // matrices are summed in one block before the entries are listed (a quarter of the
    // entries in 2D with 2 particles per cell and direction, an eighth in 3D).
    let stencil = work.interp.stencil;
    let mut order = std::mem::take(&mut work.order);
    order.clear();
    order.extend(0..sim.particles.len() as u32);
    match &work.fbar {
        // Patches are (first node's unknown, material): contiguous within a node's run.
        Some(average) => order.sort_unstable_by_key(|&p| average.patch(p as usize)),
        None => order.sort_unstable_by_key(|&p| work.interp.node[p as usize * stencil]),
    }
    let runs = 1 + order
        .windows(2)
        .filter(|w| {
            work.interp.node[w[0] as usize * stencil] != work.interp.node[w[1] as usize * stencil]
        })
        .count();
    if runs * stencil * stencil * D * D / 2 + n > MAX_TRIPLETS {
        work.order = order;
        work.pairs = pairs;
        work.values = values;
        return None;
    }
    let fbar = work.fbar.is_some();
    // The whole tangent where it was measured (split with F-bar), else the isotropic moduli.
    let anisotropic = work.tangent.len() == sim.particles.len();
    let mut patch = std::mem::take(&mut work.patch_gradient);
    let mut block = std::mem::take(&mut work.block);
    block.clear();
    block.resize(stencil * stencil * D * D, 0.0);
    // The unknowns each stencil entry's components map to, per block.
    let mut mapped = std::mem::take(&mut work.mapped);
    let mut run_start = 0;
    while run_start < order.len() {
        let first = work.interp.node[order[run_start] as usize * stencil];
        let mut run_end = run_start;
        block.fill(0.0);
        patch.clear();
        patch.resize(stencil, crate::math::Vector::<D>::zeros());
        let (mut bulk_volume, mut patch_volume) = (0.0, 0.0);
        let mut current = None;
        while run_end < order.len() && work.interp.node[order[run_end] as usize * stencil] == first
        {
            let p = order[run_end] as usize;
            let [mut lambda, mut mu] = work.moduli[p];
            let v = work.volume_n[p];
            if let Some(average) = &work.fbar {
                let patch_of_p = average.patch(p);
                if current.is_some_and(|c| c != patch_of_p) {
                    add_patch_block(&mut block, &mut patch, bulk_volume, patch_volume);
                    (bulk_volume, patch_volume) = (0.0, 0.0);
                }
                current = Some(patch_of_p);
                // The particle keeps its deviatoric stiffness; the volumetric one (eᵀCe/D²
                // of the whole tangent, or κ = λ + 2μ/D) acts on the patch's mean
                // dilatation (added below).
                bulk_volume += v * if anisotropic {
                    volumetric_part::<D>(&work.tangent[p])
                } else {
                    lambda + 2.0 * mu / D as f64
                };
                patch_volume += v;
                lambda = -2.0 * mu / D as f64;
                for (a, g) in patch.iter_mut().enumerate() {
                    *g += work.interp.gradient[p * stencil + a] * v;
                }
            }
            let stress = sim.particles.stress[p];
            let base = p * stencil;
            if anisotropic {
                let gradient = &work.interp.gradient[base..base + stencil];
                // With F-bar the volumetric part went to the patch above.
                let deviatoric;
                let tangent = if fbar {
                    deviatoric = deviatoric_part::<D>(&work.tangent[p]);
                    &deviatoric
                } else {
                    &work.tangent[p]
                };
                add_anisotropic_block(&mut block, gradient, tangent, v);
                (lambda, mu) = (0.0, 0.0);
            }
            for a in 0..stencil {
                let ga = work.interp.gradient[base + a];
                let sa = stress * ga;
                for b in 0..stencil {
                    let gb = work.interp.gradient[base + b];
                    let dot = ga.dot(&gb) * mu + if geometric { sa.dot(&gb) } else { 0.0 };
                    for i in 0..D {
                        for j in 0..D {
                            let mut k = lambda * ga[i] * gb[j] + mu * ga[j] * gb[i];
                            if i == j {
                                k += dot;
                            }
                            block[((a * stencil + b) * D + i) * D + j] += v * k;
                        }
                    }
                }
            }
            run_end += 1;
        }
        if fbar {
            add_patch_block(&mut block, &mut patch, bulk_volume, patch_volume);
        }
        let base = order[run_start] as usize * stencil;
        mapped.clear();
        for a in 0..stencil {
            let dof = work.entry_dof[base + a] as usize;
            mapped.extend((0..D).map(|i| targets(work, dof, i)));
        }
        for a in 0..stencil {
            for b in 0..stencil {
                for i in 0..D {
                    let rows = mapped[a * D + i];
                    for j in 0..D {
                        let k = block[((a * stencil + b) * D + i) * D + j];
                        for &(row, si) in &rows {
                            for &(col, sj) in &mapped[b * D + j] {
                                if si != 0.0 && sj != 0.0 && col <= row {
                                    pairs.push(Pair::new(row, col));
                                    values.push(k * si * sj);
                                }
                            }
                        }
                    }
                }
            }
        }
        run_start = run_end;
    }
    work.order = order;
    work.patch_gradient = patch;
    work.block = block;
    work.mapped = mapped;
    for i in 0..n {
        let inv = work.inverse_diagonal[i];
        if inv > 0.0 {
            // Mass term, the Newton damping, and a small shift so a body held only in part
            // stays factorable.
            let mut diag = (1e-8 + damping) / inv;
            if let Some(c) = inertia {
                diag += c.c_u * work.mass[i / D];
            }
            pairs.push(Pair::new(i, i));
            values.push(diag);
        } else {
            pairs.push(Pair::new(i, i));
            values.push(1.0);
        }
    }
    let result =
        SparseCholesky::factor_with_pattern_in(n, &pairs, &values, &mut work.pattern, precision)
            .ok();
    work.pairs = pairs;
    work.values = values;
    result
}

/// Adds one F-bar patch's volumetric stiffness to a run's element block and clears the
/// patch's gradient sums: κ̄ W θ̄²/2 with θ̄ = Σ_p Vₚ ∇wₚ·u / W is the stiffness κ̄ G Gᵀ / W,
/// G = Σ_p Vₚ ∇wₚ (`patch`), κ̄ = Σ Vκ / W (`bulk_volume` = Σ Vκ, `patch_volume` = W).
fn add_patch_block<const D: usize>(
    block: &mut [f64],
    patch: &mut [crate::math::Vector<D>],
    bulk_volume: f64,
    patch_volume: f64,
) {
    let stencil = patch.len();
    if patch_volume > 0.0 {
        let factor = bulk_volume / (patch_volume * patch_volume);
        for a in 0..stencil {
            for b in 0..stencil {
                for i in 0..D {
                    for j in 0..D {
                        block[((a * stencil + b) * D + i) * D + j] +=
                            factor * patch[a][i] * patch[b][j];
                    }
                }
            }
        }
    }
    patch.fill(crate::math::Vector::<D>::zeros());
}
