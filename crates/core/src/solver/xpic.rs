//! XPIC(m), the extended particle-in-cell velocity update (Hammerquist & Nairn 2017).
//!
//! PIC gives a particle the grid's velocity, `V ← S v`: whatever of the particles' velocity
//! field the grid cannot carry is lost, and with it energy, every step. FLIP keeps the
//! particle's own velocity and adds the grid's change, `V ← V + S (v − vⁿ)`: nothing is
//! lost, the noise the grid cannot see included. XPIC keeps the part the grid carries.
//! With the lumped grid velocity `vⁿ = m⁻¹ Sᵀ M V` (what P2G gives) and the particle round
//! trip `S⁺S z = m⁻¹ Sᵀ M S z` (grid to particles and back), the consistent-mass grid
//! velocity `(Sᵀ M S)⁻¹ Sᵀ M V` is the series `Σₖ (I − S⁺S)ᵏ vⁿ`; XPIC(m) sums its first m
//! terms into `v*` and updates `V ← S (v + v* − vⁿ)`, `v` the updated grid velocity. Order
//! 1 is PIC; each further order costs one round trip. (The binomial form of the paper,
//! `v* = Σₖ (−1)ᵏ⁺¹ C(m, k) (S⁺S)ᵏ⁻¹ vⁿ`, is the same sum; Nairn & Hammerquist 2021.)
//!
//! Stick and symmetry walls: the round trip is that of the body and its mirror image, as P2G
//! folds it (`Boundaries::fold_stick_walls`): the ghost nodes behind the wall read the image
//! of the nodes in front, and what the particles put on them is folded back. The
//! correction `v* − vⁿ` obeys the grid's velocity conditions: where a wall or obstacle
//! constrains a node, the constrained part of the correction is dropped, so a stick wall's
//! nodes move as PIC moves them; the ghosts then take the image of the correction in front.

use super::binning::SlabBins;
use super::parallel::SharedSlice;
use super::stencil::Stencil;
use crate::boundary::Boundaries;
use crate::grid::{Grid, node_coords, node_position};
use crate::kernels::Kernel;
use crate::math::Vector;
use crate::particles::Particles;
use rayon::prelude::*;

/// Leaves XPIC's correction `v* − vⁿ` of order `order` in `grid.xpic_velocity`, after a
/// grid update that kept the forces apart (`grid.velocity_old` holds `vⁿ`, `grid.momentum`
/// the updated velocity). `time` is the step's end, where the obstacles are.
pub(super) fn extrapolate<const D: usize, K: Kernel>(
    grid: &mut Grid<D>,
    particles: &Particles<D>,
    bins: &SlabBins,
    boundaries: &Boundaries<D>,
    order: u32,
    time: f64,
) {
    let zero = Vector::<D>::zeros();
    let extrapolated = SharedSlice::new(&mut grid.xpic_velocity);
    let round_trip = SharedSlice::new(&mut grid.xpic_round_trip);
    let grid = &*grid;
    let blocks = grid.blocks();
    let (mass, old) = (&grid.mass, &grid.velocity_old);
    // v*₁ = vⁿ where there is mass.
    (0..blocks.count()).into_par_iter().for_each(|k| {
        let range = blocks.range(k);
        // SAFETY: the blocks are disjoint node ranges.
        let y = unsafe { extrapolated.range(range.clone()) };
        for (value, i) in y.iter_mut().zip(range) {
            *value = if mass[i] > 0.0 { old[i] } else { zero };
        }
    });
    // Horner's form of the series: v* ← vⁿ + (I − S⁺S) v*, order − 1 times.
    for _ in 1..order {
        mirror_to_ghosts(grid, boundaries, extrapolated);
        particle_round_trip::<D, K>(grid, particles, bins, extrapolated, round_trip);
        fold_from_ghosts(grid, boundaries, round_trip);
        divide_by_mass(grid, round_trip);
        (0..blocks.count()).into_par_iter().for_each(|k| {
            let range = blocks.range(k);
            // SAFETY: the blocks are disjoint node ranges.
            let (y, trip) = unsafe {
                (
                    extrapolated.range(range.clone()),
                    round_trip.range(range.clone()),
                )
            };
            for ((value, back), i) in y.iter_mut().zip(trip.iter()).zip(range) {
                if mass[i] > 0.0 {
                    *value = old[i] + *value - *back;
                }
            }
        });
    }
    // The correction v* − vⁿ, with the constrained part dropped where the grid update
    // constrained the velocity.
    let (origin, dx, stride, velocity) = (grid.origin, grid.dx, grid.stride, &grid.momentum);
    (0..blocks.count()).into_par_iter().for_each(|k| {
        let range = blocks.range(k);
        // SAFETY: the blocks are disjoint node ranges.
        let y = unsafe { extrapolated.range(range.clone()) };
        for (value, i) in y.iter_mut().zip(range) {
            let m = mass[i];
            if m <= 0.0 {
                *value = zero;
                continue;
            }
            let mut correction = *value - old[i];
            if !boundaries.is_empty() {
                let ijk = node_coords(&stride, i);
                let x = node_position(&origin, dx, ijk);
                let mut constrained = velocity[i] + correction;
                boundaries.apply(ijk, &x, time, m, &mut constrained);
                correction = constrained - velocity[i];
            }
            *value = correction;
        }
    });
    mirror_to_ghosts(grid, boundaries, extrapolated);
}

