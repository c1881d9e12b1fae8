//! The out-of-balance force of a trial displacement increment Δu on the grid:
//! R(Δu) = f_int(Δu) − f_ext (+ the Newmark inertia M a_{n+1} in the dynamic form).
//!
//! The internal force is the virtual work of the particles' stress in the configuration at
//! the start of the step: f_i = Σ_p V_p^n P_p ∇w_ip(x_p^n), with the first Piola stress of
//! the step's deformation P = J_Δ σ F_Δ^{-T} = σ cof(F_Δ), F_Δ = I + ∇Δu. The stress comes
//! from each material's own `update_stress` at F = F_Δ F_n, from the state at the start of
//! the step, so every plugin works unchanged.

use super::super::DimensionDispatch;
use super::super::parallel::{SharedSlice, chunk_count, chunk_range};
use super::super::simulation::Simulation;
use super::super::stress_update::{StressStats, update_stress};
use super::workspace::{Mirror, NormalConstraint, Workspace};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, cofactor, determinant};
use rayon::prelude::*;

/// What an evaluation found besides the residual.
#[derive(Clone, Copy, Debug)]
pub(super) struct Evaluation {
    /// The stress update's statistics (strain energy, wave speed, free-strain work).
    pub stress: StressStats,
    /// Norm of the particles' individual force contributions: the scale the residual is
    /// judged against when the loads balance to nothing.
    pub force_scale: f64,
    /// False when a particle would be inverted (det F_Δ ≤ 0) or a stress is not finite: the
    /// residual is then meaningless.
    pub valid: bool,
}

/// Newmark coefficients of the dynamic form: M a_{n+1} = c_u M (Δu − dt vₙ) − c_a M aₙ.
#[derive(Clone, Copy, Debug)]
pub(super) struct Inertia {
    pub c_u: f64,
    pub c_a: f64,
    pub dt: f64,
}

/// Copies `du` into the workspace's full vector and gives every ghost node the image of its
/// mirror (negated behind a stick wall, normal component negated behind a symmetry wall).
pub(super) fn mirror<const D: usize>(work: &mut Workspace<D>, du: &[f64]) {
    work.full.copy_from_slice(du);
    for m in &work.mirrors {
        let (g, f) = (m.ghost as usize * D, m.front as usize * D);
        for d in 0..D {
            let v = work.full[f + d];
            work.full[g + d] = if !m.symmetry || d == m.axis as usize {
                -v
            } else {
                v
            };
        }
    }
}

/// Folds what landed on ghost nodes onto their mirrors (the transpose of [`mirror`], in
/// reverse order) and zeroes the ghosts.
pub(super) fn fold<const D: usize>(mirrors: &[Mirror], r: &mut [f64]) {
    for m in mirrors.iter().rev() {
        let (g, f) = (m.ghost as usize * D, m.front as usize * D);
        for d in 0..D {
            let v = r[g + d];
            r[f + d] += if !m.symmetry || d == m.axis as usize {
                -v
            } else {
                v
            };
            r[g + d] = 0.0;
        }
    }
}

/// Removes the constrained components: fixed ones are zeroed, general normals projected out.
pub(super) fn project<const D: usize>(work: &Workspace<D>, r: &mut [f64]) {
    project_with(&work.mask, &work.normals, r);
}

/// [`project`] with the constraints given apart from the workspace.
pub(super) fn project_with<const D: usize>(
    mask: &[f64],
    normals: &[NormalConstraint<D>],
    r: &mut [f64],
) {
    for (v, m) in r.iter_mut().zip(mask) {
        *v *= m;
    }
    for c in normals {
        let k = c.dof as usize * D;
        let dot: f64 = (0..D).map(|d| r[k + d] * c.normal[d]).sum();
        for d in 0..D {
            r[k + d] -= dot * c.normal[d];
        }
    }
}

