//! F-bar anti-locking on the increment: each particle's volume change of this step,
//! ΔJ = det(I + dt L), is replaced by its average over the neighbouring nodes,
//! ΔJ̄ = Σ_i w_ip ΔJ_i with ΔJ_i = Σ_q w_iq V_q ΔJ_q / Σ_q w_iq V_q (V the current volume),
//! and F is scaled by (ΔJ̄ / ΔJ)^(1/D). Near-incompressible materials then no longer lock
//! (too stiff in bending): the volume constraint holds on averages, not per particle.
//! Averaging the increment, not J itself, keeps the averaging from compounding step after
//! step (which would diffuse the volumetric strain).

use super::binning::SlabBins;
use super::parallel::{SharedSlice, chunk_count, chunk_range};
use super::stencil::Stencil;
use crate::grid::Grid;
use crate::kernels::Kernel;
use crate::math::determinant;
use crate::particles::Particles;
use rayon::prelude::*;

/// Grid storage for the averaging (allocated only when the scene asks for F-bar).
pub(crate) struct VolumeAverage {
    weighted_j: Vec<f64>,
    weight: Vec<f64>,
}

impl VolumeAverage {
    /// Buffers for a grid of `nodes` nodes.
    pub fn new(nodes: usize) -> Self {
        Self {
            weighted_j: vec![0.0; nodes],
            weight: vec![0.0; nodes],
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        (self.weighted_j.capacity() + self.weight.capacity()) * 8
    }

    /// Averages this step's volume change over the grid and scales F to match. `bins` must
    /// be current for the particles' positions; `particles.velocity_gradient` holds L.
    pub fn apply<const D: usize, K: Kernel>(
        &mut self,
        grid: &Grid<D>,
        particles: &mut Particles<D>,
        bins: &SlabBins,
        dt: f64,
    ) {
        let identity = crate::math::Matrix::<D>::identity();
        self.weighted_j.par_iter_mut().for_each(|x| *x = 0.0);
        self.weight.par_iter_mut().for_each(|x| *x = 0.0);
        let num = SharedSlice::new(&mut self.weighted_j);
        let den = SharedSlice::new(&mut self.weight);
        let stride = grid.stride;
        {
            let p = &*particles;
            for colour in 0..2 {
                (0..bins.slab_count())
                    .into_par_iter()
                    .filter(|s| s % 2 == colour)
                    .for_each(|slab| {
                        for &q in bins.slab(slab) {
                            let q = q as usize;
                            let half = if K::USES_PARTICLE_SIZE {
                                p.half_size[q]
                            } else {
                                0.0
                            };
                            let stencil = Stencil::<D>::new::<K>(grid, &p.position[q], half);
                            let volume = p.volume0[q] * determinant(&p.deformation_gradient[q]);
                            let dj = determinant(&(identity + p.velocity_gradient[q] * dt));
                            stencil.for_each::<K>(&stride, |i, w, _, _| {
                                // SAFETY: slab colouring, as in P2G (particle_to_grid.rs).
                                unsafe {
                                    *num.get(i) += w * volume * dj;
                                    *den.get(i) += w * volume;
                                }
                            });
                        }
                    });
            }
        }
        let (weighted_j, weight) = (&self.weighted_j, &self.weight);
        let n = particles.len();
        let Particles {
            position,
            half_size,
            deformation_gradient,
            velocity_gradient,
            ..
        } = particles;
        let (position, half_size, velocity_gradient) =
            (&*position, &*half_size, &*velocity_gradient);
        let f_out = SharedSlice::new(deformation_gradient);
        (0..chunk_count(n)).into_par_iter().for_each(|chunk| {
            for q in chunk_range(chunk, n) {
                let half = if K::USES_PARTICLE_SIZE {
                    half_size[q]
                } else {
                    0.0
                };
                let stencil = Stencil::<D>::new::<K>(grid, &position[q], half);
                let mut j_bar = 0.0;
                stencil.for_each::<K>(&stride, |i, w, _, _| {
                    if weight[i] > 0.0 {
                        j_bar += w * weighted_j[i] / weight[i];
                    }
                });
                // SAFETY: chunks are disjoint particle ranges.
                let f = unsafe { f_out.get(q) };
                let dj = determinant(&(identity + velocity_gradient[q] * dt));
                if dj > 0.0 && j_bar > 0.0 {
                    *f *= (j_bar / dj).powf(1.0 / D as f64);
                }
            }
        });
    }
}
