//! Total Lagrangian MPM (TLMPM; de Vaucorbeil, Nguyen, Sinaie & Wu 2020, "Material point
//! method after 25 years" and the TLMPM paper in CMAME 360): the grid is the reference
//! configuration, so every particle keeps the stencil it had when the mode started. Its
//! weights and their gradients with respect to the reference position X are computed once;
//! the internal force is −Σ V₀ P ∇₀w with the first Piola–Kirchhoff stress P = Jσ F⁻ᵀ, and
//! the deformation gradient grows as Ḟ = Σ vᵢ ⊗ ∇₀wᵢ. No particle crosses a cell, so there
//! is no cell-crossing noise and no numerical fracture: a bar stretched to several times its
//! length stays whole. The price: the body cannot meet another body or an obstacle (both
//! act in the current configuration) and walls hold the material that started at them.
//!
//! A stage that starts in this mode takes the positions and F it starts from as its
//! reference: X₀ and F₀, with F = F_rel·F₀, so P₀ = J σ (F₀F⁻¹)ᵀ and Ḟ = (Σ vᵢ ⊗ ∇₀wᵢ)·F₀.
//! P2G is a gather over each node's stencil entries (the transpose, built once), so no two
//! threads write one node and the sums come out the same whatever the thread count.

use super::DimensionDispatch;
use super::interpolation::build_compact_interpolation;
use super::mode::StepMode;
use super::parallel::{SharedSlice, chunk_count, chunk_range, ordered_reduce};
use super::simulation::Simulation;
use super::stage_clock::StepStage;
use super::stats::{KinematicStats, ParticleFault};
use super::stencil::stencil_fits;
use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector, determinant, inverse};
use crate::physics::Interpolation;
use crate::scene::{Scheme, Transfer};
use rayon::prelude::*;
use std::time::Instant;

/// Grid rows per task of the P2G gather.
const ROW_CHUNK: usize = 1024;

/// The total Lagrangian mode's state: the reference configuration and its stencils.
#[derive(Default)]
pub(super) struct TotalLagrangian<const D: usize> {
    /// Positions at the mode's start (the reference configuration), particle order.
    reference: Vec<Vector<D>>,
    /// F at the mode's start (the identity for a run that starts in this mode).
    start_f: Vec<Matrix<D>>,
    /// Every particle's stencil at its reference position, with compact rows; empty until
    /// the first step (and after a resume, rebuilt from `reference`).
    stencil: Interpolation<D>,
    /// The stencil's transpose: the entries of row `r` are
    /// `row_entries[row_start[r]..row_start[r + 1]]`, in particle order.
    row_start: Vec<u32>,
    row_entries: Vec<u32>,
    /// APIC's inverse inertia D⁻¹ per particle in the reference configuration (empty
    /// without APIC).
    inverse_inertia: Vec<Matrix<D>>,
    /// This step's V₀ J σ (F₀F⁻¹)ᵀ per particle: the force is −Σ of it times ∇₀w.
    force_matrix: Vec<Matrix<D>>,
    /// Each wall's axis, side and the coordinate a cell behind its plane: a particle past
    /// it went through the wall (a wall holds only the material that starts at it).
    walls: Vec<(usize, bool, f64)>,
    /// Largest 1/σ_min(F_rel) over the particles after the last stress update: the most
    /// compressed direction, where a wave crosses a reference cell fastest.
    inverse_stretch: f64,
}

impl<const D: usize, K: Kernel> StepMode<D, K> for TotalLagrangian<D>
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        if self.reference.len() != sim.particles.len() {
            // The mode's first step (or particles were removed since the reference was
            // taken): the reference is where the particles are now.
            self.reference = sim.particles.position.clone();
            self.start_f = sim.particles.deformation_gradient.clone();
            self.stencil = Interpolation::default();
        }
        if self.stencil.node.is_empty() && !self.reference.is_empty() {
            self.build_stencils::<K>(sim);
        }
        self.stress_to_force(sim);
        sim.grid.clear();
        self.p2g(sim, dt, true);
        sim.grid_update(dt, true);
        match sim.settings.scheme {
            Scheme::Musl => {
                // The paper's scheme: the new particle velocities mapped back give the
                // velocity field F grows with.
                self.g2p(sim, dt, true, false);
                sim.grid.clear_momentum();
                self.p2g(sim, dt, false);
                sim.grid_update(dt, false);
                self.g2p(sim, dt, false, true);
            }
            // Validation refuses USF with this mode.
            _ => self.g2p(sim, dt, true, true),
        }
        sim.update_stresses(dt);
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        let wave = sim.stresses.batch.max_wave_speed * self.inverse_stretch.max(1.0);
        let mechanical = if wave > 0.0 {
            sim.grid.dx / wave
        } else {
            f64::INFINITY
        };
        mechanical.min(sim.physics_dt)
    }

    fn save(&mut self, c: &mut Checkpoint) {
        let flat = |m: &[Matrix<D>]| m.iter().flat_map(|a| a.iter().copied()).collect();
        c.put("total_lagrangian.count", vec![self.reference.len() as f64]);
        c.put(
            "total_lagrangian.reference",
            self.reference
                .iter()
                .flat_map(|x| x.iter().copied())
                .collect(),
        );
        c.put("total_lagrangian.start_f", flat(&self.start_f));
        c.put(
            "total_lagrangian.inverse_stretch",
            vec![self.inverse_stretch],
        );
    }

    fn take_over(&mut self, sim: &Simulation<D, K>, c: &Checkpoint) {
        // A total Lagrangian stage after another keeps its reference configuration, unless
        // particles were removed between them (then this stage starts from where they are:
        // `advance` checks the count again).
        let n = sim.particles.len();
        if c.get("total_lagrangian.count", 1)
            .ok()
            .map(|k| k[0] as usize)
            == Some(n)
        {
            let _ = StepMode::<D, K>::restore(self, c);
        }
    }

    fn restore(&mut self, c: &Checkpoint) -> Result<(), CheckpointError> {
        let n = c.get("total_lagrangian.count", 1)?[0] as usize;
        let x = c.get("total_lagrangian.reference", n * D)?;
        self.reference = x
            .chunks_exact(D)
            .map(crate::math::vector_from_slice)
            .collect();
        let f = c.get("total_lagrangian.start_f", n * D * D)?;
        self.start_f = f
            .chunks_exact(D * D)
            .map(Matrix::<D>::from_column_slice)
            .collect();
        self.inverse_stretch = c.get("total_lagrangian.inverse_stretch", 1)?[0];
        // The stencils are rebuilt from the reference at the next step.
        self.stencil = Interpolation::default();
        Ok(())
    }
}

