//! Gap-averaged (Hele-Shaw) flow: the mean velocity across the gap is −(h²/12μ)·∇p, so
//! the volume rate between two cells is K·(p_a − p_b) with K = h³/12μ (harmonic mean of the
//! two cells, times the narrower open fraction). Mass conservation in the full cells gives
//! a symmetric positive definite system for their pressures, solved by conjugate gradients;
//! front cells hold the meniscus pressure (air pressure − capillary pressure), placed at
//! the meniscus inside the cell (its fill fraction says how far), and reservoir faces hold
//! the reservoir pressure.

use crate::front::{FRONT, FULL, FlowState};
use crate::lattice::Lattice;
use mpm_core::linear_solvers::conjugate_gradient::{Work, solve};

/// Work arrays of the pressure solve, one number per cell each.
pub(crate) struct HeleShawWork {
    /// Conductance across each cell's upper face along x and y (0: no flow), m³/(s·Pa).
    conductance: [Vec<f64>; 2],
    diagonal: Vec<f64>,
    inverse_diagonal: Vec<f64>,
    rhs: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
}

/// How a solve ended.
pub(crate) struct SolveReport {
    /// Conjugate-gradient iterations.
    pub iterations: u32,
    /// Whether it reached the tolerance.
    pub converged: bool,
}

impl HeleShawWork {
    /// Arrays for `n` cells.
    pub fn new(n: usize) -> Self {
        Self {
            conductance: [vec![0.0; n], vec![0.0; n]],
            diagonal: vec![0.0; n],
            inverse_diagonal: vec![0.0; n],
            rhs: vec![0.0; n],
            r: vec![0.0; n],
            z: vec![0.0; n],
            p: vec![0.0; n],
            ap: vec![0.0; n],
        }
    }
}

/// Distance factor of a face next to a front cell: the meniscus sits `0.5 + f` cells from
/// the liquid neighbour's centre instead of one cell.
#[inline]
fn meniscus_factor(state: &FlowState, c: usize) -> f64 {
    if state.state[c] == FRONT {
        1.0 / (0.5 + state.fill[c]).max(0.5)
    } else {
        1.0
    }
}

