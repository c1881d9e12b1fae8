//! CPDI's stencils, built every step: each particle's domain (half width h, deformed by F)
//! reaches the box of nodes its corners' linear stencils cover, and every node of that box is
//! one stencil entry with the weight and gradient of [`crate::kernels::cpdi`]. The stencil
//! length is this step's largest box, shorter boxes padded with zero-weight entries.

use super::interpolation::number_rows;
use super::parallel::{SharedSlice, chunk_count, chunk_range};
use crate::grid::Grid;
use crate::kernels::cpdi::{domain_box, domain_weights};
use crate::math::{Matrix, Vector};
use crate::particles::Particles;
use crate::physics::Interpolation;
use rayon::prelude::*;

/// A domain's node box: lowest node and nodes per axis.
pub(super) type NodeBox = ([isize; 3], [usize; 3]);

/// The domain's centre in grid units and its half vectors in cells.
#[inline]
fn domain<const D: usize>(
    grid: &Grid<D>,
    x: &Vector<D>,
    f: &Matrix<D>,
    half: f64,
) -> (Vector<D>, Matrix<D>) {
    ((x - grid.origin) * grid.inv_dx, f * half)
}

/// Whether a box lies on the grid (so does every corner's stencil).
#[inline]
fn box_fits<const D: usize>(grid: &Grid<D>, (low, count): &NodeBox) -> bool {
    (0..D).all(|d| low[d] >= 0 && low[d] as usize + count[d] <= grid.nodes[d])
}

/// Whether the domain of a particle at `x` with deformation `f` and half width `half` (cells)
/// lies on the grid.
pub(super) fn domain_fits<const D: usize>(
    grid: &Grid<D>,
    x: &Vector<D>,
    f: &Matrix<D>,
    half: f64,
) -> bool {
    if !x.iter().chain(f.iter()).all(|v| v.is_finite()) {
        return false;
    }
    let (centre, vectors) = domain(grid, x, f, half);
    box_fits(grid, &domain_box(&centre, &vectors))
}

/// Fills `out` (compact rows) with every particle's domain stencil at its current position
/// and F; `boxes` is scratch kept between steps. A particle whose domain leaves the grid gets
/// zero weights (the kinematic check stops the run for it).
pub(super) fn build_domain_stencils<const D: usize>(
    grid: &Grid<D>,
    particles: &Particles<D>,
    boxes: &mut Vec<NodeBox>,
    out: &mut Interpolation<D>,
) {
    let n = particles.len();
    (0..n)
        .into_par_iter()
        .map(|p| {
            let (x, f) = (&particles.position[p], &particles.deformation_gradient[p]);
            if !x.iter().chain(f.iter()).all(|v| v.is_finite()) {
                return ([0; 3], [0; 3]);
            }
            let (centre, vectors) = domain(grid, x, f, particles.half_size[p]);
            let b = domain_box(&centre, &vectors);
            if box_fits(grid, &b) {
                b
            } else {
                ([0; 3], [0; 3])
            }
        })
        .collect_into_vec(boxes);
    let stencil = boxes
        .iter()
        .map(|(_, c)| c[0] * c[1] * c[2])
        .max()
        .unwrap_or(1)
        .max(1);
    out.stencil = stencil;
    out.compact = false;
    out.node.resize(n * stencil, 0);
    out.weight.resize(n * stencil, 0.0);
    out.gradient.resize(n * stencil, Vector::<D>::zeros());
    let node = SharedSlice::new(&mut out.node);
    let weight = SharedSlice::new(&mut out.weight);
    let gradient = SharedSlice::new(&mut out.gradient);
    let boxes = &*boxes;
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
            let entries = k * stencil..(k + 1) * stencil;
            let (node, weight, gradient) = (
                &mut node[entries.clone()],
                &mut weight[entries.clone()],
                &mut gradient[entries],
            );
            let (low, count) = boxes[p];
            let nodes = count[0] * count[1] * count[2];
            if nodes > 0 {
                let (x, f) = (&particles.position[p], &particles.deformation_gradient[p]);
                let (centre, vectors) = domain(grid, x, f, particles.half_size[p]);
                domain_weights(&centre, &vectors, low, count, weight, gradient);
                let mut e = 0;
                for i in 0..count[0] {
                    for j in 0..count[1] {
                        for l in 0..count[2] {
                            let ijk = [i, j, l];
                            let at = std::array::from_fn(|d| {
                                if d < D {
                                    (low[d] + ijk[d] as isize) as usize
                                } else {
                                    0
                                }
                            });
                            node[e] = grid.index(at) as u32;
                            gradient[e] *= grid.inv_dx;
                            e += 1;
                        }
                    }
                }
            }
            // Padding (or a whole stencil off the grid): zero weight on a node of its own.
            let pad = if nodes > 0 { node[0] } else { 0 };
            node[nodes..].fill(pad);
            weight[nodes..].fill(0.0);
            gradient[nodes..].fill(Vector::<D>::zeros());
        }
    });
    number_rows(grid.len(), out);
}
