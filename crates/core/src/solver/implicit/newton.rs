//! Newton iterations on the grid displacement increment with a matrix-free Krylov solve
//! per iteration (the tangent applied through each particle's directional stress
//! difference: Jacobian-free Newton–Krylov, so every material plugin works without a
//! tangent of its own), a factored elastic preconditioner, Levenberg–Marquardt damping where the
//! tangent is nearly singular, and a backtracking line search.

use super::super::DimensionDispatch;
use super::super::simulation::Simulation;
use super::residual::{Evaluation, Inertia, evaluate, tangent_product};
use super::workspace::Workspace;
use crate::kernels::Kernel;
use crate::linear_solvers::conjugate_gradient::{self, Work};
use crate::linear_solvers::gmres::{self, GmresWork};
use crate::linear_solvers::sparse_cholesky::{Precision, SparseCholesky};
use crate::material::Material;
use crate::scene::{FactorPrecision, ImplicitSettings};

/// Vectors of the Newton and Krylov iterations, sized to the unknowns.
#[derive(Default)]
pub(super) struct NewtonVectors {
    pub du: Vec<f64>,
    pub residual: Vec<f64>,
    pub trial: Vec<f64>,
    pub trial_residual: Vec<f64>,
    pub direction: Vec<f64>,
    pub rhs: Vec<f64>,
    pub cg: [Vec<f64>; 4],
    pub gmres: Option<GmresWork>,
}

