//! The pressure side of the projection (mod.rs): the liquid cells' Poisson operator and its
//! CG solve (with the enclosed-air pockets' unknowns after the nodes), the velocity change
//! the pressure gives the nodes, and the nodal pressure interpolated to the particles.

use super::enclosed_air::EnclosedAir;
use super::{Incompressible, MAX_CORNERS, cell_of};
use crate::kernels::Kernel;
use crate::linear_solvers::conjugate_gradient::{Solve, Work, solve};
use crate::math::Vector;
use crate::physics::PhysicsFault;
use crate::solver::simulation::Simulation;

/// The liquid cells' pressure Poisson operator Σ_c (1/ρ_c) ∫_c ∇N_i·∇N_j, borrowed from
/// the projection's workspace (with the enclosed-air pockets' rows when `air` is given).
pub(super) struct CellOperator<'a> {
    pub(super) stiffness: &'a [[f64; MAX_CORNERS]; MAX_CORNERS],
    pub(super) corner_offset: &'a [usize; MAX_CORNERS],
    pub(super) cell_mass: &'a [f64],
    pub(super) cell_volume: &'a [f64],
    pub(super) cell_node: &'a [usize],
    /// Corners of a cell, 2^D.
    pub(super) corners: usize,
    pub(super) air: Option<&'a EnclosedAir>,
    /// Grid nodes (the pockets' unknowns come after them).
    pub(super) n: usize,
}

impl CellOperator<'_> {
    /// y = A x over the liquid cells (every node's value counts: fixed ones too).
    pub(super) fn apply(&self, x: &[f64], y: &mut [f64]) {
        let (corners, n) = (self.corners, self.n);
        y.fill(0.0);
        let mut xc = [0.0; MAX_CORNERS];
        for c in 0..self.cell_mass.len() {
            if self.cell_volume[c] <= 0.0 {
                continue;
            }
            let scale = self.cell_volume[c] / self.cell_mass[c];
            let base = self.cell_node[c];
            for (b, value) in xc.iter_mut().enumerate().take(corners) {
                let j = base + self.corner_offset[b];
                // A node around an enclosed pocket adds the pocket's pressure.
                *value = x[j] + self.air.map_or(0.0, |a| a.tied(j, x, n));
            }
            for a in 0..corners {
                let sum: f64 = self.stiffness[a][..corners]
                    .iter()
                    .zip(&xc[..corners])
                    .map(|(k, x)| k * x)
                    .sum();
                y[base + self.corner_offset[a]] += scale * sum;
            }
        }
        if let Some(air) = self.air {
            air.gather(x, y, n);
        }
    }
}

impl<const D: usize> Incompressible<D> {
    /// Solves the liquid cells' pressure Poisson operator for `pressure` from `rhs` (CG, warm
    /// started), with the enclosed-air pockets' unknowns after the `n` nodes when
    /// `with_air`.
    pub(super) fn cell_solve(&mut self, corners: usize, n: usize, with_air: bool) -> Solve {
        let Self {
            stiffness,
            corner_offset,
            cell_mass,
            cell_volume,
            cell_node,
            inverse_diagonal,
            pressure,
            rhs,
            r,
            z,
            p,
            ap,
            settings,
            air,
            ..
        } = self;
        let operator = CellOperator {
            stiffness,
            corner_offset,
            cell_mass,
            cell_volume,
            cell_node,
            corners,
            air: air.as_ref().filter(|_| with_air),
            n,
        };
        let apply = |x: &[f64], y: &mut [f64]| operator.apply(x, y);
        if inverse_diagonal.iter().any(|&v| v > 0.0) {
            solve(
                apply,
                inverse_diagonal,
                rhs,
                pressure,
                Work { r, z, p, ap },
                settings.tolerance,
                settings.max_iterations,
            )
        } else {
            Solve {
                iterations: 0,
                converged: true,
            }
        }
    }

    /// The pressure solve's vectors: one entry per node, and per enclosed-air pocket
    /// while the solve runs (enclosed_air.rs).
    pub(super) fn solve_vectors(&mut self) -> [&mut Vec<f64>; 7] {
        [
            &mut self.inverse_diagonal,
            &mut self.pressure,
            &mut self.rhs,
            &mut self.r,
            &mut self.z,
            &mut self.p,
            &mut self.ap,
        ]
    }