/// Solves the pressure of the full cells and sets the face fluxes, the reservoir fluxes,
/// the inflow of every cell and the cell velocities.
pub(crate) fn solve_pressure(
    lattice: &Lattice,
    state: &mut FlowState,
    work: &mut HeleShawWork,
    tolerance: f64,
    max_iterations: u32,
) -> SolveReport {
    let n = lattice.len();
    // Cell conductances h³/12μ and the meniscus pressure of front cells.
    let k_cell =
        |c: usize| lattice.drag[c] * lattice.depth[c].powi(3) / (12.0 * state.viscosity[c]);
    for c in 0..n {
        if state.state[c] == FRONT {
            state.pressure[c] = state.air[c] - lattice.capillary[c];
        } else if state.state[c] != FULL {
            state.pressure[c] = 0.0;
        }
        work.diagonal[c] = 0.0;
        work.rhs[c] = 0.0;
    }
    for axis in 0..2 {
        for c in 0..n {
            let mut g = 0.0;
            if state.is_liquid(c)
                && let Some(nb) = lattice.neighbour(c, axis, true)
                && state.is_liquid(nb)
            {
                let (ka, kb) = (k_cell(c), k_cell(nb));
                let open = lattice.open[c].min(lattice.open[nb]);
                g = 2.0 * ka * kb / (ka + kb) * open;
                // A full cell next to a front cell: the meniscus is nearer or farther than
                // the front cell's centre.
                if state.state[c] == FULL && state.state[nb] == FRONT {
                    g *= meniscus_factor(state, nb);
                } else if state.state[nb] == FULL && state.state[c] == FRONT {
                    g *= meniscus_factor(state, c);
                }
            }
            work.conductance[axis][c] = g;
        }
    }
    // Assemble the diagonal and the Dirichlet right-hand side of the full cells.
    for axis in 0..2 {
        for c in 0..n {
            let g = work.conductance[axis][c];
            if g == 0.0 {
                continue;
            }
            let nb = c + lattice.stride(axis);
            for (me, other) in [(c, nb), (nb, c)] {
                if state.state[me] == FULL {
                    work.diagonal[me] += g;
                    if state.state[other] == FRONT {
                        work.rhs[me] += g * state.pressure[other];
                    }
                }
            }
        }
    }
    let reservoir_conductance = |state: &FlowState, c: usize| {
        // From the cell centre (or the meniscus) to the face: half a cell (or f cells).
        let distance = if state.state[c] == FRONT {
            state.fill[c].max(0.25)
        } else {
            0.5
        };
        k_cell(c) * lattice.open[c] / distance
    };
    for link in &lattice.reservoirs {
        let c = link.cell;
        if state.state[c] == FULL {
            let g = reservoir_conductance(state, c);
            work.diagonal[c] += g;
            work.rhs[c] += g * link.pressure;
        }
    }
    for c in 0..n {
        work.inverse_diagonal[c] = if state.state[c] == FULL && work.diagonal[c] > 0.0 {
            1.0 / work.diagonal[c]
        } else {
            0.0
        };
    }
    let (stride_x, stride_y) = (lattice.stride(0), lattice.stride(1));
    let conductance = &work.conductance;
    let kinds = &state.state;
    let diagonal = &work.diagonal;
    let apply = |x: &[f64], y: &mut [f64]| {
        for c in 0..x.len() {
            if kinds[c] != FULL {
                y[c] = 0.0;
                continue;
            }
            let mut v = diagonal[c] * x[c];
            // Couplings to full neighbours only (front values sit in the right-hand side).
            // A face across the lattice's edge has zero conductance, so an index that
            // wraps to the next row couples nothing.
            for (axis, stride) in [(0, stride_x), (1, stride_y)] {
                if let Some(lower) = c.checked_sub(stride)
                    && kinds[lower] == FULL
                {
                    v -= conductance[axis][lower] * x[lower];
                }
                let upper = c + stride;
                if upper < x.len() && kinds[upper] == FULL {
                    v -= conductance[axis][c] * x[upper];
                }
            }
            y[c] = v;
        }
    };
    let solved = solve(
        apply,
        &work.inverse_diagonal,
        &work.rhs,
        &mut state.pressure,
        Work {
            r: &mut work.r,
            z: &mut work.z,
            p: &mut work.p,
            ap: &mut work.ap,
        },
        tolerance,
        max_iterations,
    );
    // Fluxes.
    for axis in 0..2 {
        for c in 0..n {
            let g = work.conductance[axis][c];
            state.flux[axis][c] = if g > 0.0 {
                g * (state.pressure[c] - state.pressure[c + lattice.stride(axis)])
            } else {
                0.0
            };
        }
    }
    for (i, link) in lattice.reservoirs.iter().enumerate() {
        let c = link.cell;
        state.reservoir_flux[i] = if state.is_liquid(c) {
            reservoir_conductance(state, c) * (link.pressure - state.pressure[c])
        } else {
            0.0
        };
    }
    state.gather_inflow(lattice);
    // Mean velocities at cell centres (flux over the open face area h·dx) and the wall
    // shear rate 6U/h of the gap's parabolic profile.
    for c in 0..n {
        let mut speed2 = 0.0;
        for axis in 0..2 {
            let area = lattice.depth[c] * lattice.dx * lattice.open[c].max(1e-12);
            let upper = state.flux[axis][c];
            let lower = lattice
                .neighbour(c, axis, false)
                .map_or(0.0, |nb| state.flux[axis][nb]);
            let u = if state.is_liquid(c) {
                0.5 * (upper + lower) / area
            } else {
                0.0
            };
            state.velocity[axis][c] = u;
            speed2 += u * u;
        }
        state.shear_rate[c] = 6.0 * speed2.sqrt() / lattice.depth[c];
    }
    SolveReport {
        iterations: solved.iterations,
        converged: solved.converged,
    }
}
