//! Implicit viscosity of the incompressible mode (`solver.mechanics.incompressible.viscosity:
//! "implicit"`): a backward-Euler viscous step on the grid between the explicit forces and
//! the pressure projection, so that the step is not bounded by ρ·dx²/(2·D·μ).
//!
//! P2G then scatters mass, momentum and gravity but not the particles' viscous stress, and
//! the grid velocity after the explicit forces, v̂, goes through
//!
//! (M_i/dt) v_i + Σ_p V_p σ_p(v)·∇w_ip = (M_i/dt) v̂_i,   σ_p(v) = 2 μ_p dev(sym ∇v_p),
//! ∇v_p = Σ_i v_i ⊗ ∇w_ip,
//!
//! matrix-free through the particles with their stencils at the start of the step (the
//! positions P2G used). The stress is the deviatoric one the `liquid` material computes:
//! the intermediate velocity is not divergence-free (the projection comes after), and the
//! deviatoric form neither resists the compression the projection removes nor changes the
//! meaning of the particles' stress output (the new velocity gradient's 2μ·dev(sym L)).
//! The operator is symmetric positive definite: x·Ay = Σ_i (M_i/dt) x_i·y_i +
//! Σ_p 2 μ_p V_p dev(sym ∇x_p) : dev(sym ∇y_p).
//!
//! Walls and obstacles hold inside the solve, as implicit mechanics holds its Dirichlet
//! nodes: v = v₀ + δ, where v₀ is v̂ (before the walls act) with the tangential velocity of
//! every stick wall or obstacle set on its nodes, and the correction δ lies in the free
//! subspace (P δ = δ; P zeroes the constrained components: all of a stick node's, the
//! normal one of a slip, symmetry or friction node, a general normal projected out). CG
//! solves P A P δ = -P K v₀ (K: the viscous part of A) with the Jacobi preconditioner
//! P D⁻¹ P. The normal components on walls keep v̂'s value, not the wall's: the pressure
//! projection takes the velocity before the walls (so a liquid at rest on a floor stays
//! exactly at rest) and the walls act after it, so the viscous step must not see the jump
//! between the wall's zero and the gravity the projection has yet to balance. Ghost nodes
//! behind stick and symmetry walls are no unknowns: the operator gives them the image of
//! their mirror node before it computes ∇v_p and folds what lands on them back (the
//! transpose), so particles beside a wall see the odd tangential velocity the explicit
//! mode's mirrored ghosts give them; behind a Navier wall the tangential components take
//! (b − d)/(b + d) of the front's (`boundary::Image`). Friction acts as slip inside the solve; the Coulomb
//! rule acts on the result when the walls act after the projection. The unknowns are all
//! nodes with (folded) P2G mass, including those beyond the liquid cells that B-splines
//! reach, which is natural for an operator built from the particles.
//!
//! For a law whose viscosity depends on the state (Cross, Castro–Macosko), μ_p is the
//! viscosity at the particle's state at the start of the step (the last step's velocity
//! gradient, temperature and cure), lagged one step: a Picard iteration over steps.
//!
//! The projection is incremental (Goda 1979) with implicit viscosity: the viscous solve
//! sees v̂ plus the last pressure's force -dt (1/M_i) Σ_c ∫_c N_i ∇p^n, taken on this
//! step's liquid cells, and the Poisson equation solves for the increment from the share
//! of p^n whose force stays in the velocity after the solve (all of it for a liquid the
//! viscous step damps, little for water; `Incompressible::add_kept_pressure_force`).
//! Without it the split scheme's steady state carries an error dt·ν·Δ∇p, which is no
//! longer small once ν·dt/dx² ≫ 1 (a Poiseuille channel with open ends at μ = 100 Pa·s
//! erred 13.6% at 15 steps, 5.3% with the increment).
//!
//! The projection then takes v₀ + δ on the free components and v̂ on the fixed ones (the
//! velocity before the walls plus the viscous change δ, zero where fixed), as with
//! explicit viscosity it takes v̂ plus the explicit viscous change; the walls act after.

