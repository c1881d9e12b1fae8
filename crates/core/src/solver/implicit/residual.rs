//! The out-of-balance force of a trial displacement increment Δu on the grid:
//! R(Δu) = f_int(Δu) − f_ext (+ the Newmark inertia M a_{n+1} in the dynamic form).
//!
//! The internal force is the virtual work of the particles' stress in the configuration at
//! the start of the step: f_i = Σ_p V_p^n P_p ∇w_ip(x_p^n), with the first Piola stress of
//! the step's deformation P = J_Δ σ F_Δ^{-T} = σ cof(F_Δ), F_Δ = I + ∇Δu. The stress comes
//! from each material's own `update_stress` at F = F_Δ F_n, from the state at the start of
//! the step, so every plugin works unchanged.

use super::super::DimensionDispatch;
use super::super::parallel::{SharedSlice, chunk_count, chunk_range, ordered_reduce};
use super::super::simulation::Simulation;
use super::super::stress_derivative::stress_derivative;
use super::super::stress_update::{StressStats, update_stress};
use super::workspace::{INACTIVE, Mirror, NormalConstraint, Workspace};
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
            work.full[g + d] = m.sign(d) * work.full[f + d];
            if m.second != INACTIVE {
                let s = m.second as usize * D;
                work.full[g + d] = 2.0 * work.full[f + d] - work.full[s + d];
            }
        }
    }
}

