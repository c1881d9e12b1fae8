//! Navier slip on walls and obstacles (`"condition": {"navier": {"slip_length": b}}`): across
//! the surface it is slip; along it the liquid feels the drag τ = −(μ/b)·(v − V)_t, V the
//! surface's velocity, so at rest against the viscous stress it slides with
//! v_t = b·∂v_t/∂n (Navier 1823). It lets a contact line move on a scale the scene sets
//! instead of by the grid's own slip, which a `stick` surface leaves (the fill rate of a
//! gap with stick plates depended on the step).
//!
//! The drag acts on the nodes `Boundaries::navier_surfaces` names, each standing for an
//! area A = dx^(D−1) of the surface: the node's coefficient is C_i = μ_i·A/b, with μ_i the
//! viscosity of the liquid particles around it weighted by w_ip·m_p. It acts on the velocity
//! before the projection, as the viscous stress does:
//! - with implicit viscosity inside the viscous solve, as a term C_i·(v_i − V) of the
//!   operator on the node's tangential components (a Robin condition; the operator stays
//!   symmetric positive definite);
//! - with explicit viscosity by itself, backward Euler on each node:
//!   (v − V)_t ← (v − V)_t / (1 + dt·C_i/M_i).
//!
//! The work it takes, Σ_i C_i·|(v_i − V)_t|²·dt at the velocity it left, is booked as viscous
//! dissipation.

use super::super::interpolation::build_interpolation;
use super::super::simulation::Simulation;
use super::viscosity::particle_viscosities;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::Vector;
use crate::physics::Interpolation;
use crate::solver::DimensionDispatch;

/// One node's share of one Navier surface.
#[derive(Clone, Copy, Debug)]
struct DragNode<const D: usize> {
    node: u32,
    /// Index of the node in `DragNodes::sums`.
    slot: u32,
    /// A/b, m^(D−2): the area the node stands for over the slip length.
    area_over_length: f64,
    /// The drag coefficient C = μ·A/b, N·s/m (N·s/m² in 2D).
    coefficient: f64,
    normal: Vector<D>,
    surface_velocity: Vector<D>,
}

/// The Navier surfaces' drag on the grid nodes, rebuilt every step (surfaces may move).
#[derive(Default)]
pub(super) struct NavierDrag<const D: usize> {
    found: DragNodes<D>,
    /// Each particle's viscosity (explicit viscosity; the implicit solve has its own).
    viscosity: Vec<f64>,
    least: Vec<f64>,
    /// The particles' stencils (explicit viscosity; the implicit solve has its own).
    interp: Interpolation<D>,
}

/// The nodes with drag this step and what finding their viscosity needs.
#[derive(Default)]
struct DragNodes<const D: usize> {
    nodes: Vec<DragNode<D>>,
    /// Per grid node: 1 + its slot in `sums`, or 0 for a node without drag.
    slot: Vec<u32>,
    /// Per node with drag: Σ_p w_ip m_p μ_p and Σ_p w_ip m_p over the liquid particles.
    sums: Vec<[f64; 2]>,
}

impl<const D: usize> DragNodes<D> {
    /// Finds the nodes with drag at `time` and their coefficients from the particles'
    /// stencils `interp` and viscosities `viscosity(p)` (Pa·s; 0 for solids).
    fn update<K: Kernel>(
        &mut self,
        sim: &Simulation<D, K>,
        time: f64,
        interp: &Interpolation<D>,
        viscosity: impl Fn(usize) -> f64,
    ) where
        dyn Material: DimensionDispatch<D>,
    {
        let grid = &sim.grid;
        if self.slot.len() != grid.len() {
            self.slot = vec![0; grid.len()];
        }
        for d in &self.nodes {
            self.slot[d.node as usize] = 0;
        }
        self.nodes.clear();
        self.sums.clear();
        let area = grid.dx.powi(D as i32 - 1);
        for (i, &m) in grid.mass.iter().enumerate() {
            if m <= 0.0 {
                continue;
            }
            let ijk = grid.coords(i);
            let x = grid.position(ijk);
            let (nodes, slots, sums) = (&mut self.nodes, &mut self.slot, &mut self.sums);
            sim.boundaries.navier_surfaces(
                ijk,
                &x,
                time,
                grid.dx,
                |normal, b, surface_velocity| {
                    if slots[i] == 0 {
                        sums.push([0.0; 2]);
                        slots[i] = sums.len() as u32;
                    }
                    nodes.push(DragNode {
                        node: i as u32,
                        slot: slots[i] - 1,
                        area_over_length: area / b,
                        coefficient: 0.0,
                        normal,
                        surface_velocity,
                    });
                },
            );
        }
        if self.nodes.is_empty() {
            return;
        }
        let particles = &sim.particles;
        for p in 0..particles.len() {
            let mu = viscosity(p);
            if mu <= 0.0 {
                continue;
            }
            let m = particles.mass[p];
            for e in interp.entries(p) {
                let slot = self.slot[interp.node[e] as usize];
                if slot > 0 {
                    let wm = interp.weight[e] * m;
                    let sum = &mut self.sums[slot as usize - 1];
                    sum[0] += wm * mu;
                    sum[1] += wm;
                }
            }
        }
        for d in &mut self.nodes {
            let [weighted, weight] = self.sums[d.slot as usize];
            let mu = if weight > 0.0 { weighted / weight } else { 0.0 };
            d.coefficient = mu * d.area_over_length;
        }
    }
}

