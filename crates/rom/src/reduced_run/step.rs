//! One reduced step: the quadrature neighbourhood of the samples, the ordinary MPM update
//! over it (kinematics from the map, stress, P2G, the core's grid update, G2P to the
//! samples) and the projection of the samples' new state back onto the map.

use super::diagnostics::diagnostic;
use super::setup::{Reduced, StepStats};
use super::stage_clock::RomStage;
use super::stress::{matrix_from_rows, update_stress_parallel};
use crate::RomError;
use mpm_core::kernels::Kernel;
use mpm_core::material::{BatchStats, Material};
use mpm_core::math::{Matrix, Vector, determinant, inverse, vector_from_slice};
use mpm_core::output::Diagnostic;
use mpm_core::solver::DimensionDispatch;
use mpm_core::solver::grid_update::{GridParams, update_grid};
use mpm_core::solver::stencil::{Stencil, stencil_fits};
use rayon::prelude::*;

impl<const D: usize, K: Kernel> Reduced<'_, D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    fn half_size(&self, p: usize) -> f64 {
        if K::USES_PARTICLE_SIZE {
            self.sim.particles.half_size[p]
        } else {
            0.0
        }
    }

    /// One reduced step of `dt` ending at `time_end`. Returns a diagnostic when the step
    /// cannot go on (a sample left the grid, a particle inverted).
    pub(super) fn step(&mut self, dt: f64, time_end: f64) -> Result<Option<Diagnostic>, RomError> {
        let lap = std::time::Instant::now();
        let grid_nodes = self.sim.grid.nodes;
        // 1. Mark the base nodes whose stencils meet a sample's stencil.
        self.map
            .positions(&self.q, &self.samples, &mut self.sample_x)?;
        self.epoch = self.epoch.wrapping_add(1).max(1);
        let span = K::SPAN as isize;
        for k in 0..self.samples.len() {
            let x: Vector<D> = vector_from_slice(&self.sample_x[k * D..]);
            let p = self.samples[k] as usize;
            if !stencil_fits::<D, K>(&self.sim.grid, &x, self.half_size(p)) {
                return Ok(Some(diagnostic(
                    p,
                    "x",
                    x.norm(),
                    "a sampled particle left the grid",
                )));
            }
            let mut lo = [0usize; 3];
            let mut hi = [0usize; 3];
            for d in 0..D {
                let xi = (x[d] - self.sim.grid.origin[d]) * self.sim.grid.inv_dx;
                let base = K::weights(xi, self.half_size(p)).base;
                lo[d] = (base - (span - 1)).max(0) as usize;
                hi[d] = ((base + span - 1) as usize).min(grid_nodes[d] - 1);
            }
            for i in lo[0]..=hi[0] {
                for j in lo[1]..=hi[1] {
                    for kk in lo[2]..=hi[2] {
                        let index = self.sim.grid.index([i, j, kk]);
                        self.base_mark[index] = self.epoch;
                    }
                }
            }
        }
        // 2. The quadrature particles: candidates whose base node is marked.
        self.map
            .positions(&self.q, &self.candidates, &mut self.candidate_x)?;
        self.quad.clear();
        self.quad_x.clear();
        for (k, &p) in self.candidates.iter().enumerate() {
            let x: Vector<D> = vector_from_slice(&self.candidate_x[k * D..]);
            let half = self.half_size(p as usize);
            if !stencil_fits::<D, K>(&self.sim.grid, &x, half) {
                continue;
            }
            let mut base = [0usize; 3];
            for d in 0..D {
                let xi = (x[d] - self.sim.grid.origin[d]) * self.sim.grid.inv_dx;
                base[d] = K::weights(xi, half).base as usize;
            }
            if self.base_mark[self.sim.grid.index(base)] == self.epoch {
                self.quad.push(p);
                self.quad_x.push(x);
            }
        }
        let nq = self.quad.len();
        self.quadrature_total += nq as f64;
        self.quadrature_max = self.quadrature_max.max(nq);
        let lap = self.clock.lap(RomStage::Neighbourhood, lap);
        // 3. Kinematics from the map: F, velocity and affine velocity of each.
        self.map
            .gradients(&self.q, &self.quad, &mut self.flat_f[..nq * D * D])?;
        self.map.velocities(
            &self.q,
            &self.q_rate,
            &self.quad,
            &mut self.flat_v[..nq * D],
        )?;
        let affine = self.settings.affine;
        if affine {
            self.map.gradient_rates(
                &self.q,
                &self.q_rate,
                &self.quad,
                &mut self.flat_rate[..nq * D * D],
            )?;
        }
        let (flat_f, flat_v, flat_rate) = (&self.flat_f, &self.flat_v, &self.flat_rate);
        let volume0 = &self.sim.particles.volume0;
        let quad = &self.quad;
        let (min_det_f, max_speed) = self.quad_f[..nq]
            .par_iter_mut()
            .zip(self.quad_v[..nq].par_iter_mut())
            .zip(self.quad_c[..nq].par_iter_mut())
            .zip(self.quad_volume0[..nq].par_iter_mut())
            .enumerate()
            .map(|(k, (((f, v), c), v0))| {
                *f = matrix_from_rows::<D>(&flat_f[k * D * D..]);
                *v = vector_from_slice(&flat_v[k * D..]);
                *v0 = volume0[quad[k] as usize];
                if affine {
                    let rate = matrix_from_rows::<D>(&flat_rate[k * D * D..]);
                    *c = inverse(f).map_or_else(Matrix::<D>::zeros, |fi| rate * fi);
                }
                (determinant(f), v.norm())
            })
            .reduce(
                || (f64::INFINITY, 0.0f64),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            );
        let lap = self.clock.lap(RomStage::Kinematics, lap);
        let mut stats = StepStats {
            min_det_f,
            max_speed,
            ..StepStats::default()
        };
        if stats.min_det_f.is_nan() || stats.min_det_f <= 0.0 {
            return Ok(Some(diagnostic(
                0,
                "J",
                stats.min_det_f,
                "the map inverted a quadrature particle (det F <= 0)",
            )));
        }
        // 4. Stress from the scene's materials, by material batch.
        let mut batch_stats = BatchStats::default();
        for group in &self.sim.particles.groups {
            let a = self
                .quad
                .partition_point(|&p| (p as usize) < group.range.start);
            let b = self
                .quad
                .partition_point(|&p| (p as usize) < group.range.end);
            batch_stats = batch_stats.merge(update_stress_parallel::<D>(
                &*group.material,
                dt,
                &self.quad_f[a..b],
                &self.quad_volume0[a..b],
                &mut self.quad_stress[a..b],
            ));
        }
        stats.max_wave_speed = batch_stats.max_wave_speed;
        let lap = self.clock.lap(RomStage::Stress, lap);
        // 5. P2G over the quadrature particles: each particle's stencil contributions are
        // computed in parallel into a buffer, then added to the grid in one pass.
        let span_z = if D == 3 { K::SPAN } else { 1 };
        let per = K::SPAN * K::SPAN * span_z * (1 + D);
        if self.p2g.len() < nq * per {
            self.p2g.resize(nq * per, 0.0);
            self.p2g_base.resize(nq, 0);
        }
        let grid = &mut self.sim.grid;
        let (dx, inv_dx, stride) = (grid.dx, grid.inv_dx, grid.stride);
        let gravity = self.settings.gravity;
        let (mls, inertia) = (self.settings.mls, self.settings.inertia);
        let particles = &self.sim.particles;
        let (quad_x, quad_v, quad_c) = (&self.quad_x, &self.quad_v, &self.quad_c);
        let (quad_f, quad_stress, quad_volume0) =
            (&self.quad_f, &self.quad_stress, &self.quad_volume0);
        {
            let grid = &*grid;
            self.p2g[..nq * per]
                .par_chunks_mut(per)
                .zip(self.p2g_base[..nq].par_iter_mut())
                .enumerate()
                .for_each(|(k, (buffer, base))| {
                    let p = quad[k] as usize;
                    let half = if K::USES_PARTICLE_SIZE {
                        particles.half_size[p]
                    } else {
                        0.0
                    };
                    let stencil = Stencil::<D>::new::<K>(grid, &quad_x[k], half);
                    *base = stencil.base_index;
                    let m = particles.mass[p];
                    let mv = (quad_v[k] + gravity * dt) * m;
                    let volume = quad_volume0[k] * determinant(&quad_f[k]);
                    let mut affine_momentum = Matrix::<D>::zeros();
                    if affine {
                        affine_momentum += quad_c[k] * (m * dx);
                    }
                    let mut force = Matrix::<D>::zeros();
                    if mls {
                        affine_momentum -=
                            quad_stress[k] * (dt * volume / (inertia * dx * dx) * dx);
                    } else {
                        force = quad_stress[k] * (-volume * inv_dx * dt);
                    }
                    let mut t = 0;
                    stencil.for_each::<K>(&stride, |_, w, grad, dpos| {
                        buffer[t] = w * m;
                        let add = (mv + affine_momentum * dpos) * w + force * grad;
                        buffer[t + 1..t + 1 + D].copy_from_slice(add.as_slice());
                        t += 1 + D;
                    });
                });
        }
        // The sparse grid zeroes the blocks the last step wrote; each stencil row marks its
        // blocks as written, so the grid update and the next clear visit only those.
        grid.clear();
        for k in 0..nq {
            let base = self.p2g_base[k];
            let buffer = &self.p2g[k * per..(k + 1) * per];
            let mut t = 0;
            for a in 0..K::SPAN {
                for b in 0..K::SPAN {
                    let row = base + a * stride[0] + b * stride[1];
                    grid.mark(row..row + span_z);
                    for c in 0..span_z {
                        let i = base + a * stride[0] + b * stride[1] + c;
                        grid.mass[i] += buffer[t];
                        grid.momentum[i] +=
                            Vector::<D>::from_column_slice(&buffer[t + 1..t + 1 + D]);
                        t += 1 + D;
                    }
                }
            }
        }
        let lap = self.clock.lap(RomStage::P2g, lap);
        // 6. The core's grid update: forces, damping, walls and obstacles.
        update_grid(
            grid,
            &self.boundaries,
            GridParams {
                dt,
                forces: true,
                flip: false,
                damping: self.settings.damping,
                time: time_end,
            },
        );
        let lap = self.clock.lap(RomStage::GridUpdate, lap);
        // 7. G2P to the sampled particles.
        for k in 0..self.samples.len() {
            let p = self.samples[k] as usize;
            let x: Vector<D> = vector_from_slice(&self.sample_x[k * D..]);
            let half = if K::USES_PARTICLE_SIZE {
                self.sim.particles.half_size[p]
            } else {
                0.0
            };
            let stencil = Stencil::<D>::new::<K>(grid, &x, half);
            let mut v = Vector::<D>::zeros();
            let velocity = &grid.momentum;
            stencil.for_each::<K>(&stride, |i, w, _, _| v += velocity[i] * w);
            let x_new = x + v * dt;
            self.sample_target[k * D..(k + 1) * D].copy_from_slice(x_new.as_slice());
            self.sample_v[k * D..(k + 1) * D].copy_from_slice(v.as_slice());
            stats.max_speed = stats.max_speed.max(v.norm());
        }
        let lap = self.clock.lap(RomStage::G2p, lap);
        // 8. Back onto the map.
        self.project_positions()?;
        self.project_velocities()?;
        self.clock.lap(RomStage::Projection, lap);
        self.stats = stats;
        Ok(None)
    }
}
