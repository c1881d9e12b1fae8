//! Particle–grid transfers over stencils built ahead (any number of entries per particle,
//! with compact rows): P2G is a gather over each node's entries through the stencil's
//! transpose, so no two threads write one node and the sums come out the same whatever the
//! thread count. The total Lagrangian mode (stencils at the reference, built once) and CPDI
//! (stencils through each particle's deformed domain, built every step) share them.

use super::DimensionDispatch;
use super::parallel::{SharedSlice, chunk_count, chunk_range, ordered_reduce};
use super::simulation::Simulation;
use super::stage_clock::StepStage;
use super::stats::{KinematicStats, ParticleFault};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector, inverse};
use crate::physics::Interpolation;
use crate::scene::Transfer;
use rayon::prelude::*;
use std::time::Instant;

/// Grid rows per task of the P2G gather.
const ROW_CHUNK: usize = 1024;

/// Where the stencils live, which sets APIC's offsets, how F grows and what stops a run.
#[derive(Clone, Copy)]
pub(super) enum Frame<'a, const D: usize> {
    /// Total Lagrangian: offsets from the reference positions, Ḟ = (Σ vᵢ ⊗ ∇₀wᵢ)·F₀, and a
    /// particle a cell past a wall plane (axis, upper side, coordinate) or whose reference
    /// stencil leaves the grid stops the run.
    Reference {
        position: &'a [Vector<D>],
        start_f: &'a [Matrix<D>],
        walls: &'a [(usize, bool, f64)],
    },
    /// Updated Lagrangian with particle domains (CPDI): offsets from the current positions,
    /// Ḟ = (Σ vᵢ ⊗ ∇wᵢ)·F, and a particle whose deformed domain leaves the grid stops the run.
    Domains,
}

/// Stencils with compact rows, their transpose and what the transfers need per particle.
#[derive(Default)]
pub(super) struct GatherStencils<const D: usize> {
    /// Every particle's stencil entries (rows are compact: `stencil.rows` maps them to nodes).
    pub stencil: Interpolation<D>,
    /// The stencil's transpose: the entries of row `r` are
    /// `row_entries[row_start[r]..row_start[r + 1]]`, in particle order.
    row_start: Vec<u32>,
    row_entries: Vec<u32>,
    /// The counting sort's scratch (kept so a rebuild every step allocates nothing).
    cursor: Vec<u32>,
    /// APIC's inverse inertia D⁻¹ per particle (empty without APIC).
    inverse_inertia: Vec<Matrix<D>>,
    /// The position of each row's node, for APIC's offsets (empty without APIC).
    row_position: Vec<Vector<D>>,
    /// This step's force matrix per particle: the internal force on a node is −Σ of it
    /// times the entry's weight gradient.
    pub force_matrix: Vec<Matrix<D>>,
}

