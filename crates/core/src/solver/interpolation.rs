//! Builds every particle's stencil (node indices, weights, weight gradients) for the
//! physics operators, which transfer their own fields without knowing the kernel.

use super::parallel::{SharedSlice, chunk_count, chunk_range};
use super::stencil::{Stencil, stencil_fits};
use crate::grid::Grid;
use crate::kernels::Kernel;
use crate::particles::Particles;
use crate::physics::Interpolation;
use rayon::prelude::*;

/// Fills `out` for the particles' current positions; buffers are reused between steps. A
/// particle whose stencil leaves the grid gets zero weights (the kinematic check stops the
/// run for it).
pub(crate) fn build_interpolation<const D: usize, K: Kernel>(
    grid: &Grid<D>,
    particles: &Particles<D>,
    out: &mut Interpolation<D>,
) {
    let n = particles.len();
    let stencil = K::SPAN.pow(D as u32);
    out.stencil = stencil;
    out.node.resize(n * stencil, 0);
    out.weight.resize(n * stencil, 0.0);
    out.gradient
        .resize(n * stencil, crate::math::Vector::<D>::zeros());
    let node = SharedSlice::new(&mut out.node);
    let weight = SharedSlice::new(&mut out.weight);
    let gradient = SharedSlice::new(&mut out.gradient);
    let inv_dx = grid.inv_dx;
    (0..chunk_count(n)).into_par_iter().for_each(|chunk| {
        let range = chunk_range(chunk, n);
        let entries = range.start * stencil..range.end * stencil;
        // SAFETY: chunks are disjoint particle ranges, so their stencil entries are too.
        let (node, weight, gradient) = unsafe {
            (
                node.range(entries.clone()),
                weight.range(entries.clone()),
                gradient.range(entries),
            )
        };
        for (k, p) in range.enumerate() {
            let x = &particles.position[p];
            let half = if K::USES_PARTICLE_SIZE {
                particles.half_size[p]
            } else {
                0.0
            };
            let base = k * stencil;
            if !stencil_fits::<D, K>(grid, x, half) {
                node[base..base + stencil].fill(0);
                weight[base..base + stencil].fill(0.0);
                continue;
            }
            let s = Stencil::<D>::new::<K>(grid, x, half);
            let mut e = base;
            s.for_each::<K>(&grid.stride, |i, w, dw, _| {
                node[e] = i as u32;
                weight[e] = w;
                gradient[e] = dw * inv_dx;
                e += 1;
            });
        }
    });
}
