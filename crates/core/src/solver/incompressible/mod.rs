//! Incompressible liquid (`solver.mechanics.incompressible`): a fractional-step (Chorin)
//! projection MPM after Kularathna & Soga (2017, "Implicit formulation of material point
//! method for analysis of incompressible materials", CMAME 313) and Zhang, Zhang & Liu
//! (2017, "Incompressible material point method for free surface flow", JCP 330).
//!
//! Each step:
//! 1. P2G of mass and momentum with the scene's transfer, the liquid's viscous
//!    (deviatoric) stress and gravity as explicit forces; grid update with walls and
//!    obstacles: the intermediate velocity v*.
//! 2. Pressure Poisson equation on the grid nodes, Galerkin with the grid's bilinear
//!    (trilinear) cell shape functions N, integrated exactly over the liquid cells:
//!    Σ_c (1/ρ_c) ∫_c ∇N_i·∇N_j p_j = (1/dt) Σ_c ∫_c ∇N_i·v*, with v* the velocity before
//!    the walls act (the weak form of -(1/dt)∫N_i ∇·v* whose wall term, the flux through
//!    fixed walls after the step, is zero). A cell is liquid when a
//!    particle lies in it (a particle a hair behind a wall counts in the cell in front of
//!    it); a node touching an empty cell is on the free surface (p = 0).
//!    Cells behind a wall surface or inside an obstacle are neither: walls are a natural
//!    ∂p/∂n = 0 boundary, open domain faces are free surface (p = 0). Solved by core's Jacobi-preconditioned CG, warm
//!    started from the last pressure.
//! 3. Projection: v = v* - (dt/M_i) Σ_c ∫_c N_i ∇p with the lumped mass of the same cells,
//!    M_i = Σ_c ρ_c ∫_c N_i (not the P2G mass: with B-splines a node beside a wall or the
//!    surface gets a P2G mass other than ρ∫N_i over the liquid cells, and a uniform ∇p/ρ
//!    would not cancel gravity there). B-spline kernels reach one node beyond the corners
//!    of a particle's cell, so nodes above the free surface and behind walls carry mass
//!    the cells do not cover; they get the velocity change of their neighbours
//!    (extrapolated, as PIC/FLIP/APIC liquid solvers extrapolate the projected velocity
//!    into the air), not free fall. Then the walls and obstacles again, so no liquid
//!    crosses them.
//! 4. G2P (velocities, positions, velocity gradient); particles that crossed into an
//!    obstacle or held body are put back on its surface (obstacle_guard.rs); liquid enters through the inlets of
//!    `inflow` bodies (inflow.rs; at a set pressure, pressure_inlet.rs, whose face nodes
//!    the Poisson solve of step 2 holds at the reservoir's pressure) and, with `outflow`, leaves through the open domain faces
//!    (outflow.rs); physics, viscous stress; the nodal pressure is interpolated to the
//!    particles' `pressure` field.
//!
//! Equal-order velocity/pressure on one grid is not inf-sup stable for the coupled
//! problem, but the fractional step is: its compact Laplacian ∫∇N·∇N differs from the
//! wide D·M⁻¹·G operator by an O(dt) pressure-stabilising term (Codina 2001), which is
//! what removes the checkerboard mode (pressures at node parity classes decouple under
//! D·M⁻¹·G, not under ∫∇N·∇N). The price: ∇·v is small, not zero, at the discrete level.
//!
//! The step is bounded by the velocity CFL, dx/(|v|max + √(dx·|g|)), and, with viscosity explicit, by
//! ρ·dx²/(2·D·μ); never by a sound speed. With `viscosity: "implicit"` P2G leaves the
//! viscous stress out and a backward-Euler viscous solve on the grid (viscosity.rs) acts
//! between steps 1 and 2; the viscous bound then goes. With surface tension as well, a
//! Poisson solve for the Laplace pressure's change comes before that viscous solve
//! (capillary_first.rs), so the viscous step damps the capillary force and the step is
//! bounded by the viscous–capillary time, not the capillary wave.

mod capillary_first;
mod enclosed_air;
mod energy_balance;
mod extrapolate;
pub(super) mod inflow;
mod navier_slip;
mod obstacle_guard;
mod outflow;
mod pressure;
mod pressure_inlet;
mod projection;
mod surface_tension;
mod viscosity;
mod volume_source;
mod wall_inlet;