use super::super::DimensionDispatch;
use super::super::interpolation::build_interpolation;
use super::super::simulation::Simulation;
use super::navier_slip::NavierDrag;
use crate::kernels::Kernel;
use crate::linear_solvers::conjugate_gradient::{Solve, Work, solve_preconditioned};
use crate::material::{MAX_SHARED_READS, Material, ViscosityBatch};
use crate::math::{Matrix, Vector, trace};
use crate::particles::MaterialGroup;
use crate::physics::{Interpolation, PhysicsFault};
use crate::scene::{Contact, IncompressibleSettings};
use rayon::prelude::*;

/// A ghost node behind a stick, symmetry or Navier wall and the node it mirrors.
#[derive(Clone, Copy, Debug)]
struct Mirror {
    ghost: u32,
    front: u32,
    axis: u8,
    /// The factor of the front's normal component the ghost takes.
    normal: f64,
    /// The factor of the front's tangential components the ghost takes.
    tangential: f64,
}

impl Mirror {
    /// A ghost behind a stick wall (`symmetry` false) or a symmetry wall: behind a stick
    /// wall the tangential components are odd (no slip) and the normal one even (the
    /// velocity before the projection still carries the normal motion the walls will stop,
    /// and at a no-slip wall ∂v_n/∂n = −∇_t·v_t = 0); behind a symmetry wall the normal
    /// component is odd and the tangential ones even.
    fn of_wall(ghost: u32, front: u32, axis: u8, symmetry: bool) -> Self {
        let (normal, tangential) = if symmetry { (-1.0, 1.0) } else { (1.0, -1.0) };
        Self {
            ghost,
            front,
            axis,
            normal,
            tangential,
        }
    }

    /// The factor component `d` of the front's velocity takes on the ghost.
    #[inline]
    fn sign(&self, d: usize) -> f64 {
        if d == self.axis as usize {
            self.normal
        } else {
            self.tangential
        }
    }
}

/// The viscous operator's data: stencils, per-particle coefficients, nodal mass, the
/// mirrors and the constraints.
#[derive(Default)]
struct Operator<const D: usize> {
    /// Stencils of the particles at the start of the step.
    interp: Interpolation<D>,
    /// Per particle: 2 μ_p V_p.
    coefficient: Vec<f64>,
    /// Per node: M_i / dt (folded P2G mass; 0 on ghosts and empty nodes).
    mass_rate: Vec<f64>,
    /// Ghost nodes in mirroring order.
    mirrors: Vec<Mirror>,
    /// Per component: 1 where free, 0 where a wall or obstacle fixes it or the node has no
    /// mass.
    mask: Vec<f64>,
    /// Components along general (not axis-aligned) normals a node may not change.
    normals: Vec<(u32, Vector<D>)>,
    /// The nodes Navier-slip surfaces drag, each once with its C_i (navier_slip.rs; empty
    /// without them).
    drag: Vec<(u32, f64)>,
}

impl<const D: usize> Operator<D> {
    /// Zeroes the constrained components of `r` (the projection P).
    fn project(&self, r: &mut [f64]) {
        for (v, m) in r.iter_mut().zip(&self.mask) {
            *v *= m;
        }
        for (node, n) in &self.normals {
            let k = *node as usize * D;
            let dot: f64 = (0..D).map(|d| r[k + d] * n[d]).sum();
            for d in 0..D {
                r[k + d] -= dot * n[d];
            }
        }
    }

    /// Gives the ghosts the image of their mirror nodes.
    fn mirror(&self, x: &mut [f64]) {
        for m in &self.mirrors {
            let (g, f) = (m.ghost as usize * D, m.front as usize * D);
            for d in 0..D {
                x[g + d] = m.sign(d) * x[f + d];
            }
        }
    }

    /// Folds what landed on the ghosts onto their mirror nodes (the transpose of
    /// [`Self::mirror`]) and zeroes the ghosts.
    fn fold(&self, y: &mut [f64]) {
        for m in self.mirrors.iter().rev() {
            let (g, f) = (m.ghost as usize * D, m.front as usize * D);
            for d in 0..D {
                y[f + d] += m.sign(d) * y[g + d];
                y[g + d] = 0.0;
            }
        }
    }

    /// y = P A P x, with the scratch arrays of `scratch`.
    fn apply(&self, x: &[f64], y: &mut [f64], scratch: &mut Scratch<D>) {
        self.product(x, y, scratch, true);
    }