/// Sets F = (I + ∇Δu) Fₙ on every particle from the mirrored increment in `work.full`;
/// returns false if a particle would be inverted.
fn gather<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    dt: f64,
) -> bool
where
    dyn Material: DimensionDispatch<D>,
{
    let n = sim.particles.len();
    let identity = Matrix::<D>::identity();
    let rate = !sim.particles.velocity_gradient.is_empty();
    let f_out = SharedSlice::new(&mut sim.particles.deformation_gradient);
    let l_out = SharedSlice::new(&mut sim.particles.velocity_gradient);
    let g_out = SharedSlice::new(&mut work.grad_du);
    let (interp, entry_dof, full, f_n) = (&work.interp, &work.entry_dof, &work.full, &work.f_n);
    (0..chunk_count(n))
        .into_par_iter()
        .map(|chunk| {
            let mut ok = true;
            for p in chunk_range(chunk, n) {
                let mut grad = Matrix::<D>::zeros();
                for e in interp.entries(p) {
                    let k = entry_dof[e] as usize * D;
                    let dw = interp.gradient[e];
                    for a in 0..D {
                        for b in 0..D {
                            grad[(a, b)] += full[k + a] * dw[b];
                        }
                    }
                }
                let step = identity + grad;
                ok &= determinant(&step) > 0.0;
                // SAFETY: chunks are disjoint particle ranges.
                unsafe {
                    *f_out.get(p) = step * f_n[p];
                    *g_out.get(p) = grad;
                    if rate {
                        *l_out.get(p) = grad / dt;
                    }
                }
            }
            ok
        })
        .reduce(|| true, |a, b| a && b)
}

/// Scatters f_i = Σ_p Vₙ σ cof(I + ∇Δu) ∇w into `out` (unfolded); returns the norm of the
/// individual contributions.
fn scatter<const D: usize, K: Kernel>(
    sim: &Simulation<D, K>,
    work: &mut Workspace<D>,
    out: &mut [f64],
) -> f64
where
    dyn Material: DimensionDispatch<D>,
{
    let n = sim.particles.len();
    let threads = work.buffers.len();
    let stress = &sim.particles.stress;
    let (interp, entry_dof, grad_du, volume_n) =
        (&work.interp, &work.entry_dof, &work.grad_du, &work.volume_n);
    let identity = Matrix::<D>::identity();
    let scale2: f64 = work
        .buffers
        .par_iter_mut()
        .enumerate()
        .map(|(t, buffer)| {
            buffer.fill(0.0);
            let per = n.div_ceil(threads);
            let mut scale2 = 0.0;
            for p in t * per..((t + 1) * per).min(n) {
                let piola = stress[p] * cofactor(&(identity + grad_du[p])) * volume_n[p];
                for e in interp.entries(p) {
                    let f = piola * interp.gradient[e];
                    let k = entry_dof[e] as usize * D;
                    for d in 0..D {
                        buffer[k + d] += f[d];
                    }
                    scale2 += f.norm_squared();
                }
            }
            scale2
        })
        .sum();
    out.fill(0.0);
    for buffer in &work.buffers {
        for (o, b) in out.iter_mut().zip(buffer) {
            *o += b;
        }
    }
    scale2.sqrt()
}

/// The internal force of the particles' current stress with no increment (∇Δu = 0),
/// folded: the start-of-step balance of the dynamic form.
pub(super) fn internal_force_now<const D: usize, K: Kernel>(
    sim: &Simulation<D, K>,
    work: &mut Workspace<D>,
    out: &mut [f64],
) where
    dyn Material: DimensionDispatch<D>,
{
    work.grad_du.fill(Matrix::<D>::zeros());
    scatter(sim, work, out);
    fold::<D>(&work.mirrors, out);
}

/// Evaluates the residual of the increment `du` into `out`: particles take the trial F and
/// stress (from the snapshot's state), then forces are scattered, folded and projected.
pub(super) fn evaluate<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    du: &[f64],
    dt: f64,
    inertia: Option<Inertia>,
    out: &mut [f64],
) -> Evaluation
where
    dyn Material: DimensionDispatch<D>,
{
    mirror(work, du);
    let valid = gather(sim, work, dt);
    if !valid {
        out.fill(f64::INFINITY);
        return Evaluation {
            stress: StressStats::default(),
            force_scale: 0.0,
            valid: false,
        };
    }
    work.restore_state(sim);
    let stress = update_stress(&mut sim.particles, dt, &mut sim.stress_scratch);
    let force_scale = scatter(sim, work, out);
    for (o, f) in out.iter_mut().zip(&work.external) {
        *o -= f;
    }
    fold::<D>(&work.mirrors, out);
    if let Some(c) = inertia {
        for k in 0..work.node_of_dof.len() {
            let m = work.mass[k];
            if m <= 0.0 {
                continue;
            }
            for d in 0..D {
                let i = k * D + d;
                out[i] += c.c_u * m * (du[i] - c.dt * work.velocity[i]) - c.c_a * work.force0[i];
            }
        }
    }
    project(work, out);
    let finite = out.iter().all(|v| v.is_finite());
    Evaluation {
        stress,
        force_scale,
        valid: finite && stress.non_finite.is_none(),
    }
}