impl<const D: usize> NavierDrag<D> {
    /// With implicit viscosity: finds the drag for the solve (`interp`, the particles'
    /// stencils, and `coefficient`, their 2·μ_p·V_p) and lists each node with drag once in
    /// `drag`, with its C_i (the surfaces' on it summed).
    pub(super) fn for_implicit_solve<K: Kernel>(
        &mut self,
        sim: &Simulation<D, K>,
        time: f64,
        interp: &Interpolation<D>,
        coefficient: &[f64],
        drag: &mut Vec<(u32, f64)>,
    ) where
        dyn Material: DimensionDispatch<D>,
    {
        let particles = &sim.particles;
        self.found.update(sim, time, interp, |p| {
            let volume =
                particles.volume0[p] * crate::math::determinant(&particles.deformation_gradient[p]);
            if volume > 0.0 {
                coefficient[p] / (2.0 * volume)
            } else {
                0.0
            }
        });
        drag.clear();
        // A node's surfaces are found one after another (a corner has two).
        for d in &self.found.nodes {
            match drag.last_mut() {
                Some((node, c)) if *node == d.node => *c += d.coefficient,
                _ => drag.push((d.node, d.coefficient)),
            }
        }
    }

    /// The surfaces' share of the implicit solve's right-hand side: adds C_i·V to each
    /// node's components in `rhs` (D numbers per node).
    pub(super) fn add_surface_velocity(&self, rhs: &mut [f64]) {
        for d in &self.found.nodes {
            let k = d.node as usize * D;
            for c in 0..D {
                rhs[k + c] += d.coefficient * d.surface_velocity[c];
            }
        }
    }

    /// With explicit viscosity: the drag on `velocity` (the grid velocity before the
    /// walls) over the step `dt`, backward Euler node by node.
    pub(super) fn apply_explicit<K: Kernel>(
        &mut self,
        sim: &Simulation<D, K>,
        dt: f64,
        velocity: &mut [Vector<D>],
    ) where
        dyn Material: DimensionDispatch<D>,
    {
        build_interpolation::<D, K>(&sim.grid, &sim.particles, &mut self.interp);
        particle_viscosities(&sim.particles, &mut self.viscosity, &mut self.least);
        let viscosity = &self.viscosity;
        self.found.update(sim, sim.time + dt, &self.interp, |p| {
            let mu = viscosity[p];
            if mu.is_finite() { mu } else { 0.0 }
        });
        for d in &self.found.nodes {
            let i = d.node as usize;
            let m = sim.grid.mass[i];
            let relative = velocity[i] - d.surface_velocity;
            let across = d.normal * d.normal.dot(&relative);
            let along = (relative - across) / (1.0 + dt * d.coefficient / m);
            velocity[i] = d.surface_velocity + across + along;
        }
    }

    /// The work the drag took over a step `dt` at the nodal `velocity` it left:
    /// Σ C_i·|(v_i − V)_t|²·dt, J (J/m in 2D).
    pub(super) fn dissipation(&self, velocity: &[Vector<D>], dt: f64) -> f64 {
        self.found
            .nodes
            .iter()
            .map(|d| {
                let relative = velocity[d.node as usize] - d.surface_velocity;
                let along = relative - d.normal * d.normal.dot(&relative);
                d.coefficient * along.norm_squared() * dt
            })
            .sum()
    }
}