    /// y = P A P x (`operand_projected`), or y = P K x, the viscous part alone on the
    /// unprojected x (the right-hand side's -P K v₀, where the constrained components of
    /// v₀ carry the walls' and obstacles' velocities).
    fn product(&self, x: &[f64], y: &mut [f64], scratch: &mut Scratch<D>, operand_projected: bool) {
        let Scratch { full, stress } = scratch;
        full.copy_from_slice(x);
        if operand_projected {
            self.project(full);
        }
        self.mirror(full);
        // Each particle's 2μ_p V_p dev(sym ∇x_p).
        let interp = &self.interp;
        let coefficient = &self.coefficient;
        let full_ref: &[f64] = full;
        stress.par_iter_mut().enumerate().for_each(|(p, s)| {
            let c = coefficient[p];
            *s = Matrix::<D>::zeros();
            if c == 0.0 {
                return;
            }
            let mut grad = Matrix::<D>::zeros();
            for e in interp.entries(p) {
                let k = interp.node[e] as usize * D;
                let dw = interp.gradient[e];
                for a in 0..D {
                    for b in 0..D {
                        grad[(a, b)] += full_ref[k + a] * dw[b];
                    }
                }
            }
            let rate = (grad + grad.transpose()) * 0.5;
            *s = (rate - Matrix::<D>::identity() * (trace(&rate) / D as f64)) * c;
        });
        // Σ_p σ_p V_p ∇w_ip, folded off the ghosts.
        y.fill(0.0);
        for (p, s) in stress.iter().enumerate() {
            if coefficient[p] == 0.0 {
                continue;
            }
            for e in interp.entries(p) {
                let k = interp.node[e] as usize * D;
                let f = s * interp.gradient[e];
                for d in 0..D {
                    y[k + d] += f[d];
                }
            }
        }
        self.fold(y);
        if operand_projected {
            // (M/dt) P x; ghosts and empty nodes have no mass.
            full.copy_from_slice(x);
            self.project(full);
            for (i, m) in self.mass_rate.iter().enumerate() {
                for d in 0..D {
                    y[i * D + d] += m * full[i * D + d];
                }
            }
        }
        // The Navier surfaces' drag, C_i on the (projected) operand: its tangential part.
        let operand: &[f64] = if operand_projected { full } else { x };
        for &(i, c) in &self.drag {
            let k = i as usize * D;
            for d in 0..D {
                y[k + d] += c * operand[k + d];
            }
        }
        self.project(y);
    }

    /// The Jacobi diagonal of A on the free components (0 on the fixed ones), without the
    /// ghosts' coupling: (M_i/dt) + Σ_p 2μ_p V_p ((|∇w|² + ∂_d w²)/2 − ∂_d w²/D).
    fn inverse_diagonal(&self, out: &mut [f64]) {
        out.fill(0.0);
        let interp = &self.interp;
        for (p, &c) in self.coefficient.iter().enumerate() {
            if c == 0.0 {
                continue;
            }
            for e in interp.entries(p) {
                let k = interp.node[e] as usize * D;
                let g = interp.gradient[e];
                let g2 = g.norm_squared();
                for d in 0..D {
                    let gd2 = g[d] * g[d];
                    out[k + d] += c * (0.5 * (g2 + gd2) - gd2 / D as f64);
                }
            }
        }
        for &(i, c) in &self.drag {
            let k = i as usize * D;
            for d in 0..D {
                out[k + d] += c;
            }
        }
        for (i, m) in self.mass_rate.iter().enumerate() {
            for d in 0..D {
                let k = i * D + d;
                let diagonal = out[k] + m;
                out[k] = if self.mask[k] > 0.0 && diagonal > 0.0 {
                    1.0 / diagonal
                } else {
                    0.0
                };
            }
        }
    }
}

/// Scratch of one operator product.
#[derive(Default)]
struct Scratch<const D: usize> {
    /// The operand, projected, with the ghosts mirrored.
    full: Vec<f64>,
    /// Each particle's 2μ_p V_p dev(sym ∇x_p).
    stress: Vec<Matrix<D>>,
}