impl<const D: usize> TotalLagrangian<D> {
    /// The stencils at the reference positions, their transpose and APIC's inertia.
    fn build_stencils<K: Kernel>(&mut self, sim: &mut Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let start = Instant::now();
        // The stencil builder reads the particles' positions: lend it the reference.
        std::mem::swap(&mut sim.particles.position, &mut self.reference);
        build_compact_interpolation::<D, K>(&sim.grid, &sim.particles, &mut self.stencil);
        std::mem::swap(&mut sim.particles.position, &mut self.reference);
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
        let mut next: Vec<u32> = self.row_start[..rows].to_vec();
        self.row_entries.clear();
        self.row_entries.resize(s.node.len(), 0);
        for (e, &r) in s.node.iter().enumerate() {
            self.row_entries[next[r as usize] as usize] = e as u32;
            next[r as usize] += 1;
        }
        self.inverse_inertia.clear();
        if sim.settings.transfer == Transfer::Apic {
            let grid = &sim.grid;
            self.inverse_inertia = (0..self.reference.len())
                .map(|p| {
                    let mut inertia = Matrix::<D>::zeros();
                    for e in s.entries(p) {
                        let offset = self.node_position(grid, e) - self.reference[p];
                        inertia += (offset * s.weight[e]) * offset.transpose();
                    }
                    inverse(&inertia).unwrap_or_else(Matrix::<D>::zeros)
                })
                .collect();
        }
        self.force_matrix
            .resize(self.reference.len(), Matrix::<D>::zeros());
        let grid = &sim.grid;
        self.walls = sim
            .boundaries
            .wall_planes()
            .map(|w| {
                let plane = grid.origin[w.axis] + w.surface as f64 * grid.dx;
                let beyond = if w.upper {
                    plane + grid.dx
                } else {
                    plane - grid.dx
                };
                (w.axis, w.upper, beyond)
            })
            .collect();
        sim.clock.add(StepStage::Bin, start);
    }

    /// The grid position of stencil entry `e`'s node.
    #[inline(always)]
    fn node_position(&self, grid: &crate::grid::Grid<D>, e: usize) -> Vector<D> {
        let i = self.stencil.grid_node(self.stencil.node[e] as usize);
        grid.position(grid.coords(i))
    }

    /// Each particle's V₀ J σ (F₀F⁻¹)ᵀ for this step's force, and the largest inverse
    /// stretch of F_rel = F F₀⁻¹ for the next step's bound.
    fn stress_to_force<K: Kernel>(&mut self, sim: &mut Simulation<D, K>) {
        let start = Instant::now();
        let p = &sim.particles;
        let start_f = &self.start_f;
        let inverse_stretch = self
            .force_matrix
            .par_iter_mut()
            .enumerate()
            .map(|(k, a)| {
                let f = &p.deformation_gradient[k];
                let j = determinant(f);
                let Some(f_inv) = inverse(f) else {
                    *a = Matrix::<D>::zeros();
                    return f64::INFINITY;
                };
                let rel_inv = start_f[k] * f_inv;
                *a = p.stress[k] * rel_inv.transpose() * (p.volume0[k] * j);
                largest_singular_value_bound(&rel_inv)
            })
            .reduce(|| 0.0, f64::max);
        self.inverse_stretch = inverse_stretch;
        sim.clock.add(StepStage::Stress, start);
    }