use super::DimensionDispatch;
use super::grid_update::{GridParams, update_grid};
use super::mode::StepMode;
use super::particle_to_grid::ForceTerm;
use super::simulation::Simulation;
use crate::boundary::Boundaries;
use crate::grid::{node_coords, node_position};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector};
use crate::scene::{IncompressibleSettings, Transfer, ViscousIntegration};
use pressure::report_solve;
use surface_tension::SurfaceTension;

/// Physics figure: the most enclosed-air pockets that resisted in one step.
pub const AIR_POCKETS: &str = "incompressible.air_pockets";
/// Physics figure: the largest gauge pressure of an enclosed-air pocket over the run, Pa.
pub const AIR_PRESSURE: &str = "incompressible.air_pressure";
/// Physics figure: the most closed gaps (empty regions inside the liquid without gas, or
/// smaller than `min_cells`) in one step; each closes instead of drawing the liquid in.
pub const CLOSED_GAPS: &str = "incompressible.closed_gaps";

/// Corners of a cell (2^D, at most 8).
const MAX_CORNERS: usize = 8;

/// The pressure projection and its workspace (allocated on the first step, reused).
pub(super) struct Incompressible<const D: usize> {
    settings: IncompressibleSettings,
    /// Cell-shape-function stiffness ∫∇N_a·∇N_b over one full cell.
    stiffness: [[f64; MAX_CORNERS]; MAX_CORNERS],
    /// ∫N_a ∂N_b/∂x_d over one full cell, `[a][d][b]`.
    gradient: [[[f64; MAX_CORNERS]; 3]; MAX_CORNERS],
    /// Node-index offset of each cell corner.
    corner_offset: [usize; MAX_CORNERS],
    /// Particle mass and reference volume per cell (cell index), for the liquid flag and ρ.
    cell_mass: Vec<f64>,
    cell_volume: Vec<f64>,
    /// Node index of each cell's lowest corner.
    cell_node: Vec<usize>,
    /// Nodal velocity after the explicit forces, before walls and obstacles act.
    free_velocity: Vec<Vector<D>>,
    /// Cells behind a wall or inside an obstacle (at its initial place): neither liquid
    /// nor free surface.
    cell_solid: Vec<bool>,
    /// The cell whose liquid a particle in each cell counts as: itself, or for a cell
    /// behind a wall the first cell in front of it.
    cell_home: Vec<usize>,
    /// The cells beside obstacles as the volume source sees them (volume_source.rs).
    source_cells: volume_source::SourceCells,
    /// Per node: the fraction of its cells that are not solid (the surface energy's
    /// weight; energy_balance.rs).
    open: Vec<f64>,
    /// Per node: 1/diagonal on the free (pressure-unknown) nodes, 0 on the free surface.
    inverse_diagonal: Vec<f64>,
    /// Per node: the projection's lumped mass Σ_c ρ_c ∫_c N_i over the liquid cells (0 off
    /// them), the mass that the gradient ∫N_i ∇p and the Laplacian's 1/ρ_c belong to.
    lumped_mass: Vec<f64>,
    /// Per node: the projection's velocity change -(dt/M_i) Σ_c ∫_c N_i ∇p, extrapolated to
    /// the nodes that carry P2G mass outside the liquid cells.
    correction: Vec<Vector<D>>,
    /// Per node: 0 where `correction` comes from the liquid cells, k where it was
    /// extrapolated in pass k, `u8::MAX` where it is not set.
    layer: Vec<u8>,
    pressure: Vec<f64>,
    /// The Laplace pressure on the free surface, when a liquid has a surface tension.
    surface: Option<SurfaceTension<D>>,
    rhs: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
    /// The implicit viscous step (`viscosity: "implicit"`), else `None`.
    viscosity: Option<viscosity::ImplicitViscosity<D>>,
    /// With implicit viscosity: the capillary pressure solved before the viscous step
    /// (capillary_first.rs; acts only with surface tension).
    capillary: Option<capillary_first::CapillaryFirst>,
    /// The gas in the pockets the liquid encloses (`enclosed_air`), else `None`.
    air: Option<enclosed_air::EnclosedAir>,
    /// The drag of Navier-slip walls and obstacles (empty without them).
    navier: navier_slip::NavierDrag<D>,
    /// With implicit viscosity: the volume source's own right-hand side and pressure, and
    /// whether this step has one (see `incremental_pressure`).
    source_rhs: Vec<f64>,
    source_pressure: Vec<f64>,
    /// Per node, the volume per unit time the last step's source asked for
    /// (`volume_source.rs`), with implicit viscosity; empty otherwise.
    last_source_rate: Vec<f64>,
    source_solved: bool,
    /// Per node: its share of the volume this step's source lets the cells gain (or lose),
    /// m³ (m² in 2D), for the source's work (volume_source.rs).
    source_volume: Vec<f64>,
    /// Scratch for taking sealed regions' net source out (volume_source.rs).
    balance: volume_source::SourceBalance,
    /// The nodes a pressure inlet holds this step (pressure_inlet.rs), and per node whether
    /// it is one of them.
    held: Vec<usize>,
    is_held: Vec<bool>,
    /// The rate inlets whose face lies on a wall plane (wall_inlet.rs), found with the
    /// workspace; `None` without any.
    wall_inlets: Option<wall_inlet::WallInlets>,
}