/// The implicit viscous step and its workspace (sized on the first step, reused).
#[derive(Default)]
pub(super) struct ImplicitViscosity<const D: usize> {
    operator: Operator<D>,
    scratch: Scratch<D>,
    /// Whether the mirrors are built (the walls do not move).
    mirrored: bool,
    /// The last step's pressure, p^n (the projection solves for the increment).
    base: Vec<f64>,
    /// When this step was cut short to land on an output time and is shorter than the
    /// last, it over the shorter of the two: the share of the pressure increment kept (see
    /// `total_pressure`).
    cut_share: Option<f64>,
    /// The last step, s (0 before the first and after a checkpoint).
    last_dt: f64,
    /// Per node: the velocity the kept pressure (and the capillary stage's) added before
    /// the viscous solve, taken back after it (see `take_back`).
    pre_applied: Vec<Vector<D>>,
    /// The share of `pre_applied` taken back after the viscous solve (see
    /// `Incompressible::add_kept_pressure_force`).
    take_back_share: f64,
    /// The start of the solve, v₀ (one number per node component).
    start: Vec<f64>,
    /// The correction δ.
    delta: Vec<f64>,
    rhs: Vec<f64>,
    inverse_diagonal: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
    /// Per particle group: the least viscosity μ_p of its particles at the last solve (or
    /// at the start), Pa·s, which bounds the viscous–capillary step (surface_tension.rs).
    least_viscosity: Vec<f64>,
}

impl<const D: usize> ImplicitViscosity<D> {
    /// Sizes the node arrays for the grid and builds the mirrors (once).
    fn prepare<K: Kernel>(&mut self, sim: &Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let grid = &sim.grid;
        let n = grid.len() * D;
        if self.start.len() != n {
            for v in [
                &mut self.start,
                &mut self.delta,
                &mut self.rhs,
                &mut self.inverse_diagonal,
                &mut self.r,
                &mut self.z,
                &mut self.p,
                &mut self.ap,
                &mut self.scratch.full,
                &mut self.operator.mask,
            ] {
                *v = vec![0.0; n];
            }
            self.operator.mass_rate = vec![0.0; grid.len()];
            self.mirrored = false;
        }
        if !self.mirrored {
            let mirrors = &mut self.operator.mirrors;
            mirrors.clear();
            sim.boundaries
                .for_each_mirror_node(grid.nodes, |ghost, front, axis, symmetry| {
                    mirrors.push(Mirror::of_wall(
                        grid.index(ghost) as u32,
                        grid.index(front) as u32,
                        axis as u8,
                        symmetry,
                    ));
                });
            // Behind a Navier wall the tangential components take the line through the
            // front's that meets v = b·∂v/∂n on the wall; the normal one is even, as behind
            // a stick wall.
            sim.boundaries.for_each_navier_mirror_node(
                grid.nodes,
                grid.dx,
                |ghost, front, axis, tangential| {
                    mirrors.push(Mirror {
                        ghost: grid.index(ghost) as u32,
                        front: grid.index(front) as u32,
                        axis: axis as u8,
                        normal: 1.0,
                        tangential,
                    });
                },
            );
            self.mirrored = true;
        }
    }

    /// The share of a velocity that changes sign from node to node (the stiffest mode)
    /// that the backward-Euler viscous step of length `dt` leaves, 1/(1 + 4·D·ν·dt/dx²),
    /// with ν the least kinematic viscosity of the moving liquids at the last solve: the
    /// share of the kept pressure's force taken back after the solve (see
    /// `Incompressible::add_kept_pressure_force`). 1 without a liquid.
    pub(super) fn undamped_share(&self, groups: &[MaterialGroup], dx: f64, dt: f64) -> f64 {
        let nu = groups
            .iter()
            .enumerate()
            .filter(|(_, g)| !g.held && g.material.liquid_viscosity().is_some())
            .map(|(k, g)| self.least_viscosity(k) / g.material.density())
            .fold(f64::INFINITY, f64::min);
        if nu.is_finite() {
            1.0 / (1.0 + 4.0 * D as f64 * nu * dt / (dx * dx))
        } else {
            1.0
        }
    }