/// Folds what landed on ghost nodes onto their mirrors (the transpose of [`mirror`], in
/// reverse order) and zeroes the ghosts.
pub(super) fn fold<const D: usize>(mirrors: &[Mirror], r: &mut [f64]) {
    for m in mirrors.iter().rev() {
        let (g, f) = (m.ghost as usize * D, m.front as usize * D);
        for d in 0..D {
            if m.second != INACTIVE {
                r[f + d] += 2.0 * r[g + d];
                r[m.second as usize * D + d] -= r[g + d];
            } else {
                r[f + d] += m.sign(d) * r[g + d];
            }
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

/// The gradient at particle `p` of a nodal vector field (one `D`-vector per unknown).
#[inline(always)]
fn nodal_gradient<const D: usize>(
    interp: &crate::physics::Interpolation<D>,
    entry_dof: &[u32],
    field: &[f64],
    p: usize,
) -> Matrix<D> {
    let mut grad = Matrix::<D>::zeros();
    for e in interp.entries(p) {
        let k = entry_dof[e] as usize * D;
        let dw = interp.gradient[e];
        for a in 0..D {
            for b in 0..D {
                grad[(a, b)] += field[k + a] * dw[b];
            }
        }
    }
    grad
}

/// Sets F = (I + ∇Δu) Fₙ on every particle from the mirrored increment in `work.full`
/// (with F-bar, scaled to the patch's mean volume change); returns false if a particle
/// would be inverted.
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
    let ok = (0..chunk_count(n))
        .into_par_iter()
        .map(|chunk| {
            let mut ok = true;
            for p in chunk_range(chunk, n) {
                let grad = nodal_gradient(interp, entry_dof, full, p);
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
        .reduce(|| true, |a, b| a && b);
    if ok {
        apply_fbar(sim, work, dt);
    }
    ok
}

/// With F-bar, averages the trial volume changes over the patches and scales each
/// particle's F (and rate) from A Fₙ to Ā Fₙ = s A Fₙ; nothing without F-bar.
fn apply_fbar<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    dt: f64,
) where
    dyn Material: DimensionDispatch<D>,
{
    let Some(average) = work.fbar.as_mut() else {
        return;
    };
    average.average(&work.grad_du, &work.volume_n);
    let average = &*average;
    let identity = Matrix::<D>::identity();
    let rate = !sim.particles.velocity_gradient.is_empty();
    let l_out = SharedSlice::new(&mut sim.particles.velocity_gradient);
    let grad_du = &work.grad_du;
    sim.particles
        .deformation_gradient
        .par_iter_mut()
        .enumerate()
        .for_each(|(p, f)| {
            let s = average.scale::<D>(p);
            *f *= s;
            if rate {
                // SAFETY: one particle per iteration.
                unsafe { *l_out.get(p) = ((identity + grad_du[p]) * s - identity) / dt };
            }
        });
}

/// The iterate's Ā_p = s_p (I + ∇Δu_p) (A_p without F-bar).
#[inline]
pub(super) fn a_bar<const D: usize>(work: &Workspace<D>, p: usize) -> Matrix<D> {
    let a = Matrix::<D>::identity() + work.grad_du[p];
    work.fbar.as_ref().map_or(a, |avg| a * avg.scale::<D>(p))
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
    let stress = &sim.particles.stress;
    let grad_du = std::mem::take(&mut work.grad_du);
    let identity = Matrix::<D>::identity();
    let scale = scatter_with(work, sim.particles.len(), out, |p| {
        stress[p] * cofactor(&(identity + grad_du[p]))
    });
    work.grad_du = grad_du;
    scale
}

/// Scatters Σ_p Vₙ P_p ∇w into `out` (unfolded) for the first Piola stress `piola(p)`,
/// threads writing buffers of their own; returns the norm of the individual contributions.
pub(super) fn scatter_with<const D: usize>(
    work: &mut Workspace<D>,
    n: usize,
    out: &mut [f64],
    piola: impl Fn(usize) -> Matrix<D> + Sync,
) -> f64 {
    let threads = work.buffers.len();
    let (interp, entry_dof, volume_n) = (&work.interp, &work.entry_dof, &work.volume_n);
    let buffers = SharedSlice::new(&mut work.buffers);
    let scale2: f64 = ordered_reduce(
        threads,
        || 0.0,
        |t| {
            // SAFETY: each task takes its own buffer.
            let buffer = unsafe { buffers.get(t) };
            buffer.fill(0.0);
            let per = n.div_ceil(threads);
            let mut scale2 = 0.0;
            let range = (t * per).min(n)..((t + 1) * per).min(n);
            for (p, volume) in volume_n
                .iter()
                .enumerate()
                .take(range.end)
                .skip(range.start)
            {
                let piola = piola(p) * *volume;
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
        },
        |a, b| a + b,
    );
    out.fill(0.0);
    for buffer in &work.buffers {
        for (o, b) in out.iter_mut().zip(buffer) {
            *o += b;
        }
    }
    scale2.sqrt()
}

/// The derivative of the cofactor matrix at `a` in the direction `g` (linear in 2D,
/// quadratic in 3D: cof(a + g) = cof(a) + dcof + cof(g)).
fn cofactor_derivative<const D: usize>(a: &Matrix<D>, g: &Matrix<D>) -> Matrix<D> {
    if D == 2 {
        cofactor(g)
    } else {
        cofactor(&(a + g)) - cofactor(a) - cofactor(g)
    }
}

/// Saves the particles' stress (and σzz in 2D) at the current iterate: the point the
/// tangent products linearise about (∇Δu there is in `work.grad_du`).
pub(super) fn linearise_at<const D: usize, K: Kernel>(
    sim: &Simulation<D, K>,
    work: &mut Workspace<D>,
) where
    dyn Material: DimensionDispatch<D>,
{
    work.stress_cur.clear();
    work.stress_cur.extend_from_slice(&sim.particles.stress);
    work.zz_cur.clear();
    work.zz_cur.extend_from_slice(&sim.particles.stress_zz);
}

/// The tangent applied to a direction `v`: J v = ∂R/∂Δu · v at the iterate saved by
/// [`linearise_at`]. The stress change of each particle is a directional difference of its
/// material's own update, with a step scaled to that particle's δF (so weakly and strongly
/// deformed particles are both resolved); the geometric part (the change of the cofactor) is
/// exact.
pub(super) fn tangent_product<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    v: &[f64],
    dt: f64,
    inertia: Option<Inertia>,
    out: &mut [f64],
) where
    dyn Material: DimensionDispatch<D>,
{
    // The mirrored direction goes through `full_v`; `full` keeps the iterate.
    std::mem::swap(&mut work.full, &mut work.full_v);
    mirror(work, v);
    std::mem::swap(&mut work.full, &mut work.full_v);
    if work.analytic {
        return tangent_product_analytic(sim, work, v, dt, inertia, out);
    }
    let n = sim.particles.len();
    let identity = Matrix::<D>::identity();
    let rate = !sim.particles.velocity_gradient.is_empty();
    work.grad_v.resize(n, Matrix::<D>::zeros());
    work.step_of.resize(n, 0.0);
    direction_gradients(work);
    let row_dot = work.out_of_plane.row_dot(a_bar_change(work));
    {
        let f_out = SharedSlice::new(&mut sim.particles.deformation_gradient);
        let l_out = SharedSlice::new(&mut sim.particles.velocity_gradient);
        let e_out = SharedSlice::new(&mut work.step_of);
        let work = &*work;
        let delta = a_bar_change(work);
        (0..chunk_count(n)).into_par_iter().for_each(|chunk| {
            for p in chunk_range(chunk, n) {
                let g = delta[p];
                let largest = g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let eps = if largest > 0.0 { 1e-7 / largest } else { 0.0 };
                let a = a_bar(work, p);
                // SAFETY: chunks are disjoint particle ranges.
                unsafe {
                    *f_out.get(p) = (a + g * eps) * work.f_n[p];
                    *e_out.get(p) = eps;
                    if rate {
                        *l_out.get(p) = (a - identity + g * eps) / dt;
                    }
                }
            }
        });
    }
    work.restore_state(sim);
    // ε₀ held: its response is the rank-one term (`out_of_plane.rs`).
    let strain = sim.stress_scratch.out_of_plane_strain();
    sim.stress_scratch
        .hold_out_of_plane_strain(strain, &sim.particles.groups);
    update_stress(&mut sim.particles, dt, &mut sim.stress_scratch);
    sim.stress_scratch
        .hold_out_of_plane_strain(None, &sim.particles.groups);
    let stress = &sim.particles.stress;
    let (grad_v, step_of, grad_du, stress_cur) = (
        std::mem::take(&mut work.grad_v),
        std::mem::take(&mut work.step_of),
        std::mem::take(&mut work.grad_du),
        std::mem::take(&mut work.stress_cur),
    );
    scatter_with(work, n, out, |p| {
        let eps = step_of[p];
        if eps == 0.0 {
            return Matrix::<D>::zeros();
        }
        let a = identity + grad_du[p];
        let d_stress = (stress[p] - stress_cur[p]) / eps;
        d_stress * cofactor(&a) + stress_cur[p] * cofactor_derivative(&a, &grad_v[p])
    });
    work.grad_v = grad_v;
    work.step_of = step_of;
    work.grad_du = grad_du;
    work.stress_cur = stress_cur;
    finish_product(work, v, inertia, out);
    work.out_of_plane.add(row_dot, out);
}

/// The common end of a tangent product: fold the ghosts, add the Newmark mass term, project.
fn finish_product<const D: usize>(
    work: &Workspace<D>,
    v: &[f64],
    inertia: Option<Inertia>,
    out: &mut [f64],
) {
    fold::<D>(&work.mirrors, out);
    if let Some(c) = inertia {
        for k in 0..work.node_of_dof.len() {
            let m = work.mass[k];
            if m > 0.0 {
                for d in 0..D {
                    out[k * D + d] += c.c_u * m * v[k * D + d];
                }
            }
        }
    }
    project(work, out);
}

/// The direction's gradient ∇v per particle into `work.grad_v` (from the mirrored direction
/// in `work.full_v`), and with F-bar the change of Ā along it, δĀ, into `work.direction`
/// (read both through [`a_bar_change`]).
fn direction_gradients<const D: usize>(work: &mut Workspace<D>) {
    let (interp, entry_dof, full_v) = (&work.interp, &work.entry_dof, &work.full_v);
    work.grad_v
        .par_iter_mut()
        .enumerate()
        .for_each(|(p, g)| *g = nodal_gradient(interp, entry_dof, full_v, p));
    let n = work.grad_v.len();
    work.direction.resize(n, Matrix::<D>::zeros());
    if let Some(average) = work.fbar.as_mut() {
        average.direction(
            &work.grad_du,
            &work.grad_v,
            &work.volume_n,
            &mut work.direction,
        );
    }
}

/// The change of Ā along the direction after [`direction_gradients`]: F-bar's δĀ, or ∇v
/// itself without F-bar (not copied).
fn a_bar_change<const D: usize>(work: &Workspace<D>) -> &[Matrix<D>] {
    if work.fbar.is_some() {
        &work.direction
    } else {
        &work.grad_v
    }
}

/// [`tangent_product`] with the laws' analytic stress derivative: δF = ∇v Fₙ per particle,
/// dσ from the laws at the iterate, no stress update. The direction is mirrored in
/// `work.full_v`.
fn tangent_product_analytic<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    v: &[f64],
    dt: f64,
    inertia: Option<Inertia>,
    out: &mut [f64],
) where
    dyn Material: DimensionDispatch<D>,
{
    let n = sim.particles.len();
    work.grad_v.resize(n, Matrix::<D>::zeros());
    work.direction.resize(n, Matrix::<D>::zeros());
    work.stress_change.resize(n, Matrix::<D>::zeros());
    direction_gradients(work);
    let row_dot = work.out_of_plane.row_dot(a_bar_change(work));
    // δF = δĀ Fₙ (∇v Fₙ without F-bar).
    if work.fbar.is_some() {
        work.direction
            .par_iter_mut()
            .zip(work.f_n.par_iter())
            .for_each(|(direction, f)| *direction *= f);
    } else {
        work.direction
            .par_iter_mut()
            .zip(work.grad_v.par_iter().zip(work.f_n.par_iter()))
            .for_each(|(direction, (g, f))| *direction = g * f);
    }
    stress_derivative(
        &sim.particles,
        &work.state_n,
        &work.direction,
        sim.stress_scratch.last_stretch(),
        dt,
        &mut work.derivative_scratch,
        &mut work.stress_change,
    );
    let identity = Matrix::<D>::identity();
    let (grad_v, stress_change, grad_du, stress_cur) = (
        std::mem::take(&mut work.grad_v),
        std::mem::take(&mut work.stress_change),
        std::mem::take(&mut work.grad_du),
        std::mem::take(&mut work.stress_cur),
    );
    scatter_with(work, n, out, |p| {
        let a = identity + grad_du[p];
        stress_change[p] * cofactor(&a) + stress_cur[p] * cofactor_derivative(&a, &grad_v[p])
    });
    work.grad_v = grad_v;
    work.stress_change = stress_change;
    work.grad_du = grad_du;
    work.stress_cur = stress_cur;
    finish_product(work, v, inertia, out);
    work.out_of_plane.add(row_dot, out);
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