impl<const D: usize> Incompressible<D> {
    pub(super) fn new(settings: IncompressibleSettings) -> Self {
        Self {
            viscosity: (settings.viscosity == ViscousIntegration::Implicit)
                .then(viscosity::ImplicitViscosity::default),
            capillary: (settings.viscosity == ViscousIntegration::Implicit)
                .then(capillary_first::CapillaryFirst::default),
            air: settings.enclosed_air.map(enclosed_air::EnclosedAir::new),
            navier: navier_slip::NavierDrag::default(),
            source_rhs: Vec::new(),
            source_pressure: Vec::new(),
            last_source_rate: Vec::new(),
            source_solved: false,
            source_volume: Vec::new(),
            balance: volume_source::SourceBalance::default(),
            held: Vec::new(),
            is_held: Vec::new(),
            wall_inlets: None,
            settings,
            stiffness: [[0.0; MAX_CORNERS]; MAX_CORNERS],
            gradient: [[[0.0; MAX_CORNERS]; 3]; MAX_CORNERS],
            corner_offset: [0; MAX_CORNERS],
            cell_mass: Vec::new(),
            cell_volume: Vec::new(),
            cell_node: Vec::new(),
            cell_solid: Vec::new(),
            cell_home: Vec::new(),
            source_cells: volume_source::SourceCells::default(),
            open: Vec::new(),
            free_velocity: Vec::new(),
            inverse_diagonal: Vec::new(),
            lumped_mass: Vec::new(),
            correction: Vec::new(),
            layer: Vec::new(),
            pressure: Vec::new(),
            surface: None,
            rhs: Vec::new(),
            r: Vec::new(),
            z: Vec::new(),
            p: Vec::new(),
            ap: Vec::new(),
        }
    }