    /// The incremental pressure correction's first half, after the kept pressure's force
    /// joined the velocity (`Incompressible::add_kept_pressure_force`): keeps p^n and the
    /// share of its force `take_back` takes back, and starts the projection's solve from
    /// that share of p^n. `chosen_dt` is the step the controller chose, longer than `dt`
    /// when this step was cut short to land on an output time (see
    /// [`ImplicitViscosity::total_pressure`]).
    pub(super) fn keep_base(
        &mut self,
        pressure: &mut [f64],
        dt: f64,
        chosen_dt: f64,
        take_back: f64,
    ) {
        if self.base.len() != pressure.len() {
            self.base = vec![0.0; pressure.len()];
        }
        self.base.copy_from_slice(pressure);
        self.take_back_share = take_back;
        pressure.iter_mut().for_each(|p| *p *= take_back);
        // A sliver: cut short of both the chosen step and the last one (a run whose every
        // step lands on a frame cuts them all, and none is a sliver).
        let reference = chosen_dt.min(self.last_dt);
        self.cut_share = (self.last_dt > 0.0 && reference > dt).then(|| dt / reference);
        self.last_dt = dt;
    }

    /// The total pressure on the nodes the projection solved for (`free` > 0) and those
    /// `kept` (an enclosed-air pocket's, a pressure inlet's, and with surface tension the
    /// free surface's, where it is σ·κ); 0 on the rest of the free surface. The projection
    /// solved for the increment Δp from the share of p^n whose force stayed in the velocity,
    /// (1 − s)·p^n with s the share taken back: the total is p^n + (Δp − s·p^n), its change
    /// from p^n in brackets.
    ///
    /// In a step cut short to land on an output time, and shorter than the step before
    /// it, the change counts scaled by that step over the shorter of the chosen and the
    /// last one. Its part that took away divergence the particles left (cells turning liquid, an
    /// inlet's rows) grows as 1/dt, and the next, whole step applies the total again: the
    /// inflow tank kept 2.5 kPa from a step cut to a tenth, and the step after it,
    /// applying that for ten times as long, inverted a particle. The next projection
    /// solves for what the scaled change lacks.
    pub(super) fn total_pressure(
        &self,
        pressure: &mut [f64],
        free: &[f64],
        kept: impl Fn(usize) -> bool,
    ) {
        let share = self.cut_share.unwrap_or(1.0);
        for (i, ((p, b), f)) in pressure.iter_mut().zip(&self.base).zip(free).enumerate() {
            *p = if *f > 0.0 || kept(i) {
                b + (*p - self.take_back_share * b) * share
            } else {
                0.0
            };
        }
    }

    /// Adds `increment` to the kept pressure p^n (the capillary stage's, solved before the
    /// viscous step: the projection then solves for what is left).
    pub(super) fn add_to_kept_pressure(&mut self, increment: &[f64]) {
        for (b, d) in self.base.iter_mut().zip(increment) {
            *b += d;
        }
    }

    /// Adds a velocity change (`change` where `layer` marks it set) to the velocity before
    /// the viscous solve and to what `take_back` takes back; `fresh` starts anew.
    pub(super) fn pre_apply(
        &mut self,
        velocity: &mut [Vector<D>],
        change: &[Vector<D>],
        layer: &[u8],
        fresh: bool,
    ) {
        if fresh || self.pre_applied.len() != velocity.len() {
            self.pre_applied.clear();
            self.pre_applied
                .resize(velocity.len(), Vector::<D>::zeros());
        }
        for (((v, pre), c), l) in velocity
            .iter_mut()
            .zip(&mut self.pre_applied)
            .zip(change)
            .zip(layer)
        {
            if *l != u8::MAX {
                *pre += c;
                *v += c;
            }
        }
    }

    /// Takes the share `take_back_share` of the kept pressure's velocity (and the capillary
    /// stage's) back out of `velocity` after the viscous solve; the projection solves for
    /// the increment from the rest (`kept_in_velocity`).
    pub(super) fn take_back(&self, velocity: &mut [Vector<D>]) {
        for (v, pre) in velocity.iter_mut().zip(&self.pre_applied) {
            *v -= pre * self.take_back_share;
        }
    }

