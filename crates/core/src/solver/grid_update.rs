//! Grid update: momentum to velocity, FLIP forces, damping and boundary conditions.
//!
//! Gravity arrives with the momentum (or the FLIP force) from P2G, so stick walls fold it
//! like any other force.

use super::parallel::{SharedSlice, ordered_reduce};
use crate::boundary::Boundaries;
use crate::grid::{Grid, GridArrays, node_coords, node_position};
use crate::math::Vector;

/// What one grid update applies.
#[derive(Clone, Copy, Debug)]
pub struct GridParams<const D: usize> {
    /// Time step, seconds.
    pub dt: f64,
    /// Apply forces, gravity and damping (false: only turn momentum into velocity and
    /// apply boundary conditions, as after a velocity remap).
    pub forces: bool,
    /// Forces are in `grid.force` (FLIP) and the pre-force velocity is kept.
    pub flip: bool,
    /// Velocity damping rate, 1/s.
    pub damping: f64,
    /// Time at the end of the step (obstacles move).
    pub time: f64,
}

/// The energy a grid update exchanged with the bodies, J (J/m in 2D).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GridWork {
    /// Work moving obstacles did on the nodes (fixed walls do none: what they take away
    /// is the method's impact loss, or friction, booked apart).
    pub boundaries: f64,
    /// Kinetic energy the velocity damping removed.
    pub damping: f64,
    /// Kinetic energy Coulomb friction at walls and obstacles took from the motion along
    /// them.
    pub friction: f64,
}

/// The kinetic energy a velocity damping factor `damping` (< 1, this step's) took from the
/// velocities the grid's nodes now have, ½ m |v|² (1/d² − 1) summed: for a multi-field
/// step, whose contact laws change the velocities after the grid update, so that only
/// motion the bodies keep is booked (not the relative velocity a bond or contact removes).
pub fn damped_energy<const D: usize>(grid: &Grid<D>, damping: f64) -> f64 {
    if damping >= 1.0 {
        return 0.0;
    }
    let factor = 1.0 / (damping * damping) - 1.0;
    const CHUNK: usize = 4096;
    let (mass, velocity) = (&grid.mass, &grid.momentum);
    ordered_reduce(
        mass.len().div_ceil(CHUNK),
        || 0.0,
        |chunk| {
            (chunk * CHUNK..((chunk + 1) * CHUNK).min(mass.len()))
                .filter(|&i| mass[i] > 0.0)
                .map(|i| 0.5 * mass[i] * velocity[i].norm_squared() * factor)
                .sum::<f64>()
        },
        |a, b| a + b,
    )
}

/// Turns nodal momentum into velocity in place and applies forces and boundary conditions.
/// Returns the work moving obstacles did and the energy damping removed, for the energy
/// ledger.
pub fn update_grid<const D: usize>(
    grid: &mut Grid<D>,
    boundaries: &Boundaries<D>,
    params: GridParams<D>,
) -> GridWork {
    // A sparse grid's active blocks are those the transfer just wrote.
    grid.take_marks();
    boundaries.fold_stick_walls(grid);
    let damping = (-params.damping * params.dt).exp();
    let (origin, dx, stride) = (grid.origin, grid.dx, grid.stride);
    let GridArrays {
        blocks,
        mass,
        momentum,
        force,
        velocity_old,
    } = grid.split_for_update();
    let old_out = SharedSlice::new(velocity_old);
    let momentum = SharedSlice::new(momentum);
    let work = ordered_reduce(
        blocks.count(),
        || (0.0, 0.0, 0.0),
        |unit| {
            let range = blocks.range(unit);
            let start = range.start;
            // SAFETY: the units are disjoint node ranges.
            let velocities = unsafe { momentum.range(range) };
            let (mut work, mut damped, mut friction) = (0.0, 0.0, 0.0);
            for (k, v) in velocities.iter_mut().enumerate() {
                let i = start + k;
                let m = mass[i];
                if m <= 0.0 {
                    *v = Vector::<D>::zeros();
                    continue;
                }
                *v /= m;
                if params.flip {
                    // SAFETY: the units' node ranges are disjoint.
                    unsafe { *old_out.get(i) = *v };
                }
                if params.forces && params.flip {
                    *v += force[i] * (params.dt / m);
                }
                let damps = params.forces && damping < 1.0;
                if damps {
                    *v *= damping;
                }
                let mut surface_work = 0.0;
                if !boundaries.is_empty() {
                    let ijk = node_coords(&stride, i);
                    let x = node_position(&origin, dx, ijk);
                    let booked = boundaries.apply_booked(ijk, &x, params.time, m, v);
                    surface_work = booked.work;
                    work += surface_work;
                    friction += booked.friction;
                }
                if damps && surface_work == 0.0 {
                    // What damping took from the velocity the node keeps: fixed walls act
                    // linearly, so the wall-constrained part of the damped velocity (a
                    // clamp's reaction, say) was never motion and is not booked; where a
                    // moving obstacle set the velocity, its work term books the change.
                    damped += 0.5 * m * v.norm_squared() * (1.0 / (damping * damping) - 1.0);
                }
            }
            (work, damped, friction)
        },
        |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2),
    );
    boundaries.mirror_stick_walls(grid);
    GridWork {
        boundaries: work.0,
        damping: work.1,
        friction: work.2,
    }
}