    /// Sizes the workspace and the element matrices for `grid` (once).
    fn prepare(
        &mut self,
        grid: &crate::grid::Grid<D>,
        boundaries: &crate::boundary::Boundaries<D>,
        groups: &[crate::particles::MaterialGroup],
        inflows: Option<&inflow::Inflows<D>>,
    ) {
        if self.pressure.len() == grid.len() {
            return;
        }
        let walls: Vec<_> = boundaries.wall_planes().collect();
        self.wall_inlets =
            inflows.and_then(|f| wall_inlet::WallInlets::new(grid, &walls, f.layouts()));
        // Validation lets only one surface tension into a scene (liquids without one
        // count as 0); its liquid's density makes the colour field.
        self.surface = groups
            .iter()
            .find(|g| g.material.surface_tension() > 0.0)
            .map(|g| {
                SurfaceTension::new(
                    g.material.surface_tension(),
                    g.material.density(),
                    boundaries.wall_planes().collect(),
                    boundaries.solid_images(
                        grid,
                        surface_tension::IMAGE_REACH,
                        surface_tension::FOLD_REACH,
                    ),
                )
            });
        let dx = grid.dx;
        let corners = 1 << D;
        // 1D factors on [0, 1]: φ0 = 1 - s, φ1 = s.
        let m1 = |a: usize, b: usize| if a == b { 1.0 / 3.0 } else { 1.0 / 6.0 };
        let k1 = |a: usize, b: usize| if a == b { 1.0 } else { -1.0 };
        let g1 = |_a: usize, b: usize| if b == 1 { 0.5 } else { -0.5 };
        let bit = |a: usize, d: usize| (a >> d) & 1;
        for a in 0..corners {
            self.corner_offset[a] = (0..D).map(|d| bit(a, d) * grid.stride[d]).sum();
            for b in 0..corners {
                let mut k = 0.0;
                for d in 0..D {
                    let mut term = k1(bit(a, d), bit(b, d)) / dx;
                    let mut grad = g1(bit(a, d), bit(b, d));
                    for e in (0..D).filter(|&e| e != d) {
                        term *= dx * m1(bit(a, e), bit(b, e));
                        grad *= dx * m1(bit(a, e), bit(b, e));
                    }
                    k += term;
                    self.gradient[a][d][b] = grad;
                }
                self.stiffness[a][b] = k;
            }
        }
        let cells: usize = grid.cells[..D].iter().product();
        self.cell_mass = vec![0.0; cells];
        self.cell_volume = vec![0.0; cells];
        self.cell_node = (0..cells)
            .map(|c| {
                let mut rest = c;
                let mut node = 0;
                for d in (0..D).rev() {
                    node += (rest % grid.cells[d]) * grid.stride[d];
                    rest /= grid.cells[d];
                }
                node
            })
            .collect();
        self.cell_solid = self
            .cell_node
            .iter()
            .map(|&node| {
                let ijk = node_coords(&grid.stride, node);
                let mut centre = node_position(&grid.origin, grid.dx, ijk);
                for d in 0..D {
                    centre[d] += 0.5 * grid.dx;
                }
                boundaries.cell_is_solid(ijk, &centre)
            })
            .collect();
        self.source_cells =
            volume_source::SourceCells::new(grid, boundaries, &self.cell_node, &self.cell_solid);
        self.cell_home = (0..cells)
            .map(|c| {
                let ijk =
                    boundaries.cell_in_front_of_walls(node_coords(&grid.stride, self.cell_node[c]));
                (0..D).fold(0, |home, d| home * grid.cells[d] + ijk[d])
            })
            .collect();
        self.open = energy_balance::open_fraction(
            grid,
            &self.cell_solid,
            &self.cell_node,
            &self.corner_offset[..corners],
        );
        let n = grid.len();
        self.free_velocity = vec![Vector::<D>::zeros(); n];
        self.correction = vec![Vector::<D>::zeros(); n];
        self.layer = vec![u8::MAX; n];
        self.lumped_mass = vec![0.0; n];
        self.is_held = vec![false; n];
        self.held.clear();
        for v in self.solve_vectors() {
            *v = vec![0.0; n];
        }
    }
}

/// The rows of the particles that move: all but those of groups held in place (solids,
/// `scene::held_bodies`), in row order.
fn moving_rows<const D: usize>(
    particles: &crate::particles::Particles<D>,
) -> impl Iterator<Item = usize> + '_ {
    particles
        .groups
        .iter()
        .filter(|g| !g.held)
        .flat_map(|g| g.range.clone())
}

/// Cell index of a position (clamped into the grid).
#[inline]
fn cell_of<const D: usize>(grid: &crate::grid::Grid<D>, x: &Vector<D>) -> (usize, [f64; 3]) {
    let mut index = 0;
    let mut local = [0.0; 3];
    for d in 0..D {
        let s = (x[d] - grid.origin[d]) * grid.inv_dx;
        let last = grid.cells[d] as f64 - 1.0;
        let c = s.floor().clamp(0.0, last.max(0.0));
        local[d] = (s - c).clamp(0.0, 1.0);
        index = index * grid.cells[d] + c as usize;
    }
    (index, local)
}