    /// The part of the last total pressure at node `i` whose force stays in the velocity
    /// after the viscous solve: the projection solves for the increment from it.
    pub(super) fn kept_in_velocity(&self, i: usize) -> f64 {
        (1.0 - self.take_back_share) * self.last_pressure(i)
    }

    /// The last total pressure at node `i` (0 before the first step).
    pub(super) fn last_pressure(&self, i: usize) -> f64 {
        self.base.get(i).copied().unwrap_or(0.0)
    }

    /// Forgets the last pressure (a checkpoint: the resumed run does not have it).
    pub(super) fn forget_pressure(&mut self) {
        self.base.fill(0.0);
        self.cut_share = None;
        self.last_dt = 0.0;
    }

    /// The particles' coefficients 2 μ_p V_p, μ_p from each liquid at its particles' state
    /// at the start of the step, and each group's least μ_p. Returns the first particle
    /// whose viscosity is not a finite number ≥ 0, with it.
    fn coefficients<K: Kernel>(&mut self, sim: &Simulation<D, K>) -> Option<(usize, f64)>
    where
        dyn Material: DimensionDispatch<D>,
    {
        let particles = &sim.particles;
        let n = particles.len();
        let coefficient = &mut self.operator.coefficient;
        self.scratch.stress.resize(n, Matrix::<D>::zeros());
        particle_viscosities(particles, coefficient, &mut self.least_viscosity);
        let mut bad = None;
        for (p, c) in coefficient.iter_mut().enumerate() {
            if !(c.is_finite() && *c >= 0.0) {
                bad = bad.or(Some((p, *c)));
                *c = 0.0;
                continue;
            }
            let volume =
                particles.volume0[p] * crate::math::determinant(&particles.deformation_gradient[p]);
            *c *= 2.0 * volume;
        }
        bad
    }

    /// The least viscosity of particle group `group` at the last solve, Pa·s (0 before
    /// the first one, or for a group that has none).
    pub(super) fn least_viscosity(&self, group: usize) -> f64 {
        self.least_viscosity.get(group).copied().unwrap_or(0.0)
    }

    /// Evaluates the particles' viscosities at the current state (before the first step,
    /// so that the first step's bound, and a fixed step's check, see them).
    pub(super) fn measure_viscosities<K: Kernel>(&mut self, sim: &Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        self.coefficients(sim);
    }

    /// The constraints of the walls and obstacles on the nodes with mass at `time`, the
    /// mass term M_i/dt, and the start v₀: the velocity before the walls, `velocity`, with
    /// the tangential components a stick wall or obstacle fixes set to its own.
    fn constrain<K: Kernel>(
        &mut self,
        sim: &Simulation<D, K>,
        time: f64,
        dt: f64,
        velocity: &[Vector<D>],
    ) where
        dyn Material: DimensionDispatch<D>,
    {
        let grid = &sim.grid;
        let op = &mut self.operator;
        op.normals.clear();
        for (i, (&m, &v)) in grid.mass.iter().zip(velocity).enumerate() {
            let free = m > 0.0;
            op.mass_rate[i] = if free { m / dt } else { 0.0 };
            let mask = &mut op.mask[i * D..(i + 1) * D];
            mask.fill(if free { 1.0 } else { 0.0 });
            let mut v = v;
            if free && !sim.boundaries.is_empty() {
                let ijk = grid.coords(i);
                let x = grid.position(ijk);
                let normals = &mut op.normals;
                sim.boundaries.node_conditions(
                    ijk,
                    &x,
                    time,
                    |n, contact, surface| match contact {
                        Contact::Stick => {
                            mask.fill(0.0);
                            v = n * n.dot(&v) + (surface - n * n.dot(&surface));
                        }
                        Contact::Slip
                        | Contact::Symmetry
                        | Contact::Friction { .. }
                        | Contact::Navier { .. } => {
                            if let Some(axis) = (0..D).find(|&d| n[d].abs() > 1.0 - 1e-12) {
                                mask[axis] = 0.0;
                            } else {
                                normals.push((i as u32, n));
                            }
                        }
                    },
                );
            }
            for d in 0..D {
                self.start[i * D + d] = v[d];
            }
        }
        // Ghosts are no unknowns (a Navier wall's keep their P2G mass: nothing is folded).
        for m in &op.mirrors {
            op.mass_rate[m.ghost as usize] = 0.0;
            op.mask[m.ghost as usize * D..(m.ghost as usize + 1) * D].fill(0.0);
        }
    }

