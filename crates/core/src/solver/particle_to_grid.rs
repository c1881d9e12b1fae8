//! P2G: scatter particle mass, momentum (with the APIC affine part) and internal force to the
//! grid.
//!
//! Threads never share a node: particles are binned into slabs along x of width `SPAN`
//! nodes, and slabs of one colour (even, then odd) run in parallel. A slab writes at most
//! `2·SPAN - 1` node planes starting at its own, so two slabs of one colour never overlap.

use super::binning::SlabBins;
use super::parallel::SharedSlice;
use super::separable::{Scatter, scatter};
use super::stencil::Stencil;
use crate::grid::Grid;
use crate::grid_activity::BLOCK_NODES;
use crate::kernels::Kernel;
use crate::math::{Matrix, Vector, determinant};
use crate::particles::Particles;
use rayon::prelude::*;

/// How internal forces enter P2G.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ForceTerm {
    /// No stress term (velocity remaps).
    None,
    /// Gravity only, no stress term: the incompressible mode with implicit viscosity, whose
    /// liquids' (viscous) stress is solved for on the grid instead.
    Body,
    /// f_i = -Σ V_p σ_p ∇w_ip.
    Standard,
    /// MLS-MPM: the stress enters the affine momentum, f_i = -Σ V_p σ_p D⁻¹ (x_i - x_p) w_ip.
    Mls,
}

/// What one P2G pass scatters.
#[derive(Clone, Copy, Debug)]
pub(crate) struct P2gParams<const D: usize> {
    pub dt: f64,
    /// Scatter mass too (false for a velocity remap, where the mass is already there).
    pub mass: bool,
    pub force: ForceTerm,
    /// Keep forces in `grid.force` (FLIP) instead of folding `dt·f` into the momentum.
    pub force_apart: bool,
    /// Use the particles' affine matrices (APIC).
    pub affine: bool,
    /// APIC inertia coefficient c (D = c·dx²·I) for the MLS force.
    pub inertia: f64,
    /// Gravity, scattered with the forces as m·g (so stick walls fold it like any force).
    pub gravity: Vector<D>,
}

/// Tells a sparse grid which blocks the stencil with first node `first` writes. The rows of
/// the stencil (along z, or along y in 2D) are runs of `K::SPAN` nodes; where rows lie
/// within a block of each other, one range per x-plane from its first row to the end of
/// its last covers them (the nodes between rows add no block that a row does not hold), else
/// each row is marked. At most `2·K::SPAN²` blocks per particle
/// ([`crate::grid_activity::MAX_BLOCKS_PER_PARTICLE`]). `recent` holds blocks this task has
/// marked (direct-mapped): neighbouring particles mostly write the same blocks, and skip
/// the atomic marks.
#[inline(always)]
fn mark_stencil<const D: usize, K: Kernel>(
    grid: &Grid<D>,
    first: usize,
    recent: &mut [usize; RECENT_BLOCKS],
) {
    let (stride, span) = (grid.stride, K::SPAN);
    // Rows far apart (long z lines) are marked one by one.
    let (rows, length, step) = match D {
        3 if stride[1] >= BLOCK_NODES => (span, span, stride[1]),
        3 => (1, (span - 1) * stride[1] + span, 0),
        _ => (1, span, 0),
    };
    for a in 0..span {
        for b in 0..rows {
            let start = first + a * stride[0] + b * step;
            let (lo, hi) = (start / BLOCK_NODES, (start + length - 1) / BLOCK_NODES);
            if recent[lo % RECENT_BLOCKS] != lo || recent[hi % RECENT_BLOCKS] != hi {
                grid.mark(start..start + length);
                recent[lo % RECENT_BLOCKS] = lo;
                recent[hi % RECENT_BLOCKS] = hi;
            }
        }
    }
}

/// Blocks one P2G task remembers having marked (direct-mapped by block number): a slab's
/// particles write a few dozen blocks.
const RECENT_BLOCKS: usize = 64;