impl<const D: usize, K: Kernel> StepMode<D, K> for Incompressible<D>
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        sim.reorder_if_due();
        sim.bins.rebuild::<D, K>(&sim.grid, &sim.particles);
        // With implicit viscosity the liquids' stress is solved for, not scattered.
        let force = if self.viscosity.is_some() {
            ForceTerm::Body
        } else {
            sim.force_term()
        };
        sim.grid.clear();
        sim.p2g(dt, true, force);
        self.grid_velocity(sim, dt);
        // The liquid cells and pressure unknowns of this step, for every stage below: the
        // particles do not move until G2P.
        self.classify_cells(sim);
        self.add_kept_pressure_force(sim, dt);
        self.capillary_first(sim, dt);
        let navier = sim.boundaries.has_navier().then_some(&mut self.navier);
        if let Some(viscosity) = self.viscosity.as_mut() {
            viscosity.solve(sim, &self.settings, dt, &mut self.free_velocity, navier);
            viscosity.take_back(&mut self.free_velocity);
        } else if let Some(navier) = navier {
            navier.apply_explicit(sim, dt, &mut self.free_velocity);
            sim.ledger.viscous += navier.dissipation(&self.free_velocity, dt);
        }
        self.project(sim, dt);
        self.incremental_pressure();
        inflow::park(sim);
        sim.g2p(dt, true, true, true);
        obstacle_guard::put_back(sim, sim.time + dt);
        // The liquid's volume is kept by the projection, not by F: keep F = I so the
        // particle volume stays its reference volume and F cannot degenerate.
        let particles = &mut sim.particles;
        for group in particles.groups.iter().filter(|g| !g.held) {
            particles.deformation_gradient[group.range.clone()].fill(Matrix::<D>::identity());
        }
        inflow::enter(sim, dt);
        outflow::leave(sim);
        sim.advance_physics(dt, true);
        for group in &sim.particles.groups {
            group.material.forget_viscosity_bound();
        }
        sim.update_stresses(dt);
        sim.ledger.viscous += energy_balance::viscous_power(&sim.particles) * dt;
        self.pressure_to_particles(sim);
        sim.ledger.openings += self.pumping_work(sim, dt);
    }

    /// The surface energy at the start: the colour of a P2G of the particles' mass.
    /// With implicit viscosity, the particles' viscosities too (they bound the first step).
    fn measure_stored_energy(&mut self, sim: &mut Simulation<D, K>) {
        self.prepare(
            &sim.grid,
            &sim.boundaries,
            &sim.particles.groups,
            sim.inflow.as_ref(),
        );
        if let Some(viscosity) = self.viscosity.as_mut() {
            viscosity.measure_viscosities(sim);
        }
        let Some(surface) = self.surface.as_mut() else {
            return;
        };
        sim.bins.rebuild::<D, K>(&sim.grid, &sim.particles);
        sim.grid.clear();
        sim.p2g(0.0, true, ForceTerm::Body);
        sim.surface_energy = surface.measure(&sim.grid, &self.open);
    }

    /// The pressure solve is warm-started from the last pressure; a resumed run starts it
    /// cold, so the run that writes the checkpoint does too.
    /// With implicit viscosity the last pressure force is forgotten too (the next step is
    /// a plain projection), as a resumed run does not have it.
    fn save(&mut self, _checkpoint: &mut crate::checkpoint::Checkpoint) {
        self.pressure.iter_mut().for_each(|p| *p = 0.0);
        self.last_source_rate.clear();
        if let Some(viscosity) = self.viscosity.as_mut() {
            viscosity.forget_pressure();
        }
        if let Some(air) = self.air.as_mut() {
            air.forget();
        }
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        convective_step(sim)
            .min(self.liquid_step(sim))
            .min(sim.physics_dt)
    }
}

/// Velocity CFL step before `cfl`, with the speed gravity adds within one step so that a
/// liquid at rest does not get an unbounded step: dx / (|v|max + √(dx·|g|) + v_inlet),
/// where v_inlet is the most a pressure inlet may add (pressure_inlet.rs).
fn convective_step<const D: usize, K: Kernel>(sim: &Simulation<D, K>) -> f64 {
    let dx = sim.grid.dx;
    let g = sim.settings.gravity.norm();
    let inlet = sim.inflow.as_ref().map_or(0.0, |f| {
        f.drives()
            .map(|(layout, drive)| drive.added_speed(layout, sim.time, dx))
            .fold(0.0, f64::max)
    });
    dx / (sim.kinematics.max_speed + (dx * g).sqrt() + inlet).max(1e-300)
}

impl<const D: usize> Incompressible<D> {
    /// Writes σκ on the free-surface nodes into `pressure` (surface_tension.rs); nothing
    /// without surface tension. The liquid behind pressure inlets is no void (its face is no
    /// free surface).
    fn surface_pressure<K: Kernel>(&mut self, sim: &Simulation<D, K>) {
        let Some(surface) = self.surface.as_mut() else {
            return;
        };
        if let Some(inflows) = &sim.inflow {
            pressure_inlet::reservoir_nodes(
                inflows.drives(),
                &sim.grid,
                sim.time,
                &mut surface.reservoir,
            );
        }
        let liquid_cells = self
            .cell_volume
            .iter()
            .zip(&self.cell_node)
            .filter(|(v, _)| **v > 0.0)
            .map(|(_, &node)| node);
        surface.surface_pressure(
            &sim.grid,
            liquid_cells,
            &self.corner_offset[..1 << D],
            &self.inverse_diagonal,
            &mut self.pressure,
        );
    }

