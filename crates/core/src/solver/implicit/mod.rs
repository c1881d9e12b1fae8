//! Implicit mechanics (`solver.mechanics.implicit`): every step solves equilibrium
//! (`static`) or Newmark dynamics (`dynamic`) on the grid by Newton iterations on the nodal
//! displacement increment, so the step is bounded by neither the wave speed nor the
//! stiffness. The physics operators (heat, phase change, cure) advance first, as in the
//! quasi-static mode; the mechanics follows within the same step.
//!
//! - `workspace`: active nodes and their unknowns, constraints, the start-of-step snapshot;
//! - `residual`: the out-of-balance force of a trial increment (each material's own stress
//!   update, so third-party plugins work unchanged);
//! - `newton`: Newton–Krylov iterations with a line search;
//! - `out_of_plane`: generalized plane strain's rank-one term of the tangent;
//! - `finish`: the particle update once a step has converged.
//!
//! A step that does not converge is halved and retried (free strains and the gravity ramp
//! follow the cut); after `max_cuts` halvings the run stops with a diagnostic naming the
//! step, the Newton iteration, the residual and the worst node.

mod fbar;
mod finish;
mod newton;
mod out_of_plane;
mod preconditioner;
mod residual;
mod tangent_estimate;
mod workspace;

use super::DimensionDispatch;
use super::mode::StepMode;
use super::particle_to_grid::ForceTerm;
use super::simulation::Simulation;
use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::physics::{FREE_STRAIN, PhysicsFault};
use crate::scene::{ImplicitForm, ImplicitSettings, KrylovMethod, TangentMethod};
use newton::{NewtonResult, NewtonVectors};
use residual::{Inertia, internal_force_now};
use workspace::Workspace;

/// Krylov vectors between GMRES restarts.
const GMRES_RESTART: usize = 40;

/// The implicit mode with its reusable work space.
pub(super) struct Implicit<const D: usize> {
    settings: ImplicitSettings,
    /// F-bar anti-locking over stencil patches (`solver.anti_locking: "fbar"`).
    fbar: bool,
    work: Workspace<D>,
    vectors: NewtonVectors,
    totals: Totals,
}

/// Iteration counts over the run, for the metrics.
#[derive(Default)]
struct Totals {
    steps: u64,
    newton: u64,
    krylov: u64,
    factorisations: u64,
    cuts: u64,
    max_newton: u32,
}

impl<const D: usize> Implicit<D> {
    pub(super) fn new(settings: ImplicitSettings, fbar: bool) -> Self {
        Self {
            settings,
            fbar,
            work: Workspace::default(),
            vectors: NewtonVectors::default(),
            totals: Totals::default(),
        }
    }
}

/// Why an attempt at a (sub)step failed.
struct Failure {
    newton: NewtonResult,
    node: Option<usize>,
    unsupported: bool,
}

impl<const D: usize, K: Kernel> StepMode<D, K> for Implicit<D>
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        sim.reorder_if_due();
        let free_strain = sim.particles.shared.contains(FREE_STRAIN);
        if free_strain {
            let fs = sim.particles.shared.get(FREE_STRAIN).unwrap_or(&[]);
            self.work.free_strain_old.clear();
            self.work.free_strain_old.extend_from_slice(fs);
        }
        sim.advance_physics(dt, true);
        if free_strain {
            let fs = sim.particles.shared.get(FREE_STRAIN).unwrap_or(&[]);
            self.work.free_strain_new.clear();
            self.work.free_strain_new.extend_from_slice(fs);
        }
        let balance_before = sim.total_energy() - sim.ledger.net_input();
        let start = sim.time;
        let mut done = 0.0;
        let mut h = dt;
        let mut cuts = 0u32;
        while done < dt * (1.0 - 1e-12) {
            h = h.min(dt - done);
            if free_strain {
                self.ramp_free_strain(sim, (done + h) / dt);
            }
            match self.attempt(sim, start + done, h) {
                Ok(()) => done += h,
                Err(failure) => {
                    self.work.restore(sim);
                    cuts += 1;
                    self.totals.cuts += 1;
                    if failure.unsupported || cuts > self.settings.max_cuts {
                        self.report_failure(sim, &failure, cuts, start + done, h);
                        break;
                    }
                    h *= 0.5;
                }
            }
        }
        if free_strain {
            self.ramp_free_strain(sim, 1.0);
        }
        if self.settings.form == ImplicitForm::Static {
            // A static step ends at rest: the energy the load step released (what dynamics
            // would have carried as motion) is taken out, as the damping of a relaxation is.
            sim.ledger.damping += balance_before - (sim.total_energy() - sim.ledger.net_input());
        }
        let t = &self.totals;
        sim.report
            .record_max("implicit.newton_iterations", t.newton as f64);
        sim.report
            .record_max("implicit.krylov_iterations", t.krylov as f64);
        sim.report
            .record_max("implicit.factorisations", t.factorisations as f64);
        sim.report.record_max("implicit.cuts", t.cuts as f64);
        sim.report.record_max("implicit.steps", t.steps as f64);
        sim.report
            .record_max("implicit.max_newton_per_step", t.max_newton as f64);
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        sim.physics_dt
    }

    fn save(&mut self, c: &mut Checkpoint) {
        let t = &self.totals;
        let numbers = [
            t.steps,
            t.newton,
            t.krylov,
            t.factorisations,
            t.cuts,
            t.max_newton as u64,
        ];
        c.put(
            "implicit.totals",
            numbers.iter().map(|&v| v as f64).collect(),
        );
    }

    fn restore(&mut self, c: &Checkpoint) -> Result<(), CheckpointError> {
        let t = c.get("implicit.totals", 6)?;
        self.totals = Totals {
            steps: t[0] as u64,
            newton: t[1] as u64,
            krylov: t[2] as u64,
            factorisations: t[3] as u64,
            cuts: t[4] as u64,
            max_newton: t[5] as u32,
        };
        Ok(())
    }
}