    /// The projection's velocity change at the nodes of the liquid cells:
    /// -(dt/M_i) Σ_c ∫_c N_i ∇p with the lumped mass M_i = Σ_c ρ_c ∫_c N_i of the same
    /// cells. A uniform ∇p/ρ (hydrostatics) then changes every one of those nodes by the
    /// same -dt ∇p/ρ, whatever mass P2G gave them (with B-splines a node next to a wall or
    /// the surface has a P2G mass that differs from ρ∫N_i over the liquid cells).
    pub(super) fn pressure_correction(&mut self, dt: f64, dx: f64) {
        let corners = 1 << D;
        // ∫_c N_a over one full cell: dx^D / 2^D.
        let share = (0..D).fold(1.0, |v, _| v * 0.5 * dx);
        self.lumped_mass.fill(0.0);
        self.correction.fill(Vector::<D>::zeros());
        let mut grad = [[0.0; 3]; MAX_CORNERS];
        for c in 0..self.cell_mass.len() {
            if self.cell_volume[c] <= 0.0 {
                continue;
            }
            let rho = self.cell_mass[c] / self.cell_volume[c];
            let base = self.cell_node[c];
            for (a, g) in grad.iter_mut().enumerate().take(corners) {
                for (d, gd) in g.iter_mut().enumerate().take(D) {
                    let mut sum = 0.0;
                    for b in 0..corners {
                        sum += self.gradient[a][d][b] * self.pressure[base + self.corner_offset[b]];
                    }
                    *gd = sum;
                }
            }
            for (a, g) in grad.iter().enumerate().take(corners) {
                let node = base + self.corner_offset[a];
                self.lumped_mass[node] += rho * share;
                for (d, gd) in g.iter().enumerate().take(D) {
                    self.correction[node][d] += gd;
                }
            }
        }
        for ((m, c), layer) in self
            .lumped_mass
            .iter()
            .zip(self.correction.iter_mut())
            .zip(self.layer.iter_mut())
        {
            if *m > 0.0 {
                *c *= -dt / m;
                *layer = 0;
            } else {
                *layer = u8::MAX;
            }
        }
    }

    /// Interpolates the nodal pressure (cell shape functions) into the liquids' `pressure`
    /// state field.
    pub(super) fn pressure_to_particles<K: Kernel>(&self, sim: &mut Simulation<D, K>) {
        let grid = &sim.grid;
        let crate::particles::Particles {
            groups, position, ..
        } = &mut sim.particles;
        for group in groups.iter_mut() {
            let Some(field) = group
                .material
                .state_fields()
                .iter()
                .position(|f| f.name == "pressure" && f.components == 1)
            else {
                continue;
            };
            let out = &mut group.state[field];
            for (k, i) in group.range.clone().enumerate() {
                out[k] = self.pressure_at(grid, &position[i]);
            }
        }
    }

    /// The nodal pressure interpolated with the cell's bilinear (trilinear) shape
    /// functions at `x`.
    pub(super) fn pressure_at(&self, grid: &crate::grid::Grid<D>, x: &Vector<D>) -> f64 {
        let (c, s) = cell_of(grid, x);
        let base = self.cell_node[c];
        let mut value = 0.0;
        for a in 0..1 << D {
            let mut w = 1.0;
            for (d, sd) in s.iter().enumerate().take(D) {
                w *= if (a >> d) & 1 == 1 { *sd } else { 1.0 - sd };
            }
            value += w * self.pressure[base + self.corner_offset[a]];
        }
        value
    }
}

/// Records a linear solve's iterations under `key` and stops the run with a diagnostic
/// on `field` when it did not converge (`what` names the solve in the message).
pub(super) fn report_solve(
    report: &mut crate::physics::PhysicsReport,
    result: Solve,
    (key, field, what): (&str, &str, &str),
    max_iterations: u32,
) {
    report.record_max(key, result.iterations as f64);
    if !result.converged {
        report.fail(PhysicsFault {
            field: field.into(),
            particle: None,
            value: result.iterations as f64,
            message: format!(
                "the {what} did not converge in {max_iterations} iterations (raise solver.mechanics.incompressible.max_iterations or the tolerance)"
            ),
        });
    }
}