    /// The backward-Euler viscous step: solves for the viscous velocity change δ of
    /// `velocity`, the grid velocity before the walls (which the projection takes), and
    /// adds it there. Reports the
    /// iterations as `incompressible.viscous_iterations`; a solve that does not converge,
    /// or a viscosity that is not a finite number ≥ 0, stops the run.
    pub(super) fn solve<K: Kernel>(
        &mut self,
        sim: &mut Simulation<D, K>,
        settings: &IncompressibleSettings,
        dt: f64,
        velocity: &mut [Vector<D>],
        navier: Option<&mut NavierDrag<D>>,
    ) where
        dyn Material: DimensionDispatch<D>,
    {
        self.prepare(sim);
        build_interpolation::<D, K>(&sim.grid, &sim.particles, &mut self.operator.interp);
        if let Some((p, mu)) = self.coefficients(sim) {
            sim.report.fail(PhysicsFault {
                field: "viscosity".into(),
                particle: Some(p),
                value: mu,
                message: "a liquid's viscosity is not a finite number >= 0".into(),
            });
        }
        self.constrain(sim, sim.time + dt, dt, velocity);
        let mut navier = navier;
        match navier.as_deref_mut() {
            Some(navier) => navier.for_implicit_solve(
                sim,
                sim.time + dt,
                &self.operator.interp,
                &self.operator.coefficient,
                &mut self.operator.drag,
            ),
            None => self.operator.drag.clear(),
        }
        // (M/dt + K + C)(v₀ + δ) = (M/dt) v₀ + C V on the free subspace, with C the Navier
        // surfaces' drag and V their velocity: P A P δ = -P (K + C) v₀ + P C V.
        let Self {
            operator,
            scratch,
            start,
            delta,
            rhs,
            inverse_diagonal,
            r,
            z,
            p,
            ap,
            ..
        } = self;
        operator.product(start, rhs, scratch, false);
        rhs.iter_mut().for_each(|b| *b = -*b);
        if let Some(navier) = navier.as_deref() {
            navier.add_surface_velocity(rhs);
            operator.project(rhs);
        }
        delta.fill(0.0);
        operator.inverse_diagonal(inverse_diagonal);
        let result = if operator.coefficient.iter().any(|&c| c > 0.0)
            || operator.drag.iter().any(|&(_, c)| c > 0.0)
        {
            let op = &*operator;
            let inverse = &*inverse_diagonal;
            solve_preconditioned(
                |x, y| op.apply(x, y, scratch),
                |r, z| {
                    for ((z, r), d) in z.iter_mut().zip(r).zip(inverse) {
                        *z = r * d;
                    }
                    op.project(z);
                },
                &op.mask,
                rhs,
                delta,
                Work { r, z, p, ap },
                settings.tolerance,
                settings.max_iterations,
            )
        } else {
            Solve {
                iterations: 0,
                converged: true,
            }
        };
        super::report_solve(
            &mut sim.report,
            result,
            (
                "incompressible.viscous_iterations",
                "velocity",
                "implicit viscous solve",
            ),
            settings.max_iterations,
        );
        operator.project(delta);
        for (i, v) in velocity.iter_mut().enumerate() {
            for d in 0..D {
                v[d] += delta[i * D + d];
            }
        }
        if let Some(navier) = navier {
            sim.ledger.viscous += navier.dissipation(velocity, dt);
        }
    }
}