impl<const D: usize> Implicit<D> {
    /// Sets the free strain to the fraction `s` of the way from its value before the
    /// physics advanced to its value after.
    fn ramp_free_strain<K: Kernel>(&self, sim: &mut Simulation<D, K>, s: f64)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let (old, new) = (&self.work.free_strain_old, &self.work.free_strain_new);
        if let Some(fs) = sim.particles.shared.get_mut(FREE_STRAIN)
            && fs.len() == old.len()
            && fs.len() == new.len()
        {
            for ((f, a), b) in fs.iter_mut().zip(old).zip(new) {
                *f = a + s * (b - a);
            }
        }
    }

    /// One attempt at a step of `dt` from `time`: set-up, Newton, and on success the
    /// particle update.
    fn attempt<K: Kernel>(
        &mut self,
        sim: &mut Simulation<D, K>,
        time: f64,
        dt: f64,
    ) -> Result<(), Box<Failure>>
    where
        dyn Material: DimensionDispatch<D>,
    {
        let s = self.settings;
        let dynamic = s.form == ImplicitForm::Dynamic;
        let end = time + dt;
        // Nodal mass and start velocity through the explicit path's own P2G and grid update
        // (ghost folding, walls on the velocity, mirroring).
        sim.bins.rebuild::<D, K>(&sim.grid, &sim.particles);
        sim.grid.clear();
        sim.p2g(dt, true, ForceTerm::None);
        sim.grid_update_work(dt, false);
        let work = &mut self.work;
        work.prepare(sim, dynamic);
        work.analytic = s.tangent == TangentMethod::Auto
            && super::stress_derivative::all_analytic(&sim.particles);
        let ramp = s.gravity_ramp.map_or(1.0, |r| (end / r).min(1.0));
        work.gravity(sim, ramp);
        let held = work.constrain(sim, end, dt);
        work.snapshot(sim);
        if self.fbar {
            let mut average = work.fbar.take().unwrap_or_default();
            average.prepare(
                &work.interp,
                &work.entry_dof,
                &work.volume_n,
                work.node_of_dof.len(),
                sim.particles.groups.iter().map(|g| g.range.clone()),
            );
            work.fbar = Some(average);
        }
        let n = work.len();
        // Auto is GMRES: away from equilibrium the tangent need not be positive definite
        // (a prestressed body's geometric stiffness), nor symmetric (plasticity, the
        // finite-difference product), and with the factored preconditioner GMRES needs few
        // iterations. CG on request, for tangents known to be symmetric positive definite.
        let use_cg = s.krylov == KrylovMethod::Cg;
        self.vectors.resize(n, (!use_cg).then_some(GMRES_RESTART));
        let inertia = dynamic.then(|| Inertia {
            c_u: 1.0 / (s.beta * dt * dt),
            c_a: 1.0 / (2.0 * s.beta) - 1.0,
            dt,
        });
        if dynamic {
            // M aₙ: the out-of-balance force at the start of the step (gravity at its start).
            let start_ramp = s.gravity_ramp.map_or(1.0, |r| (time / r).min(1.0));
            let mut f_int = std::mem::take(&mut self.vectors.trial);
            internal_force_now(sim, work, &mut f_int);
            let scale = start_ramp / ramp;
            for (f0, g) in work.force0.iter_mut().zip(&work.external) {
                *f0 = g * scale;
            }
            residual::fold::<D>(&work.mirrors, &mut work.force0);
            for (f0, f) in work.force0.iter_mut().zip(&f_int) {
                *f0 -= f;
            }
            self.vectors.trial = f_int;
        }
        self.preconditioner(sim, inertia);
        // Start: prescribed increments, and the velocity predictor for dynamics.
        let work = &self.work;
        let du = &mut self.vectors.du;
        for (i, du) in du.iter_mut().enumerate() {
            *du = if work.mask[i] == 0.0 {
                work.prescribed[i]
            } else if dynamic {
                dt * work.velocity[i]
            } else {
                0.0
            };
        }
        for c in &work.normals {
            let k = c.dof as usize * D;
            let dot: f64 = (0..D).map(|d| du[k + d] * c.normal[d]).sum();
            for d in 0..D {
                du[k + d] += (c.value - dot) * c.normal[d];
            }
        }
        if !dynamic && !held && n > 0 {
            return Err(Box::new(Failure {
                newton: NewtonResult {
                    converged: false,
                    iterations: 0,
                    krylov_iterations: 0,
                    factorisations: 0,
                    residual: f64::NAN,
                    scale: 0.0,
                    worst: 0,
                    last: None,
                },
                node: None,
                unsupported: true,
            }));
        }
        let result = newton::solve(
            sim,
            &mut self.work,
            &mut self.vectors,
            &s,
            use_cg,
            dt,
            inertia,
        );
        self.totals.newton += result.iterations as u64;
        self.totals.krylov += result.krylov_iterations as u64;
        self.totals.factorisations += result.factorisations as u64;
        self.totals.max_newton = self.totals.max_newton.max(result.iterations);
        if !result.converged {
            let node = self
                .work
                .node_of_dof
                .get(result.worst / D)
                .map(|&n| n as usize);
            return Err(Box::new(Failure {
                newton: result,
                node,
                unsupported: false,
            }));
        }
        self.totals.steps += 1;
        finish::update_particles(
            sim,
            &mut self.work,
            &self.vectors.du,
            &s,
            dt,
            inertia,
            result,
        );
        Ok(())
    }
}