impl NewtonVectors {
    pub fn resize(&mut self, n: usize, restart: Option<usize>) {
        for v in [
            &mut self.du,
            &mut self.residual,
            &mut self.trial,
            &mut self.trial_residual,
            &mut self.direction,
            &mut self.rhs,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        for v in &mut self.cg {
            v.clear();
            v.resize(n, 0.0);
        }
        if let Some(m) = restart {
            match &mut self.gmres {
                Some(g) if g.restart() == m => g.resize(n),
                slot => *slot = Some(GmresWork::new(n, m)),
            }
        }
    }
}

/// A factored preconditioner kept from one step for the next (`reuse_preconditioner`),
/// with the unknowns and step it was factored for: it is used only where they are the
/// same.
pub(super) struct CarriedFactor {
    factor: SparseCholesky,
    node_of_dof: Vec<u32>,
    mask: Vec<f64>,
    dt: f64,
}

impl CarriedFactor {
    /// Whether the factor fits this step's unknowns (nodes, fixed components) and step.
    fn fits<const D: usize>(&self, work: &Workspace<D>, dt: f64) -> bool {
        // The step to round-off (steps that land on output times differ in the last digits).
        (self.dt - dt).abs() <= 1e-9 * dt
            && self.node_of_dof == work.node_of_dof
            && self.mask == work.mask
    }
}

/// How a Newton solve ended.
#[derive(Clone, Copy, Debug)]
pub(super) struct NewtonResult {
    pub converged: bool,
    pub iterations: u32,
    pub krylov_iterations: u32,
    /// Preconditioner factorisations made.
    pub factorisations: u32,
    /// Residual norm and the scale it was judged against at the end.
    pub residual: f64,
    pub scale: f64,
    /// Unknown with the largest residual at the end.
    pub worst: usize,
    pub last: Option<Evaluation>,
}

/// Levenberg–Marquardt damping of the Newton direction. Where the tangent is nearly
/// singular (a liquid before it gels has next to no shear stiffness) a full Newton step
/// moves far along the soft modes, the residual does not follow the linear model and the
/// line search stalls. Adding `damping`·diag(K̃) (the Jacobi estimate) to the Krylov
/// operator and the preconditioner, never to the residual, shortens those moves and leaves
/// the converged answer unchanged. It starts at zero (plain Newton), rises tenfold from
/// [`DAMPING_START`] after a step that needed the line search or did not halve the residual,
/// and falls tenfold (to zero) after one that did.
trait Damping {
    fn stiffen(self) -> Self;
    fn relax(self) -> Self;
}

/// Krylov iterations past which the factored preconditioner is made again at the next
/// Newton iteration.
const STALE: u32 = 20;

/// The first damping tried.
const DAMPING_START: f64 = 1e-6;
/// The most damping tried before the step is given up (and cut).
const DAMPING_MAX: f64 = 1e-2;

impl Damping for f64 {
    fn stiffen(self) -> f64 {
        (self * 10.0).max(DAMPING_START)
    }
    fn relax(self) -> f64 {
        if self > DAMPING_START {
            self * 0.1
        } else {
            0.0
        }
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Solves R(Δu) = 0 starting from `vectors.du`; the particles hold F and stress of the
/// returned increment when it converged.
#[allow(clippy::too_many_arguments)]
pub(super) fn solve<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    vectors: &mut NewtonVectors,
    settings: &ImplicitSettings,
    use_cg: bool,
    dt: f64,
    inertia: Option<Inertia>,
) -> NewtonResult
where
    dyn Material: DimensionDispatch<D>,
{
    let n = work.len();
    let mut result = NewtonResult {
        converged: false,
        iterations: 0,
        krylov_iterations: 0,
        factorisations: 0,
        residual: f64::INFINITY,
        scale: 0.0,
        worst: 0,
        last: None,
    };
    let NewtonVectors {
        du,
        residual,
        trial,
        trial_residual,
        direction,
        rhs,
        cg,
        gmres: gmres_work,
    } = vectors;
    let mut eval = evaluate(sim, work, du, dt, inertia, residual);
    if !eval.valid {
        return result;
    }
    let external = norm(&work.external);
    let force0 = inertia.map_or(0.0, |_| norm(&work.force0));
    // A floor on the force scale: the force of a strain of 1e-3 in the stiffest material on
    // one cell face, so a nearly unloaded step is judged on an absolute scale (equilibrium
    // to a strain of about 1e-9 at the default tolerance) and not on its own round-off.
    let stiffest = (0..sim.particles.groups.len())
        .map(|g| super::workspace::group_modulus(sim, g))
        .fold(0.0f64, f64::max);
    let floor = 1e-3 * stiffest * sim.grid.dx.powi(D as i32 - 1);
    let scale = external
        .max(force0)
        .max(eval.force_scale)
        .max(norm(residual))
        .max(floor);
    let mut energy0 = 0.0;
    let mut factored: Option<SparseCholesky> = None;
    // The last step's factor, where it fits: not factored afresh until it goes stale.
    // Its layout buffers are kept for the next one either way.
    let mut carried_over = false;
    let mut layout = (Vec::new(), Vec::new());
    if settings.reuse_preconditioner
        && let Some(carried) = work.carried.take()
    {
        if carried.fits(work, dt) {
            factored = Some(carried.factor);
            carried_over = true;
            sim.report
                .record_max("implicit.factored_preconditioner", 1.0);
        }
        layout = (carried.node_of_dof, carried.mask);
    }
    let mut try_factor = true;
    // Whether the factor in use was made in f32 at this iteration.
    let mut fresh_single = false;
    let mut last_krylov = 0u32;
    let mut factored_damping = 0.0f64;
    let mut damping = 0.0f64;
    let mut r_norm = norm(residual);
    for iteration in 0..settings.max_newton_iterations {
        result.iterations = iteration;
        // Judged against the loads and the start's forces, or the forces of the iterate
        // itself (not of an earlier, rejected or far-off, iterate).
        if r_norm <= settings.force_tolerance * scale.max(eval.force_scale) {
            result.converged = true;
            break;
        }
        // The factored estimate is made after the first evaluation (the moduli probe
        // differences against the iterate's stress) and made again when it has gone stale
        // (the last Krylov solve needed more than STALE iterations) or the damping changed;
        // Jacobi once it is too large.
        let stale =
            (iteration == 0 && !carried_over) || last_krylov > STALE || damping != factored_damping;
        if try_factor && stale {
            factored_damping = damping;
            let precision = match settings.factor_precision {
                FactorPrecision::Double => Precision::Double,
                FactorPrecision::Single => Precision::Single,
            };
            let fresh = super::preconditioner::factor(sim, work, inertia, dt, damping, precision);
            if work.pattern.single_failed() {
                sim.report
                    .record_max("implicit.single_precision_fell_back", 1.0);
            }
            result.factorisations += u32::from(fresh.is_some());
            fresh_single = fresh.as_ref().is_some_and(SparseCholesky::is_single);
            if fresh_single {
                sim.report
                    .record_max("implicit.single_precision_factors", 1.0);
            }
            factored = fresh.or(factored);
            if iteration == 0 && !carried_over {
                try_factor = factored.is_some();
                if try_factor {
                    sim.report
                        .record_max("implicit.factored_preconditioner", 1.0);
                }
            }
        }
        let factored = factored.as_ref();
        // Krylov: J δ = −R, J v ≈ (R(Δu + εv) − R(Δu)) / ε.
        for (b, r) in rhs.iter_mut().zip(residual.iter()) {
            *b = -r;
        }
        direction.fill(0.0);
        let inverse_diagonal = std::mem::take(&mut work.inverse_diagonal);
        super::residual::linearise_at(sim, work);
        super::out_of_plane::measure(sim, work, dt);
        let mut apply = |v: &[f64], out: &mut [f64]| {
            if v.iter().all(|x| *x == 0.0) {
                out.fill(0.0);
                return;
            }
            tangent_product(sim, work, v, dt, inertia, out);
            if damping > 0.0 {
                for ((o, x), d) in out.iter_mut().zip(v).zip(&inverse_diagonal) {
                    if *d > 0.0 {
                        *o += damping * x / d;
                    }
                }
            }
        };
        // Inexact Newton: no need to solve below a tenth of the convergence target (the
        // finite-difference product is not more accurate than that anyway).
        let tolerance = settings
            .krylov_tolerance
            .max(0.1 * settings.force_tolerance * scale / r_norm.max(1e-300))
            .min(0.5);
        let precondition = |r: &[f64], z: &mut [f64]| match factored {
            Some(chol) => {
                for ((z, r), d) in z.iter_mut().zip(r).zip(&inverse_diagonal) {
                    *z = if *d > 0.0 { *r } else { 0.0 };
                }
                chol.solve_in_place(z);
                for (z, d) in z.iter_mut().zip(&inverse_diagonal) {
                    if *d <= 0.0 {
                        *z = 0.0;
                    }
                }
            }
            None => {
                for ((z, r), d) in z.iter_mut().zip(r).zip(&inverse_diagonal) {
                    *z = r * d;
                }
            }
        };
        let solve = if use_cg {
            let [r, z, p, ap] = cg;
            conjugate_gradient::solve_preconditioned(
                &mut apply,
                precondition,
                &inverse_diagonal,
                rhs,
                direction,
                Work { r, z, p, ap },
                tolerance,
                settings.max_krylov_iterations,
            )
        } else {
            let g = gmres_work
                .as_mut()
                .expect("GMRES work space sized in prepare");
            gmres::solve_preconditioned(
                &mut apply,
                precondition,
                &inverse_diagonal,
                rhs,
                direction,
                g,
                tolerance,
                settings.max_krylov_iterations,
            )
        };
        work.inverse_diagonal = inverse_diagonal;
        result.krylov_iterations += solve.iterations;
        last_krylov = solve.iterations;
        if fresh_single && last_krylov > STALE {
            // An f32 factor that preconditions worse than a stale one would: too coarse for
            // this tangent (soft, damaged particles beside stiff ones); f64 from now on.
            work.pattern.give_up_single();
            sim.report
                .record_max("implicit.single_precision_fell_back", 1.0);
        }
        fresh_single = false;
        if direction.iter().any(|v| !v.is_finite()) {
            break;
        }
        super::residual::project(work, direction);
        let energy: f64 = direction
            .iter()
            .zip(residual.iter())
            .map(|(a, b)| a * b)
            .sum::<f64>()
            .abs();
        if iteration == 0 {
            energy0 = energy;
        }
        // Line search along the direction. A step is taken when it lowers the residual norm
        // or, for a descent direction of the energy (s₀ = δ·R < 0), when the slope
        // s(α) = δ·R(Δu + αδ) has fallen to half of |s₀| (the energy went down and is near
        // its minimum along δ). The residual norm alone is a poor judge for slender bodies: a
        // good Newton step that rotates a beam leaves a large, easily corrected out-of-balance
        // force in its stiff axial modes. Otherwise α comes from the secant of the slope (or
        // is halved).
        let s0: f64 = direction
            .iter()
            .zip(residual.iter())
            .map(|(a, b)| a * b)
            .sum();
        let mut alpha = 1.0;
        let mut accepted = false;
        for _ in 0..8 {
            for i in 0..n {
                trial[i] = du[i] + alpha * direction[i];
            }
            let e = evaluate(sim, work, trial, dt, inertia, trial_residual);
            let t_norm = norm(trial_residual);
            let slope: f64 = direction
                .iter()
                .zip(trial_residual.iter())
                .map(|(a, b)| a * b)
                .sum();
            let lower = t_norm <= (1.0 - 1e-4 * alpha) * r_norm;
            let minimum = s0 < 0.0 && slope <= 0.5 * s0.abs();
            if e.valid && t_norm.is_finite() && (lower || minimum) {
                damping = if alpha == 1.0 && (t_norm <= 0.5 * r_norm || minimum) {
                    damping.relax()
                } else {
                    damping.stiffen()
                };
                std::mem::swap(du, trial);
                std::mem::swap(residual, trial_residual);
                r_norm = t_norm;
                eval = e;
                accepted = true;
                break;
            }
            // A valid trial that was not taken has s(α) > |s₀|/2 > 0: the energy's minimum
            // lies before α, where the secant of the slope from 0 puts it.
            alpha = if e.valid && s0 < 0.0 && slope.is_finite() {
                (alpha * s0 / (s0 - slope)).clamp(0.1 * alpha, 0.9 * alpha)
            } else {
                0.5 * alpha
            };
        }
        if !accepted && damping < DAMPING_MAX {
            // A more strongly damped direction before giving up.
            damping = damping.stiffen();
            eval = evaluate(sim, work, du, dt, inertia, residual);
            continue;
        }
        if !accepted {
            // The particles hold a rejected trial: put back the last accepted state.
            eval = evaluate(sim, work, du, dt, inertia, residual);
            break;
        }
        if iteration > 0 && energy <= settings.energy_tolerance * energy0 {
            result.iterations = iteration + 1;
            result.converged = true;
            break;
        }
        result.iterations = iteration + 1;
    }
    if !result.converged && r_norm <= settings.force_tolerance * scale.max(eval.force_scale) {
        result.converged = true;
    }
    result.residual = r_norm;
    result.scale = scale;
    result.worst = residual
        .iter()
        .enumerate()
        .fold(
            (0, 0.0f64),
            |(w, m), (i, v)| {
                if v.abs() > m { (i, v.abs()) } else { (w, m) }
            },
        )
        .0;
    result.last = Some(eval);
    if settings.reuse_preconditioner
        && let Some(factor) = factored
    {
        let (mut node_of_dof, mut mask) = layout;
        node_of_dof.clone_from(&work.node_of_dof);
        mask.clone_from(&work.mask);
        work.carried = Some(CarriedFactor {
            factor,
            node_of_dof,
            mask,
            dt,
        });
    }
    result
}