/// Scatters particle quantities onto the (cleared) grid; on a sparse grid, marks the blocks
/// it writes ([`Grid::take_marks`] makes them the step's active ones).
pub(crate) fn particle_to_grid<const D: usize, K: Kernel>(
    grid: &mut Grid<D>,
    particles: &Particles<D>,
    bins: &SlabBins,
    params: P2gParams<D>,
) {
    let dx = grid.dx;
    let inv_dx = grid.inv_dx;
    let stride = grid.stride;
    let mass_out = SharedSlice::new(&mut grid.mass);
    let momentum_out = SharedSlice::new(&mut grid.momentum);
    let force_out = SharedSlice::new(&mut grid.force);
    let grid = &*grid;
    let sparse = grid.is_sparse();
    let loads = (!particles.external_force.is_empty()).then_some(&particles.external_force);
    for colour in 0..2 {
        (0..bins.slab_count())
            .into_par_iter()
            .filter(|s| s % 2 == colour)
            .for_each(|slab| {
                let mut recent = [usize::MAX; RECENT_BLOCKS];
                for &p in bins.slab(slab) {
                    let p = p as usize;
                    let x = particles.position[p];
                    let half = if K::USES_PARTICLE_SIZE {
                        particles.half_size[p]
                    } else {
                        0.0
                    };
                    let stencil = Stencil::<D>::new::<K>(grid, &x, half);
                    if sparse {
                        mark_stencil::<D, K>(grid, stencil.base_index, &mut recent);
                    }
                    let m = particles.mass[p];
                    let mut mv = particles.velocity[p] * m;
                    let mut weight = Vector::<D>::zeros();
                    if params.force != ForceTerm::None {
                        if params.force_apart {
                            weight = params.gravity * m;
                        } else {
                            mv += params.gravity * (m * params.dt);
                        }
                        if let Some(loads) = loads {
                            if params.force_apart {
                                weight += loads[p];
                            } else {
                                mv += loads[p] * params.dt;
                            }
                        }
                    }
                    // Affine momentum per cell of offset: Q·(x_i - x_p) with offsets in cells.
                    let mut q = Matrix::<D>::zeros();
                    if params.affine {
                        q += particles.affine[p] * (m * dx);
                    }
                    // Standard force per unit weight gradient (grid units).
                    let mut s = Matrix::<D>::zeros();
                    match params.force {
                        ForceTerm::None | ForceTerm::Body => {}
                        ForceTerm::Standard => {
                            let f = &particles.deformation_gradient[p];
                            let volume = particles.volume0[p] * determinant(f);
                            s = particles.stress[p] * (-volume * inv_dx);
                        }
                        ForceTerm::Mls => {
                            let f = &particles.deformation_gradient[p];
                            let volume = particles.volume0[p] * determinant(f);
                            q -= particles.stress[p]
                                * (params.dt * volume / (params.inertia * dx * dx) * dx);
                        }
                    }
                    if !params.force_apart {
                        // Forces folded into the momentum: the tensor-product scatter.
                        let what = Scatter {
                            mass: params.mass.then_some(m),
                            mv,
                            q,
                            s: (params.force == ForceTerm::Standard).then(|| s * params.dt),
                        };
                        // SAFETY: the slab colouring gives this task exclusive access to
                        // every node its particles touch (module docs); the stencil is on
                        // the grid because positions are checked against it after every move.
                        unsafe {
                            scatter::<D, K>(&stencil, &stride, &what, mass_out, momentum_out);
                        }
                        continue;
                    }
                    // FLIP: forces kept apart in `grid.force`.
                    stencil.for_each::<K>(&stride, |i, w, grad, dpos| {
                        // SAFETY: as above.
                        unsafe {
                            if params.mass {
                                *mass_out.get(i) += w * m;
                            }
                            if params.force != ForceTerm::None {
                                *force_out.get(i) += weight * w;
                            }
                            if params.force == ForceTerm::Standard {
                                *force_out.get(i) += s * grad;
                            }
                            *momentum_out.get(i) += (mv + q * dpos) * w;
                        }
                    });
                }
            });
    }
}
