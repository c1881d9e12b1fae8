//! Builds every particle's stencil (node indices, weights, weight gradients) for the
//! physics operators, which transfer their own fields without knowing the kernel.

use super::parallel::{SharedSlice, chunk_count, chunk_range};
use super::stencil::{Stencil, stencil_fits};
use crate::grid::Grid;
use crate::kernels::Kernel;
use crate::particles::Particles;
use crate::physics::Interpolation;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

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
    // Grid nodes, until `number_rows` makes them rows.
    out.compact = false;
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

/// Builds the stencils as [`build_interpolation`] does, with compact rows
/// ([`number_rows`]): the physics operators' node arrays then cover the body's nodes, not
/// the box.
pub(crate) fn build_compact_interpolation<const D: usize, K: Kernel>(
    grid: &Grid<D>,
    particles: &Particles<D>,
    out: &mut Interpolation<D>,
) {
    build_interpolation::<D, K>(grid, particles, out);
    number_rows(grid.len(), out);
}

/// Numbers the nodes of `out`'s stencil entries (grid nodes, of `grid_nodes`) in grid
/// order and makes `node` hold those rows ([`Interpolation::compact`]). One bit per grid
/// node marks the reached nodes, one bit per 64 of those words says which words hold any,
/// so a build costs the entries plus 1/4096 of the box, and clearing costs the last rows.
/// Buffers are reused: no allocation once grown.
pub(super) fn number_rows<const D: usize>(grid_nodes: usize, out: &mut Interpolation<D>) {
    let words = grid_nodes.div_ceil(64);
    if out.marks.len() != words {
        out.marks.clear();
        out.marks.resize_with(words, AtomicU64::default);
        out.summary.clear();
        out.summary
            .resize_with(words.div_ceil(64), AtomicU64::default);
        out.rank.clear();
        out.rank.resize(words, 0);
        out.rows.clear();
    }
    // Clear what the last numbering marked.
    for &row in &out.rows {
        let w = row as usize / 64;
        out.marks[w].store(0, Ordering::Relaxed);
        out.summary[w / 64].store(0, Ordering::Relaxed);
    }
    let (marks, summary) = (&out.marks, &out.summary);
    out.node.par_chunks(4096).for_each(|chunk| {
        for &i in chunk {
            let (w, bit) = (i as usize / 64, 1u64 << (i % 64));
            // Neighbouring entries mostly set bits already set: read before writing.
            if marks[w].load(Ordering::Relaxed) & bit == 0 {
                marks[w].fetch_or(bit, Ordering::Relaxed);
                let flag = 1u64 << (w % 64);
                if summary[w / 64].load(Ordering::Relaxed) & flag == 0 {
                    summary[w / 64].fetch_or(flag, Ordering::Relaxed);
                }
            }
        }
    });
    out.rows.clear();
    let mut before = 0u32;
    for (s, flags) in out.summary.iter().enumerate() {
        let mut flags = flags.load(Ordering::Relaxed);
        while flags != 0 {
            let w = s * 64 + flags.trailing_zeros() as usize;
            flags &= flags - 1;
            out.rank[w] = before;
            let mut bits = out.marks[w].load(Ordering::Relaxed);
            before += bits.count_ones();
            while bits != 0 {
                out.rows.push((w * 64) as u32 + bits.trailing_zeros());
                bits &= bits - 1;
            }
        }
    }
    let (marks, rank) = (&out.marks, &out.rank);
    out.node.par_chunks_mut(4096).for_each(|chunk| {
        for i in chunk {
            let (w, bit) = (*i as usize / 64, *i % 64);
            let below = marks[w].load(Ordering::Relaxed) & ((1u64 << bit) - 1);
            *i = rank[w] + below.count_ones();
        }
    });
    out.compact = true;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Compact rows name every reached node once, in grid order, and map each stencil
    /// entry back to its grid node; numbered again, they follow the new entries.
    #[test]
    fn compact_rows_number_the_reached_nodes_in_grid_order() {
        let grid_nodes = 50_000;
        let mut k = 11u64;
        let mut next = |limit: u32| {
            k = k
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (k >> 33) as u32 % limit
        };
        // One numbering reused: each round clears what the last one marked.
        let mut it = Interpolation::<3> {
            stencil: 27,
            ..Interpolation::default()
        };
        for round in 0..4 {
            // Clusters of nearby nodes (shared between entries), moving from round to
            // round, plus the last node.
            let mut plain: Vec<u32> = (0..27 * 300)
                .map(|e| (e / 500) as u32 * (3000 - 500 * round) + next(700) + 37 * round)
                .collect();
            plain.push(grid_nodes as u32 - 1);
            it.node = plain.clone();
            number_rows(grid_nodes, &mut it);
            let mut reached = plain.clone();
            reached.sort_unstable();
            reached.dedup();
            assert!(it.compact);
            assert_eq!(it.rows, reached);
            assert!(it.rows.len() < plain.len());
            assert_eq!(it.row_count(grid_nodes), reached.len());
            for (e, &row) in it.node.iter().enumerate() {
                assert_eq!(it.grid_node(row as usize), plain[e] as usize);
            }
        }
        let plain = Interpolation::<3>::default();
        assert_eq!(plain.row_count(grid_nodes), grid_nodes);
        assert_eq!(plain.grid_node(17), 17);
    }
}
