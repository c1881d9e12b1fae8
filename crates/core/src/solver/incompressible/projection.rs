//! The projection itself (step 2 and 3 of mod.rs): which cells are liquid and which nodes
//! are pressure unknowns, the Poisson solve's right-hand side with the volume source,
//! surface tension, pressure inlets and enclosed air, the solve, and the velocity change;
//! with implicit viscosity, the total pressure kept for the next step's viscous solve.

use super::pressure::report_solve;
use super::volume_source::{SOURCE_CFL, VOLUME_CORRECTION};
use super::{
    AIR_POCKETS, AIR_PRESSURE, CLOSED_GAPS, Incompressible, cell_of, convective_step, extrapolate,
    moving_rows, pressure_inlet,
};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::solver::DimensionDispatch;
use crate::solver::simulation::Simulation;

impl<const D: usize> Incompressible<D> {
    /// The liquid cells (a particle of a moving group in them) with their mass and volume,
    /// and the pressure unknowns: `inverse_diagonal` is 1/diagonal on nodes whose every
    /// cell is liquid or solid, 0 on the free surface and off the liquid.
    pub(super) fn classify_cells<K: Kernel>(&mut self, sim: &Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let corners = 1 << D;
        // Liquid cells and their density.
        self.cell_mass.fill(0.0);
        self.cell_volume.fill(0.0);
        let particles = &sim.particles;
        // Held solids are no liquid: their cells are solid (`Boundaries::cell_is_solid`).
        for i in moving_rows(particles) {
            let (c, _) = cell_of(&sim.grid, &particles.position[i]);
            // A particle a hair behind a wall (interpolated velocities let one cross by a
            // fraction of a cell) counts in the cell in front of it. Counted where it was,
            // it made a liquid cell behind the wall, and free nodes held by that cell
            // alone: with implicit viscosity, whose projection solves for the change from
            // the pressure it kept, such a node kept a pressure tens of kPa under the
            // liquid's around it in a sealed box, and the next step's force from that
            // inverted a particle (stop 80). Left out, the strays felt no pressure and
            // were flung off the walls at 0.6 m/s in the inflow tank.
            let c = self.cell_home[c];
            self.cell_mass[c] += particles.mass[i];
            self.cell_volume[c] += particles.volume0[i];
        }
        // Free nodes: every cell around them inside the grid is liquid. Start all nodes
        // touched by a liquid cell as free, then clear those touching an empty cell.
        self.inverse_diagonal.fill(0.0);
        for c in 0..self.cell_mass.len() {
            if self.cell_volume[c] > 0.0 {
                let rho = self.cell_mass[c] / self.cell_volume[c];
                let base = self.cell_node[c];
                for a in 0..corners {
                    self.inverse_diagonal[base + self.corner_offset[a]] +=
                        self.stiffness[a][a] / rho;
                }
            }
        }
        for c in 0..self.cell_mass.len() {
            if self.cell_volume[c] <= 0.0 && !self.cell_solid[c] {
                let base = self.cell_node[c];
                for a in 0..corners {
                    self.inverse_diagonal[base + self.corner_offset[a]] = -1.0;
                }
            }
        }
        for v in &mut self.inverse_diagonal {
            *v = if *v > 0.0 { 1.0 / *v } else { 0.0 };
        }
    }