    /// The liquid's own step bounds before `cfl`: the explicit viscous limit ρdx²/(2Dμ)
    /// (explicit viscosity only) and the capillary one (surface_tension.rs), which with
    /// implicit viscosity grows with each liquid's least viscosity at the last solve.
    fn liquid_step<K: Kernel>(&self, sim: &Simulation<D, K>) -> f64 {
        let dx = sim.grid.dx;
        let mut viscous = f64::INFINITY;
        let explicit = self.viscosity.is_none();
        for group in sim.particles.groups.iter().filter(|_| explicit) {
            let mu = group.material.liquid_viscosity().unwrap_or(0.0);
            if mu > 0.0 {
                let rho = group.material.density();
                viscous = viscous.min(rho * dx * dx / (2.0 * D as f64 * mu));
            }
        }
        let capillary = sim
            .particles
            .groups
            .iter()
            .enumerate()
            .map(|(k, g)| {
                let mu = self
                    .viscosity
                    .as_ref()
                    .map_or(0.0, |v| v.least_viscosity(k));
                let (sigma, rho) = (g.material.surface_tension(), g.material.density());
                surface_tension::stable_dt(sigma, rho, mu, dx)
            })
            .fold(f64::INFINITY, f64::min);
        viscous.min(capillary)
    }

    /// Turns nodal momentum into velocity with the explicit forces (as the explicit grid
    /// update does) and keeps it before the walls and obstacles act: the projection
    /// corrects that velocity, so a wall's reaction to gravity and to the pressure
    /// balance (a liquid at rest on a floor stays at rest), and only then do the walls
    /// act again.
    fn grid_velocity<K: Kernel>(&mut self, sim: &mut Simulation<D, K>, dt: f64)
    where
        dyn Material: DimensionDispatch<D>,
    {
        self.prepare(
            &sim.grid,
            &sim.boundaries,
            &sim.particles.groups,
            sim.inflow.as_ref(),
        );
        let params = GridParams {
            dt,
            forces: true,
            flip: sim.settings.transfer == Transfer::Flip,
            damping: sim.settings.damping,
            time: sim.time + dt,
        };
        sim.boundaries.fold_stick_walls(&mut sim.grid);
        update_grid(&mut sim.grid, &Boundaries::default(), params);
        self.free_velocity.copy_from_slice(&sim.grid.momentum);
        // The velocity the projection starts from is `free_velocity`: what the inlets add
        // here is booked after the projection.
        self.walls_act(sim, dt);
    }

    /// Walls and obstacles on the nodal velocity at the end of the step of length `dt`,
    /// then the wall inlets' entry speed on their nodes (wall_inlet.rs). Returns the
    /// kinetic energy the inlets' speed added.
    fn walls_act<K: Kernel>(&self, sim: &mut Simulation<D, K>, dt: f64) -> f64
    where
        dyn Material: DimensionDispatch<D>,
    {
        apply_boundaries(sim, sim.time + dt);
        self.wall_inlets
            .as_ref()
            .map_or(0.0, |inlets| inlets.impose(&mut sim.grid, sim.time, dt))
    }
}

/// Walls and obstacles on the nodal velocity (with the stick walls' mirrored ghosts).
fn apply_boundaries<const D: usize, K: Kernel>(sim: &mut Simulation<D, K>, time: f64)
where
    dyn Material: DimensionDispatch<D>,
{
    if sim.boundaries.is_empty() {
        return;
    }
    let (origin, dx, stride) = (sim.grid.origin, sim.grid.dx, sim.grid.stride);
    for i in 0..sim.grid.len() {
        let m = sim.grid.mass[i];
        if m <= 0.0 {
            continue;
        }
        let ijk = node_coords(&stride, i);
        let x = node_position(&origin, dx, ijk);
        let mut v = sim.grid.momentum[i];
        sim.boundaries.apply(ijk, &x, time, m, &mut v);
        sim.grid.momentum[i] = v;
    }
    sim.boundaries.mirror_stick_walls(&mut sim.grid);
}