/// Each particle's viscosity μ_p, Pa·s, at its state (the last step's velocity gradient,
/// its temperature and cure): 0 for particles whose law has none, whatever the law gives
/// (even not finite) otherwise; and per group the least finite one ≥ 0 (0 if none).
pub(super) fn particle_viscosities<const D: usize>(
    particles: &crate::particles::Particles<D>,
    out: &mut Vec<f64>,
    least_per_group: &mut Vec<f64>,
) where
    dyn Material: DimensionDispatch<D>,
{
    out.resize(particles.len(), 0.0);
    least_per_group.clear();
    for group in &particles.groups {
        let range = group.range.clone();
        let material = group.material.as_ref();
        let reads: [&[f64]; MAX_SHARED_READS] = std::array::from_fn(|k| {
            material
                .shared_reads()
                .get(k)
                .and_then(|r| particles.shared.get(r.name))
                .map_or(&[][..], |f| &f[range.clone()])
        });
        let velocity_gradient = if particles.velocity_gradient.is_empty() {
            &[][..]
        } else {
            &particles.velocity_gradient[range.clone()]
        };
        let viscosity = &mut out[range];
        material.viscosities(ViscosityBatch {
            velocity_gradient,
            shared: reads,
            viscosity: &mut *viscosity,
        });
        let least = viscosity
            .iter()
            .copied()
            .filter(|c| c.is_finite() && *c >= 0.0)
            .fold(f64::INFINITY, f64::min);
        least_per_group.push(if least.is_finite() { least } else { 0.0 });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small pseudo-random sequence in [-1, 1).
    fn numbers(seed: u64, n: usize) -> Vec<f64> {
        let mut state = seed;
        (0..n)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    /// P A P is symmetric and positive definite on the free subspace with a stick ghost,
    /// a symmetry ghost, fixed components, a general normal and Navier drag.
    #[test]
    fn operator_is_symmetric_positive_definite() {
        let nodes = 12;
        let particles = 5;
        let stencil = 4;
        let r = numbers(7, particles * stencil * 3);
        let interp = Interpolation::<2> {
            stencil,
            node: (0..particles * stencil)
                .map(|e| ((r[3 * e] + 1.0) * 0.5 * nodes as f64).min(nodes as f64 - 1.0) as u32)
                .collect(),
            weight: vec![0.25; particles * stencil],
            gradient: (0..particles * stencil)
                .map(|e| Vector::<2>::new(r[3 * e + 1] * 100.0, r[3 * e + 2] * 100.0))
                .collect(),
            ..Interpolation::default()
        };
        let mut mask = vec![1.0; nodes * 2];
        // Ghosts 0, 1 and 2 (a Navier wall's; no mass, no unknowns), node 3 held along y.
        mask[0..4].fill(0.0);
        mask[4..6].fill(0.0);
        mask[7] = 0.0;
        let mut mass_rate: Vec<f64> = numbers(3, nodes).iter().map(|m| 2.0 + m).collect();
        mass_rate[0] = 0.0;
        mass_rate[1] = 0.0;
        mass_rate[2] = 0.0;
        let op = Operator::<2> {
            interp,
            coefficient: numbers(5, particles).iter().map(|c| 1.5 + c).collect(),
            mass_rate,
            mirrors: vec![
                Mirror::of_wall(0, 5, 1, false),
                Mirror::of_wall(1, 6, 0, true),
                Mirror {
                    ghost: 2,
                    front: 7,
                    axis: 1,
                    normal: 1.0,
                    tangential: 0.4,
                },
            ],
            mask,
            normals: vec![(8, Vector::<2>::new(0.6, 0.8))],
            // A Navier surface's drag on a few nodes, one of them with a general normal.
            drag: (0..nodes as u32)
                .filter(|i| i % 3 == 2)
                .map(|i| (i, 0.7))
                .collect(),
        };
        let mut scratch = Scratch::<2> {
            full: vec![0.0; nodes * 2],
            stress: vec![Matrix::<2>::zeros(); particles],
        };
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        for seed in 0..4 {
            let x = numbers(100 + seed, nodes * 2);
            let y = numbers(200 + seed, nodes * 2);
            let (mut ax, mut ay) = (vec![0.0; nodes * 2], vec![0.0; nodes * 2]);
            op.apply(&x, &mut ax, &mut scratch);
            op.apply(&y, &mut ay, &mut scratch);
            let (xay, yax) = (dot(&x, &ay), dot(&y, &ax));
            assert!(
                (xay - yax).abs() <= 1e-12 * xay.abs().max(yax.abs()),
                "{xay} vs {yax}"
            );
            let mut px = x.clone();
            op.project(&mut px);
            assert!(dot(&px, &ax) > 0.0);
        }
    }
}