    /// Solves the pressure Poisson equation for the grid velocity after the explicit
    /// forces and projects it; walls and obstacles act again afterwards.
    pub(super) fn project<K: Kernel>(&mut self, sim: &mut Simulation<D, K>, dt: f64)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let corners = 1 << D;
        // Right-hand side (1/dt) ∫ ∇N_i · v* over the liquid cells, with v* before the walls
        // act: -(1/dt) ∫ N_i ∇·v* integrated by parts, where the boundary term is the flux
        // through the walls after the step, zero (fixed walls), and N_i = 0 on the free
        // surface. A liquid at rest on a floor then has exactly ρ·g·h.
        self.rhs.fill(0.0);
        let velocity = &self.free_velocity;
        for c in 0..self.cell_mass.len() {
            if self.cell_volume[c] <= 0.0 {
                continue;
            }
            let base = self.cell_node[c];
            for a in 0..corners {
                let mut flux = 0.0;
                for b in 0..corners {
                    let v = &velocity[base + self.corner_offset[b]];
                    for d in 0..D {
                        flux += self.gradient[b][d][a] * v[d];
                    }
                }
                self.rhs[base + self.corner_offset[a]] += flux / dt;
            }
        }
        // Scenes with inlets or enclosed air, or that ask for it, move misplaced particle
        // volume back (volume_source.rs).
        let rate = (dt / (sim.settings.cfl.max(SOURCE_CFL) * convective_step(sim))).min(1.0);
        let source = self.settings.volume_correction
            || self.air.is_some()
            || sim.inflow.as_ref().is_some_and(|f| f.has_inlets());
        self.source_solved = source && self.viscosity.is_some();
        if source {
            self.add_volume_source(&sim.grid, &sim.particles, dt, rate);
        }
        if !self.source_solved {
            self.last_source_rate.clear();
        }
        // A rate inlet in a wall pushes its rate through its face (wall_inlet.rs), where
        // the liquid before it is not sealed (the source's balance found the regions; a
        // face node on the free surface is open).
        if let Some(inlets) = &mut self.wall_inlets {
            let (balance, free) = (&mut self.balance, &self.inverse_diagonal);
            inlets.add_flux(sim.time, dt, &mut self.rhs, |i| {
                !(free[i] > 0.0 && balance.is_sealed(i))
            });
        }
        for (x, free) in self.pressure.iter_mut().zip(&self.inverse_diagonal) {
            if *free <= 0.0 {
                *x = 0.0;
            }
        }
        self.surface_pressure(sim);
        if let Some(surface) = &mut self.surface {
            sim.surface_energy = surface.energy(&sim.grid, &self.open);
        }
        // The incremental projection (implicit viscosity) solves for the change from the
        // part of the kept total pressure whose force is still in the velocity
        // (`add_kept_pressure_force`): on the free surface the increment is what the surface
        // asks for (0, or σ·κ with surface tension) less that, enclosed air's nodes
        // included. A node that was inside the liquid at the last step and is on the
        // surface now kept its last pressure; with an increment of 0 there (as it was
        // without surface tension until stop 86) the projection acted as if it still had
        // it, and the next step, whose kept force said 0, did not: the implicit inflow
        // tank's surface flickered at a wall and threw particles up it at 0.25 m/s.
        if let Some(viscosity) = &self.viscosity {
            for (i, p) in self.pressure.iter_mut().enumerate() {
                if self.inverse_diagonal[i] <= 0.0 {
                    *p -= viscosity.kept_in_velocity(i);
                }
            }
        }
        // Pressure inlets hold their face at the reservoir's pressure (pressure_inlet.rs);
        // the incremental projection solves for the change from the pressure whose force
        // the velocity kept there.
        for &i in &self.held {
            self.is_held[i] = false;
        }
        self.held.clear();
        if let Some(inflows) = &sim.inflow {
            let viscosity = self.viscosity.as_ref();
            pressure_inlet::hold_pressure(
                inflows.drives(),
                &sim.grid,
                sim.time,
                &self.inverse_diagonal,
                |i| viscosity.map_or(0.0, |v| v.kept_in_velocity(i)),
                &mut self.pressure,
                &mut self.held,
            );
            for &i in &self.held {
                self.is_held[i] = true;
            }
        }
        let n = sim.grid.len();
        if let Some(mut air) = self.air.take() {
            air.find_pockets(
                &sim.grid,
                &self.cell_volume,
                &self.cell_solid,
                &self.cell_node,
                &self.corner_offset[..corners],
            );
            for v in self.solve_vectors() {
                v.resize(n + air.unknowns(), 0.0);
            }
            let (cell_volume, cell_mass) = (&self.cell_volume, &self.cell_mass);
            air.fill_rows(
                n,
                dt,
                VOLUME_CORRECTION * rate,
                |c| (cell_volume[c] > 0.0).then(|| cell_volume[c] / cell_mass[c]),
                &self.cell_node,
                &self.corner_offset[..corners],
                &self.stiffness,
                &mut self.rhs,
                &mut self.inverse_diagonal,
                &mut self.pressure,
            );
            self.air = Some(air);
        }
        let result = self.cell_solve(corners, n, true);
        report_solve(
            &mut sim.report,
            result,
            ("incompressible.iterations", "pressure", "pressure solve"),
            self.settings.max_iterations,
        );
        if let Some(air) = &mut self.air {
            let (pockets, gaps) = air.counts();
            sim.report.record_max(AIR_POCKETS, pockets as f64);
            sim.report.record_max(CLOSED_GAPS, gaps as f64);
            let largest = air.finish(&mut self.pressure, n);
            sim.report.record_max(AIR_PRESSURE, largest);
        }
        if self.source_solved {
            // The volume source's own pressure, for `incremental_pressure` to leave out:
            // the same operator, pockets and gaps included (their volume share is a source
            // too, and must not come back as next step's force).
            std::mem::swap(&mut self.rhs, &mut self.source_rhs);
            std::mem::swap(&mut self.pressure, &mut self.source_pressure);
            let unknowns = self.air.as_ref().map_or(0, |a| a.unknowns());
            self.rhs.resize(n + unknowns, 0.0);
            self.pressure.resize(n + unknowns, 0.0);
            self.pressure.fill(0.0);
            if let Some(air) = &self.air {
                air.source_rows(n, &mut self.rhs);
            }
            let result = self.cell_solve(corners, n, true);
            if let Some(air) = &self.air {
                air.add_tied(&mut self.pressure, n);
            }
            self.rhs.truncate(n);
            self.pressure.truncate(n);
            std::mem::swap(&mut self.rhs, &mut self.source_rhs);
            std::mem::swap(&mut self.pressure, &mut self.source_pressure);
            report_solve(
                &mut sim.report,
                result,
                (
                    "incompressible.source_iterations",
                    "pressure",
                    "volume source solve",
                ),
                self.settings.max_iterations,
            );
        }
        if source {
            sim.ledger.volume_source += self.volume_source_work();
        }
        for v in self.solve_vectors() {
            v.truncate(n);
        }
        self.pressure_correction(dt, sim.grid.dx);
        extrapolate::extrapolate_correction(&sim.grid, &mut self.correction, &mut self.layer);
        // Projection of the velocity before the walls, then the walls.
        for (i, v) in sim.grid.momentum.iter_mut().enumerate() {
            *v = self.free_velocity[i];
            if self.layer[i] != u8::MAX {
                *v += self.correction[i];
            }
        }
        sim.ledger.openings += self.walls_act(sim, dt);
    }

    /// With implicit viscosity, the first half of the incremental projection: adds the
    /// kept total pressure's velocity change dt·(-(1/M_i) Σ_c ∫_c N_i ∇p^n) to the velocity
    /// before the walls (extrapolated as the projection's) for the viscous solve to see,
    /// and keeps p^n. After the solve `ImplicitViscosity::take_back` takes a share of it
    /// back out again, and the projection solves for the increment from the rest.
    ///
    /// The force is taken on this step's liquid cells, the ones the projection solves on.
    /// Until stop 87 it was the last step's, taken on its cells, and where cells had filled
    /// or emptied since, it differed from the kept pressure's force on this step's; the
    /// difference, no gradient here, stayed in the velocity.
    ///
    /// The share taken back: the projection's Laplacian ∫∇N·∇N is not the divergence of its
    /// gradient (the fractional step's stabilisation, mod.rs), so a pressure that changes
    /// sharply from node to node, as the impulse that closes a gap inside the liquid does
    /// (0.3-0.9 kPa over one node in the inflow tank), is not taken away again by the
    /// projection when its force comes back: with all of it left in the velocity, half of
    /// a 0.7 m/s kick stayed and inverted a particle. Its force goes through the viscous
    /// solve, whose backward Euler leaves 1/(1 + 4·D·ν·dt/dx²) of a velocity that changes
    /// sign from node to node (the stiffest mode; ν the least kinematic viscosity of the
    /// liquids), and that share is what is taken back: all of it for water at these steps
    /// (the kick goes), none for a liquid whose viscous step damps such a velocity away
    /// (the viscous drop's Laplace pressure goes through the viscous step, as before; taken
    /// back whole, its spurious speed was 5× the incremental form's). A smooth pressure's
    /// force is taken away by the projection exactly either way.
    pub(super) fn add_kept_pressure_force<K: Kernel>(&mut self, sim: &Simulation<D, K>, dt: f64)
    where
        dyn Material: DimensionDispatch<D>,
    {
        if self.viscosity.is_none() {
            return;
        }
        self.pressure_correction(dt, sim.grid.dx);
        extrapolate::extrapolate_correction(&sim.grid, &mut self.correction, &mut self.layer);
        if let Some(viscosity) = self.viscosity.as_mut() {
            let share = viscosity.undamped_share(&sim.particles.groups, sim.grid.dx, dt);
            viscosity.pre_apply(&mut self.free_velocity, &self.correction, &self.layer, true);
            viscosity.keep_base(&mut self.pressure, dt, sim.chosen_dt, share);
        }
    }

    /// With implicit viscosity the projection solved for the pressure increment: adds the
    /// last pressure back (on the free surface σ·κ with surface tension, else 0) and keeps
    /// the total for the next step (`add_kept_pressure_force`). Nothing with explicit
    /// viscosity.
    pub(super) fn incremental_pressure(&mut self) {
        let Some(viscosity) = self.viscosity.as_mut() else {
            return;
        };
        // The volume source moves particles back into place once; its pressure is no part
        // of the liquid's and must not come back as next step's force.
        if self.source_solved {
            for (p, q) in self.pressure.iter_mut().zip(&self.source_pressure) {
                *p -= q;
            }
        }
        let (air, held, surface) = (self.air.as_ref(), &self.is_held, self.surface.as_ref());
        viscosity.total_pressure(&mut self.pressure, &self.inverse_diagonal, |i| {
            air.is_some_and(|a| a.is_tied(i))
                || held[i]
                || surface.is_some_and(|s| s.touches_liquid(i))
        });
    }
}