impl<const D: usize> Implicit<D> {
    /// The Jacobi preconditioner: an estimate of the tangent's diagonal, Σ_p Vₙ ρc² |∇w|²
    /// with each material group's wave speed, plus the Newmark mass term in dynamics.
    fn preconditioner<K: Kernel>(&mut self, sim: &Simulation<D, K>, inertia: Option<Inertia>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let work = &mut self.work;
        let diag = &mut work.inverse_diagonal;
        diag.fill(0.0);
        for (g, group) in sim.particles.groups.iter().enumerate() {
            let modulus = workspace::group_modulus(sim, g);
            for p in group.range.clone() {
                let v = work.volume_n[p] * modulus;
                for e in work.interp.entries(p) {
                    let k = work.entry_dof[e] as usize * D;
                    let add = v * work.interp.gradient[e].norm_squared();
                    for d in 0..D {
                        diag[k + d] += add;
                    }
                }
            }
        }
        for m in work.mirrors.iter().rev() {
            let (gh, f) = (m.ghost as usize * D, m.front as usize * D);
            for d in 0..D {
                diag[f + d] += diag[gh + d];
                diag[gh + d] = 0.0;
            }
        }
        if let Some(c) = inertia {
            for (k, &m) in work.mass.iter().enumerate() {
                for d in 0..D {
                    diag[k * D + d] += c.c_u * m;
                }
            }
        }
        for (v, m) in diag.iter_mut().zip(&work.mask) {
            *v = if *v > 0.0 && *m > 0.0 { 1.0 / *v } else { 0.0 };
        }
        // Keep general normal constraints out of the scaling's way: isotropic per node.
        for c in &work.normals {
            let k = c.dof as usize * D;
            let mean = (0..D).map(|d| diag[k + d]).sum::<f64>() / D as f64;
            diag[k..k + D].fill(mean);
        }
    }

    /// Stops the run with a diagnostic after a step failed past its cuts.
    fn report_failure<K: Kernel>(
        &self,
        sim: &mut Simulation<D, K>,
        failure: &Failure,
        cuts: u32,
        time: f64,
        dt: f64,
    ) where
        dyn Material: DimensionDispatch<D>,
    {
        let message = if failure.unsupported {
            "implicit static step: nothing holds the body (no wall or obstacle constrains any \
             node it touches), so equilibrium has no unique solution; add a stick, slip or \
             symmetry wall, an obstacle, or use the dynamic form"
                .to_string()
        } else {
            let r = &failure.newton;
            let at = failure.node.map_or(String::new(), |node| {
                let x = sim.grid.position(sim.grid.coords(node));
                format!(
                    "; the largest out-of-balance force is at the node at ({})",
                    x.iter()
                        .map(|v| format!("{v:.6e}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            });
            format!(
                "implicit step did not converge after {} cuts (last try: t = {time:e} s, dt = {dt:e} s): \
                 Newton iteration {}, residual {:.3e} N against the tolerance {:.3e} N \
                 ({} Krylov iterations){at}; take smaller steps (solver.dt), raise \
                 solver.mechanics.implicit.max_newton_iterations or max_cuts",
                cuts - 1,
                r.iterations,
                r.residual,
                self.settings.force_tolerance * r.scale,
                r.krylov_iterations,
            )
        };
        sim.report.fail(PhysicsFault {
            field: "implicit".into(),
            particle: None,
            value: failure.newton.residual,
            message,
        });
    }
}