    /// Gathers mass, momentum and (with `forces`) force at every reached node from its
    /// stencil entries; writes the grid's arrays as the explicit P2G leaves them.
    fn p2g<K: Kernel>(&self, sim: &mut Simulation<D, K>, dt: f64, forces: bool)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let start = Instant::now();
        let apart = sim.forces_apart();
        let gravity = sim.settings.gravity;
        let apic = !self.inverse_inertia.is_empty();
        let s = &self.stencil;
        let stencil_len = s.stencil;
        let particles = &sim.particles;
        let grid = &mut sim.grid;
        let (origin, dx, stride) = (grid.origin, grid.dx, grid.stride);
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
                    let xi = crate::grid::node_position(
                        &origin,
                        dx,
                        crate::grid::node_coords(&stride, i),
                    );
                    let (mut m, mut momentum, mut force) =
                        (0.0, Vector::<D>::zeros(), Vector::<D>::zeros());
                    let entries = &self.row_entries
                        [self.row_start[r] as usize..self.row_start[r + 1] as usize];
                    for &e in entries {
                        let e = e as usize;
                        let p = e / stencil_len;
                        let (w, mp) = (s.weight[e], particles.mass[p]);
                        m += w * mp;
                        let mut v = particles.velocity[p];
                        if apic {
                            v += particles.affine[p] * (xi - self.reference[p]);
                        }
                        momentum += v * (w * mp);
                        if forces {
                            force -= self.force_matrix[p] * s.gradient[e];
                        }
                    }
                    // SAFETY: every row is one grid node, and each row is in one chunk.
                    unsafe {
                        if forces {
                            force += gravity * m;
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
    /// FLIP blend or APIC) and positions, with `deformation` F from Ḟ = (Σ vᵢ ⊗ ∇₀wᵢ)F₀.
    fn g2p<K: Kernel>(&self, sim: &mut Simulation<D, K>, dt: f64, velocity: bool, deformation: bool)
    where
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
        let walls = &self.walls;
        let p = &mut sim.particles;
        let n = p.len();
        let position = SharedSlice::new(&mut p.position);
        let vel = SharedSlice::new(&mut p.velocity);
        let def = SharedSlice::new(&mut p.deformation_gradient);
        let affine = SharedSlice::new(&mut p.affine);
        let gradient_out = SharedSlice::new(&mut p.velocity_gradient);
        let (mass, half_size) = (&p.mass, &p.half_size);
        let stats = ordered_reduce(
            chunk_count(n),
            KinematicStats::<D>::default,
            |chunk| {
                let mut stats = KinematicStats::<D>::default();
                for k in chunk_range(chunk, n) {
                    // SAFETY: chunks are disjoint particle ranges.
                    let (x, v, f) = unsafe { (position.get(k), vel.get(k), def.get(k)) };
                    let (mut v_new, mut change) = (Vector::<D>::zeros(), Vector::<D>::zeros());
                    let (mut b, mut grad) = (Matrix::<D>::zeros(), Matrix::<D>::zeros());
                    for e in s.entries(k) {
                        let i = s.grid_node(s.node[e] as usize);
                        let (w, vi) = (s.weight[e], grid.momentum[i]);
                        v_new += vi * w;
                        if flip {
                            change += (vi - grid.velocity_old[i]) * w;
                        }
                        if apic {
                            let offset = self.node_position(grid, e) - self.reference[k];
                            b += (vi * w) * offset.transpose();
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
                        *x += v_new * dt;
                    }
                    if deformation {
                        let rate = grad * self.start_f[k];
                        if store_gradient {
                            let l = inverse(f).map_or(Matrix::<D>::zeros(), |fi| rate * fi);
                            // SAFETY: as above.
                            unsafe { *gradient_out.get(k) = l };
                        }
                        *f += rate * dt;
                    }
                    stats.record(k, mass[k], v, x, f, &gravity);
                    if velocity && stats.escaped.is_none() {
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
                        if through || !stencil_fits::<D, K>(grid, x, half) {
                            stats.escaped = Some(ParticleFault {
                                particle: k,
                                field: if through { "wall" } else { "x" },
                                value: x.norm(),
                            });
                        }
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

/// An upper bound on the largest singular value of `m`: the square root of the largest
/// absolute row sum of mᵀm (Gershgorin), exact for a diagonal `m`.
fn largest_singular_value_bound<const D: usize>(m: &Matrix<D>) -> f64 {
    let c = m.transpose() * m;
    (0..D)
        .map(|i| (0..D).map(|j| c[(i, j)].abs()).sum::<f64>())
        .fold(0.0, f64::max)
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound is the singular value for a stretch and never below it for a shear.
    #[test]
    fn singular_value_bound_holds() {
        let stretch = Matrix::<2>::new(0.5, 0.0, 0.0, 2.0);
        assert!((largest_singular_value_bound(&stretch) - 2.0).abs() < 1e-15);
        let shear = Matrix::<3>::new(1.0, 0.7, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let exact = shear.singular_values().max();
        let bound = largest_singular_value_bound(&shear);
        assert!(bound >= exact && bound < 1.2 * exact, "{bound} vs {exact}");
    }
}