/// The mirror image of a nodal vector across a stick wall (negated: the image moves
/// opposite) or a symmetry wall (normal component `axis` negated).
fn image<const D: usize>(mut value: Vector<D>, axis: usize, symmetry: bool) -> Vector<D> {
    if symmetry {
        value[axis] = -value[axis];
        value
    } else {
        -value
    }
}

/// Gives the ghost nodes behind stick and symmetry walls the image of the nodes in front,
/// as the grid update's mirror does for the velocity.
fn mirror_to_ghosts<const D: usize>(
    grid: &Grid<D>,
    boundaries: &Boundaries<D>,
    field: SharedSlice<Vector<D>>,
) {
    boundaries.for_each_mirror_node(grid.nodes, |ghost, front, axis, symmetry| {
        let (g, f) = (grid.index(ghost), grid.index(front));
        if grid.is_active(g) {
            // SAFETY: one thread; `field` is borrowed by no one else during the call.
            unsafe { *field.get(g) = image(*field.get(f), axis, symmetry) };
        }
    });
}

/// Folds what the particles put on the ghost nodes onto the nodes in front, as P2G's mass
/// and momentum are folded (`Boundaries::fold_stick_walls`).
fn fold_from_ghosts<const D: usize>(
    grid: &Grid<D>,
    boundaries: &Boundaries<D>,
    field: SharedSlice<Vector<D>>,
) {
    boundaries.for_each_mirror_node(grid.nodes, |ghost, front, axis, symmetry| {
        let (g, f) = (grid.index(ghost), grid.index(front));
        if grid.is_active(g) {
            // SAFETY: one thread; `field` is borrowed by no one else during the call.
            unsafe {
                let folded = image(*field.get(g), axis, symmetry);
                *field.get(f) += folded;
                *field.get(g) = Vector::<D>::zeros();
            }
        }
    });
}

/// `out ← Sᵀ M S z`: every particle gathers `z` from its stencil and scatters it back
/// weighted by its mass. Slabs of one colour run in parallel and never share a node (as in
/// P2G), so the sums are in a fixed order.
fn particle_round_trip<const D: usize, K: Kernel>(
    grid: &Grid<D>,
    particles: &Particles<D>,
    bins: &SlabBins,
    z: SharedSlice<Vector<D>>,
    out: SharedSlice<Vector<D>>,
) {
    let zero = Vector::<D>::zeros();
    let blocks = grid.blocks();
    (0..blocks.count()).into_par_iter().for_each(|k| {
        // SAFETY: the blocks are disjoint node ranges.
        unsafe { out.range(blocks.range(k)) }.fill(zero);
    });
    let stride = grid.stride;
    for colour in 0..2 {
        (0..bins.slab_count())
            .into_par_iter()
            .filter(|s| s % 2 == colour)
            .for_each(|slab| {
                for &p in bins.slab(slab) {
                    let p = p as usize;
                    let half = if K::USES_PARTICLE_SIZE {
                        particles.half_size[p]
                    } else {
                        0.0
                    };
                    let stencil = Stencil::<D>::new::<K>(grid, &particles.position[p], half);
                    let mut at_particle = zero;
                    // SAFETY: `z` is only read during the pass; the slab colouring gives
                    // this task exclusive access to the nodes of `out` its particles touch.
                    stencil.for_each::<K>(&stride, |i, w, _, _| {
                        at_particle += unsafe { *z.get(i) } * w;
                    });
                    let carried = at_particle * particles.mass[p];
                    stencil.for_each::<K>(&stride, |i, w, _, _| unsafe {
                        *out.get(i) += carried * w;
                    });
                }
            });
    }
}

/// `field ← m⁻¹ field` on the nodes in use (zero where there is no mass).
fn divide_by_mass<const D: usize>(grid: &Grid<D>, field: SharedSlice<Vector<D>>) {
    let zero = Vector::<D>::zeros();
    let (blocks, mass) = (grid.blocks(), &grid.mass);
    (0..blocks.count()).into_par_iter().for_each(|k| {
        let range = blocks.range(k);
        // SAFETY: the blocks are disjoint node ranges.
        let trip = unsafe { field.range(range.clone()) };
        for (value, i) in trip.iter_mut().zip(range) {
            let m = mass[i];
            *value = if m > 0.0 { *value / m } else { zero };
        }
    });
}
