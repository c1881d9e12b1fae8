//! The liquid's share of the energy balance: the energy its viscosity dissipates (booked
//! in `EnergyLedger::viscous`) and the energy its surfaces store (`surface_energy`, part of
//! the total energy), so that what remains of a liquid run's energy balance is the
//! method's own error (the projection's and the transfer's losses), as for solids.
//!
//! - Viscous dissipation: the stress power of the liquid particles' viscous stress,
//!   Σ_p V_p σ_p : L_p (σ = 2μ dev(sym L) ≥ 0 against L), at the end of each step, times
//!   the step. With explicit viscosity that stress acts in the next step's P2G; with
//!   implicit viscosity the grid solve applied the same law to the same velocity field.
//! - Surface energy: σ ∫|∇c| dV over the nodes in front of every wall and obstacle (the
//!   colour c of the surface tension, smoothed, goes from 0 to 1 across the surface, so
//!   the integral of its gradient's length is the surface's area), plus, on each wall and
//!   obstacle with a contact angle θ ≠ 90°, (γ_SL − γ_SV) A_wet = −σ cos θ A_wet (Young),
//!   with A_wet = ∫ c dA over the solid's surface: on a wall the sum over the nodes of its
//!   plane in front of the other walls, on an obstacle a sum over the nodes near its
//!   surface with the hat weight max(0, 1 − |depth|) in cells, which integrates a plane
//!   at any angle. Solid bodies are held obstacles in this mode (`scene::held_bodies`),
//!   so their wetted faces count as an obstacle's.
//! - Pumping work: liquid that enters through an inlet is pushed in against the pressure
//!   there, so it brings p·V with it besides its kinetic and gravity energy (the pressure
//!   term of the energy flux (½ρ|v|² + ρgz + p) v·n); each entering particle's volume
//!   times the pressure at its place at the end of the step, booked in
//!   `EnergyLedger::openings`. Liquid leaves through open faces at p = 0.
//!
//! The surface energy is measured from the P2G mass at the start of the step, the
//! positions the projection's colour sees, so it lags the kinetic energy by one step; the
//! difference is part of the method's error and vanishes as dt does.

use super::Incompressible;
use super::surface_tension::SurfaceTension;
use crate::grid::{Grid, node_coords};
use crate::kernels::Kernel;
use crate::particles::Particles;
use crate::solver::parallel::ordered_particle_sum;
use crate::solver::simulation::Simulation;

/// Σ_p V_p σ_p : L_p over the particles of liquid materials (those with a viscosity), W
/// (W/m in 2D): the rate at which their viscous stress dissipates energy. The liquid's
/// F stays I, so V_p is the reference volume.
pub(super) fn viscous_power<const D: usize>(particles: &Particles<D>) -> f64 {
    if particles.velocity_gradient.len() != particles.len() {
        return 0.0;
    }
    let mut power = 0.0;
    for group in &particles.groups {
        if group.material.liquid_viscosity().is_none() {
            continue;
        }
        let start = group.range.start;
        power += ordered_particle_sum(group.range.len(), |k| {
            let p = start + k;
            particles.volume0[p] * particles.stress[p].dot(&particles.velocity_gradient[p])
        });
    }
    power
}

/// Per node, the fraction of the cells around it (those inside the grid) that are not
/// behind a wall or inside an obstacle: 1 in the open, ½ on a flat wall's plane, 0 inside
/// a solid. `cell_node` is each cell's lowest corner, `corner_offset` the 2^D corners.
pub(super) fn open_fraction<const D: usize>(
    grid: &Grid<D>,
    cell_solid: &[bool],
    cell_node: &[usize],
    corner_offset: &[usize],
) -> Vec<f64> {
    let mut open = vec![0.0; grid.len()];
    let mut count = vec![0u8; grid.len()];
    for (&solid, &base) in cell_solid.iter().zip(cell_node) {
        for offset in corner_offset {
            count[base + offset] += 1;
            if !solid {
                open[base + offset] += 1.0;
            }
        }
    }
    for (o, &n) in open.iter_mut().zip(&count) {
        *o = if n > 0 { *o / f64::from(n) } else { 0.0 };
    }
    open
}

impl<const D: usize> SurfaceTension<D> {
    /// The surface energy at the colour the last [`SurfaceTension::surface_pressure`] (or
    /// [`SurfaceTension::measure`]) made, J (J/m in 2D): σ ∫|∇c| dV over the open part of
    /// each node (`open`, from [`open_fraction`]) less σ cos θ times the wetted area of
    /// every wall and obstacle with a contact angle.
    pub(super) fn energy(&self, grid: &Grid<D>, open: &[f64]) -> f64 {
        let cell = grid.dx.powi(D as i32);
        let face = grid.dx.powi(D as i32 - 1);
        let free: f64 = self
            .gradient
            .iter()
            .zip(open)
            .map(|(g, w)| g.norm() * w)
            .sum::<f64>()
            * cell;
        let mut wetting = 0.0;
        for wall in &self.walls {
            let cos = wall.contact_angle.cos();
            if cos.abs() < 1e-12 {
                continue;
            }
            // A node of the plane stands for its share of the plane in front of every
            // other wall: twice its open fraction (1 on the plane, ½ where another wall
            // meets it, 0 behind one).
            let wetted: f64 = (0..grid.len())
                .filter(|&i| node_coords(&grid.stride, i)[wall.axis] == wall.surface)
                .map(|i| self.colour[i] * (2.0 * open[i]).min(1.0))
                .sum();
            wetting -= cos * wetted * face;
        }
        for image in &self.solid_images {
            let cos = image.contact_angle.cos();
            let hat = 1.0 - image.depth.abs();
            if cos.abs() < 1e-12 || hat <= 0.0 {
                continue;
            }
            wetting -= cos * hat * self.colour[image.node] * face;
        }
        self.sigma * (free + wetting)
    }

    /// The colour of the grid's P2G mass and its gradient (as
    /// [`SurfaceTension::surface_pressure`] makes them), then [`SurfaceTension::energy`]:
    /// the surface energy before the first step.
    pub(super) fn measure(&mut self, grid: &Grid<D>, open: &[f64]) -> f64 {
        self.size_for(grid);
        self.colour_normals(grid);
        self.energy(grid, open)
    }
}

impl<const D: usize> Incompressible<D> {
    /// The work done pushing in the particles that entered in the step of length `dt`:
    /// Σ p(x_i) V_i with this step's (total) pressure, J (J/m in 2D); for a rate inlet in
    /// a wall, the work its face did, Σ p_i U a_i dt (wall_inlet.rs), in their place.
    pub(super) fn pumping_work<K: Kernel>(&self, sim: &Simulation<D, K>, dt: f64) -> f64 {
        let Some(inflows) = sim.inflow.as_ref() else {
            return 0.0;
        };
        let walls = self.wall_inlets.as_ref();
        let particles: f64 = inflows
            .entered()
            .iter()
            .filter(|&&i| {
                let plan = inflows.plan_index(sim.particles.id[i]);
                !plan.is_some_and(|k| walls.is_some_and(|w| w.has_plan(k)))
            })
            .map(|&i| {
                self.pressure_at(&sim.grid, &sim.particles.position[i]) * sim.particles.volume0[i]
            })
            .sum();
        particles + walls.map_or(0.0, |w| w.work(&self.pressure, sim.time, dt))
    }
}