impl<const D: usize> GatherStencils<D> {
    /// After `stencil` is built: its transpose and, with APIC, the rows' positions and each
    /// particle's inverse inertia about `anchor` (its position in the stencils' frame).
    pub fn index<K: Kernel>(&mut self, sim: &Simulation<D, K>, anchor: &[Vector<D>]) {
        let s = &self.stencil;
        let rows = s.rows.len();
        self.row_start.clear();
        self.row_start.resize(rows + 1, 0);
        for &r in &s.node {
            self.row_start[r as usize + 1] += 1;
        }
        for r in 0..rows {
            self.row_start[r + 1] += self.row_start[r];
        }
        // Counting sort: each row's entries in ascending entry (particle) order.
        self.row_entries.resize(s.node.len(), 0);
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.row_start[..rows]);
        for (e, &r) in s.node.iter().enumerate() {
            self.row_entries[self.cursor[r as usize] as usize] = e as u32;
            self.cursor[r as usize] += 1;
        }
        self.row_position.clear();
        self.inverse_inertia.clear();
        if sim.settings.transfer == Transfer::Apic {
            let grid = &sim.grid;
            self.row_position.extend(
                s.rows
                    .iter()
                    .map(|&i| grid.position(grid.coords(i as usize))),
            );
            let row_position = &self.row_position;
            (0..anchor.len())
                .into_par_iter()
                .map(|p| {
                    let mut inertia = Matrix::<D>::zeros();
                    for e in s.entries(p) {
                        let offset = row_position[s.node[e] as usize] - anchor[p];
                        inertia += (offset * s.weight[e]) * offset.transpose();
                    }
                    inverse(&inertia).unwrap_or_else(Matrix::<D>::zeros)
                })
                .collect_into_vec(&mut self.inverse_inertia);
        }
        self.force_matrix.resize(anchor.len(), Matrix::<D>::zeros());
    }

    /// Gathers mass, momentum and (with `forces`) force at every reached node from its
    /// stencil entries; writes the grid's arrays as the explicit P2G leaves them.
    pub fn p2g<K: Kernel>(
        &self,
        sim: &mut Simulation<D, K>,
        frame: Frame<'_, D>,
        dt: f64,
        forces: bool,
    ) where
        dyn Material: DimensionDispatch<D>,
    {
        let start = Instant::now();
        let apart = sim.forces_apart();
        let gravity = sim.settings.gravity;
        let apic = !self.inverse_inertia.is_empty();
        let s = &self.stencil;
        let stencil_len = s.stencil;
        let particles = &sim.particles;
        let loads = (!particles.external_force.is_empty()).then_some(&particles.external_force);
        let anchor = match frame {
            Frame::Reference { position, .. } => position,
            Frame::Domains => &particles.position[..],
        };
        let grid = &mut sim.grid;
        let rows = s.rows.len();
        for &i in &s.rows {
            grid.mark(i as usize..i as usize + 1);
        }
        let mass_out = SharedSlice::new(&mut grid.mass);
        let momentum_out = SharedSlice::new(&mut grid.momentum);
        let force_out = SharedSlice::new(&mut grid.force);
        (0..rows.div_ceil(ROW_CHUNK))
            .into_par_iter()
            .for_each(|chunk| {
                for r in chunk * ROW_CHUNK..((chunk + 1) * ROW_CHUNK).min(rows) {
                    let i = s.rows[r] as usize;
                    let (mut m, mut momentum, mut force) =
                        (0.0, Vector::<D>::zeros(), Vector::<D>::zeros());
                    let mut load = Vector::<D>::zeros();
                    let entries = &self.row_entries
                        [self.row_start[r] as usize..self.row_start[r + 1] as usize];
                    for &e in entries {
                        let e = e as usize;
                        let p = e / stencil_len;
                        let (w, mp) = (s.weight[e], particles.mass[p]);
                        m += w * mp;
                        let mut v = particles.velocity[p];
                        if apic {
                            v += particles.affine[p] * (self.row_position[r] - anchor[p]);
                        }
                        momentum += v * (w * mp);
                        if forces {
                            force -= self.force_matrix[p] * s.gradient[e];
                            if let Some(loads) = loads {
                                load += loads[p] * w;
                            }
                        }
                    }
                    // SAFETY: every row is one grid node, and each row is in one chunk.
                    unsafe {
                        if forces {
                            force += gravity * m;
                            if loads.is_some() {
                                force += load;
                            }
                            *mass_out.get(i) = m;
                            if apart {
                                *momentum_out.get(i) = momentum;
                                *force_out.get(i) = force;
                            } else {
                                *momentum_out.get(i) = momentum + force * dt;
                            }
                        } else {
                            *momentum_out.get(i) = momentum;
                        }
                    }
                }
            });
        sim.clock.add(StepStage::P2g, start);
    }

    /// Gathers the grid velocities to the particles: with `velocity` their velocities (PIC,
    /// FLIP blend or APIC), with `moves` their positions (and the checks that stop a run),
    /// with `deformation` F from the frame's Ḟ.
    pub fn g2p<K: Kernel>(
        &self,
        sim: &mut Simulation<D, K>,
        frame: Frame<'_, D>,
        dt: f64,
        velocity: bool,
        moves: bool,
        deformation: bool,
    ) where
        dyn Material: DimensionDispatch<D>,
    {
        let start = Instant::now();
        let transfer = sim.settings.transfer;
        let flip_blend = sim.settings.flip_blend;
        let gravity = sim.settings.gravity;
        let flip = transfer == Transfer::Flip && velocity;
        let apic = transfer == Transfer::Apic && velocity;
        let s = &self.stencil;
        let grid = &sim.grid;
        let store_gradient = !sim.particles.velocity_gradient.is_empty();
        let p = &mut sim.particles;
        let n = p.len();
        let position = SharedSlice::new(&mut p.position);
        let vel = SharedSlice::new(&mut p.velocity);
        let def = SharedSlice::new(&mut p.deformation_gradient);
        let affine = SharedSlice::new(&mut p.affine);
        let gradient_out = SharedSlice::new(&mut p.velocity_gradient);
        let (mass, half_size) = (&p.mass, &p.half_size);
        let loads = (!p.external_force.is_empty()).then_some(&p.external_force);
        let stats = ordered_reduce(
            chunk_count(n),
            KinematicStats::<D>::default,
            |chunk| {
                let mut stats = KinematicStats::<D>::default();
                for k in chunk_range(chunk, n) {
                    // SAFETY: chunks are disjoint particle ranges.
                    let (x, v, f) = unsafe { (position.get(k), vel.get(k), def.get(k)) };
                    let anchor = match frame {
                        Frame::Reference { position, .. } => position[k],
                        Frame::Domains => *x,
                    };
                    let (mut v_new, mut change) = (Vector::<D>::zeros(), Vector::<D>::zeros());
                    let (mut b, mut grad) = (Matrix::<D>::zeros(), Matrix::<D>::zeros());
                    for e in s.entries(k) {
                        let row = s.node[e] as usize;
                        let i = s.grid_node(row);
                        let (w, vi) = (s.weight[e], grid.momentum[i]);
                        v_new += vi * w;
                        if flip {
                            change += (vi - grid.velocity_old[i]) * w;
                        }
                        if apic {
                            b += (vi * w) * (self.row_position[row] - anchor).transpose();
                        }
                        if deformation {
                            grad += vi * s.gradient[e].transpose();
                        }
                    }
                    if velocity {
                        *v = match transfer {
                            Transfer::Flip => {
                                (*v + change) * flip_blend + v_new * (1.0 - flip_blend)
                            }
                            _ => v_new,
                        };
                        if apic {
                            // SAFETY: as above.
                            unsafe { *affine.get(k) = b * self.inverse_inertia[k] };
                        }
                    }
                    if moves {
                        *x += v_new * dt;
                    }
                    if deformation {
                        let rate = match frame {
                            Frame::Reference { start_f, .. } => grad * start_f[k],
                            Frame::Domains => grad * *f,
                        };
                        if store_gradient {
                            let l = match frame {
                                Frame::Reference { .. } => {
                                    inverse(f).map_or(Matrix::<D>::zeros(), |fi| rate * fi)
                                }
                                Frame::Domains => grad,
                            };
                            // SAFETY: as above.
                            unsafe { *gradient_out.get(k) = l };
                        }
                        *f += rate * dt;
                    }
                    stats.record(k, mass[k], v, x, f, (&gravity, loads.map(|l| &l[k])));
                    if moves && stats.escaped.is_none() {
                        stats.escaped = escape::<D, K>(frame, grid, k, x, f, half_size);
                    }
                }
                stats.max_speed = stats.max_speed.sqrt();
                stats
            },
            KinematicStats::merge,
        );
        sim.clock.add(StepStage::G2p, start);
        sim.take_kinematics(stats, velocity);
    }
}

/// Why particle `k` at `x` with deformation `f` stops the run, if it does: past a wall or
/// off the grid in the reference frame, its domain off the grid with domains.
fn escape<const D: usize, K: Kernel>(
    frame: Frame<'_, D>,
    grid: &crate::grid::Grid<D>,
    k: usize,
    x: &Vector<D>,
    f: &Matrix<D>,
    half_size: &[f64],
) -> Option<ParticleFault> {
    let (through, fits) = match frame {
        Frame::Reference { walls, .. } => {
            let through = walls.iter().any(|&(axis, upper, beyond)| {
                if upper {
                    x[axis] > beyond
                } else {
                    x[axis] < beyond
                }
            });
            let half = if K::USES_PARTICLE_SIZE {
                half_size[k]
            } else {
                0.0
            };
            (through, super::stencil::stencil_fits::<D, K>(grid, x, half))
        }
        Frame::Domains => (
            false,
            super::cpdi_stencils::domain_fits(grid, x, f, half_size[k]),
        ),
    };
    (through || !fits).then(|| ParticleFault {
        particle: k,
        field: if through { "wall" } else { "x" },
        value: x.norm(),
    })
}
