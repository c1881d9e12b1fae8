//! Flow resolved in a cross-section of the gap: incompressible Stokes flow with inertia,
//! ρ·∂u/∂t = μ∇²u − ∇p, ∇·u = 0, on a staggered (MAC) arrangement of the cells (pressure at
//! cell centres, each velocity component on the cell faces normal to it).
//!
//! Each step is backward Euler in the velocity with the pressure and the incompressibility
//! solved together, so neither the viscosity nor a sound speed limits the step: the coupled
//! system is numbered along the section's long axis, which keeps it banded, and solved
//! directly ([`crate::banded`]). Walls (closed cells and plain domain faces) are no-slip;
//! the free surface (faces towards air) is stress-free; front cells hold the meniscus
//! pressure (air − 2σcosθ/h); reservoir faces hold the reservoir pressure.

use crate::banded::{BandedMatrix, Singular};
use crate::front::{CLOSED, FRONT, FULL, FlowState};
use crate::lattice::{Lattice, ReservoirLink};

const NONE: u32 = u32::MAX;

/// Work arrays and the velocities kept between steps.
pub(crate) struct CrossSectionWork {
    /// Face velocities (upper x and y face of each cell) of the last step, m/s.
    pub face_velocity: [Vec<f64>; 2],
    /// Velocity (along +axis) at each reservoir face of the last step, m/s.
    pub link_velocity: Vec<f64>,
    pressure_index: Vec<u32>,
    face_index: [Vec<u32>; 2],
    link_index: Vec<u32>,
    /// Links of each cell (at most two: a corner cell), as indices into the lattice's list.
    cell_links: Vec<[u32; 2]>,
    order: Vec<u32>,
    entries: Vec<(u32, u32, f64)>,
    rhs: Vec<f64>,
    matrix: BandedMatrix,
}

impl CrossSectionWork {
    /// Arrays for a lattice.
    pub fn new(lattice: &Lattice) -> Self {
        let n = lattice.len();
        let mut cell_links = vec![[NONE; 2]; n];
        for (l, link) in lattice.reservoirs.iter().enumerate() {
            let slot = &mut cell_links[link.cell];
            if slot[0] == NONE {
                slot[0] = l as u32;
            } else {
                slot[1] = l as u32;
            }
        }
        // Number the cells along the longer axis first, so couplings stay near the diagonal.
        let major = if lattice.n[0] >= lattice.n[1] { 0 } else { 1 };
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.sort_by_key(|&c| {
            let ij = lattice.coords(c as usize);
            (ij[major], ij[1 - major])
        });
        Self {
            face_velocity: [vec![0.0; n], vec![0.0; n]],
            link_velocity: vec![0.0; lattice.reservoirs.len()],
            pressure_index: vec![NONE; n],
            face_index: [vec![NONE; n], vec![NONE; n]],
            link_index: vec![NONE; lattice.reservoirs.len()],
            cell_links,
            order,
            entries: Vec::new(),
            rhs: Vec::new(),
            matrix: BandedMatrix::new(),
        }
    }
}

/// Whether a face of liquid cell `c` towards (`axis`, `upper`) is a no-slip wall: the cell
/// beyond is closed or outside the lattice.
#[inline]
fn beyond_is_wall(
    lattice: &Lattice,
    state: &FlowState,
    c: usize,
    axis: usize,
    upper: bool,
) -> bool {
    lattice
        .neighbour(c, axis, upper)
        .is_none_or(|nb| state.state[nb] == CLOSED)
}

/// Where a neighbouring velocity of a momentum equation comes from.
enum Neighbour {
    /// Another unknown.
    Unknown(u32),
    /// A wall at the given distance in cells (0.5 or 1): the velocity there is zero.
    Wall(f64),
    /// Free surface or open end: zero gradient, no term.
    Free,
}

/// Solves one backward-Euler step of `dt` and sets the face fluxes (per metre of depth),
/// the reservoir fluxes, the inflow and the cell velocities and shear rates.
pub(crate) fn solve_step(
    lattice: &Lattice,
    state: &mut FlowState,
    work: &mut CrossSectionWork,
    density: f64,
    dt: f64,
) -> Result<(), Singular> {
    let n = lattice.len();
    let dx = lattice.dx;
    for c in 0..n {
        if state.state[c] == FRONT {
            state.pressure[c] = state.air[c] - lattice.capillary[c];
        } else if state.state[c] != FULL {
            state.pressure[c] = 0.0;
        }
    }
    // Number the unknowns.
    let mut count = 0u32;
    for slot in work.pressure_index.iter_mut() {
        *slot = NONE;
    }
    for axis in 0..2 {
        for slot in work.face_index[axis].iter_mut() {
            *slot = NONE;
        }
    }
    for slot in work.link_index.iter_mut() {
        *slot = NONE;
    }
    for k in 0..n {
        let c = work.order[k] as usize;
        if !state.is_liquid(c) {
            continue;
        }
        for l in work.cell_links[c] {
            if l != NONE && !lattice.reservoirs[l as usize].upper {
                work.link_index[l as usize] = count;
                count += 1;
            }
        }
        if state.state[c] == FULL {
            work.pressure_index[c] = count;
            count += 1;
        }
        for axis in 0..2 {
            if let Some(nb) = lattice.neighbour(c, axis, true)
                && state.is_liquid(nb)
            {
                work.face_index[axis][c] = count;
                count += 1;
            }
        }
        for l in work.cell_links[c] {
            if l != NONE && lattice.reservoirs[l as usize].upper {
                work.link_index[l as usize] = count;
                count += 1;
            }
        }
    }
    let unknowns = count as usize;
    work.entries.clear();
    work.rhs.clear();
    work.rhs.resize(unknowns, 0.0);
    let inertia = density / dt;
    let h2 = dx * dx;
    let face_neighbour =
        |work: &CrossSectionWork, c: usize, axis: usize, along: usize, upper: bool| {
            // The `axis` face of cell `c` (between c and c+e_axis), its neighbour face in
            // direction (`along`, `upper`).
            if along == axis {
                // The next face along the same axis: the far face of the cell beyond.
                let (near, far) = if upper {
                    (
                        lattice
                            .neighbour(c, axis, true)
                            .expect("face has two cells"),
                        true,
                    )
                } else {
                    (c, false)
                };
                if let Some(next) = lattice.neighbour(near, axis, far) {
                    let owner = if far { near } else { next };
                    let idx = work.face_index[axis][owner];
                    if idx != NONE {
                        return Neighbour::Unknown(idx);
                    }
                }
                // A reservoir face there?
                for l in work.cell_links[near] {
                    if l != NONE {
                        let link = &lattice.reservoirs[l as usize];
                        if link.axis == axis && link.upper == far {
                            let idx = work.link_index[l as usize];
                            if idx != NONE {
                                return Neighbour::Unknown(idx);
                            }
                        }
                    }
                }
                if lattice.neighbour(near, axis, far).is_none()
                    || beyond_is_wall(lattice, state, near, axis, far)
                {
                    return Neighbour::Wall(1.0);
                }
                Neighbour::Free
            } else {
                let b = lattice
                    .neighbour(c, axis, true)
                    .expect("face has two cells");
                let (Some(c2), Some(b2)) = (
                    lattice.neighbour(c, along, upper),
                    lattice.neighbour(b, along, upper),
                ) else {
                    return Neighbour::Wall(0.5);
                };
                let idx = work.face_index[axis][c2];
                if idx != NONE {
                    return Neighbour::Unknown(idx);
                }
                if state.state[c2] == CLOSED || state.state[b2] == CLOSED {
                    Neighbour::Wall(0.5)
                } else {
                    Neighbour::Free
                }
            }
        };
    // Momentum of interior faces.
    for c in 0..n {
        for axis in 0..2 {
            let row = work.face_index[axis][c];
            if row == NONE {
                continue;
            }
            let b = c + lattice.stride(axis);
            let mu = 0.5 * (state.viscosity[c] + state.viscosity[b]);
            let mut diagonal = inertia;
            work.rhs[row as usize] += inertia * work.face_velocity[axis][c];
            for along in 0..2 {
                for upper in [false, true] {
                    match face_neighbour(work, c, axis, along, upper) {
                        Neighbour::Unknown(col) => {
                            diagonal += mu / h2;
                            work.entries.push((row, col, -mu / h2));
                        }
                        Neighbour::Wall(d) => diagonal += mu / (h2 * d),
                        Neighbour::Free => {}
                    }
                }
            }
            work.entries.push((row, row, diagonal));
            // Pressure gradient (p_b − p_a)/dx.
            for (cell, sign) in [(c, -1.0), (b, 1.0)] {
                let col = work.pressure_index[cell];
                if col != NONE {
                    work.entries.push((row, col, sign / dx));
                } else {
                    work.rhs[row as usize] -= sign * state.pressure[cell] / dx;
                }
            }
        }
    }
    // Momentum of reservoir faces.
    for (l, link) in lattice.reservoirs.iter().enumerate() {
        let row = work.link_index[l];
        if row == NONE {
            continue;
        }
        let ReservoirLink {
            cell: c,
            axis,
            upper,
            pressure,
        } = *link;
        let mu = state.viscosity[c];
        let mut diagonal = inertia;
        work.rhs[row as usize] += inertia * work.link_velocity[l];
        // Normal direction: the cell's opposite face, one cell inwards.
        let inward = !upper;
        let opposite = if inward {
            work.face_index[axis][c]
        } else {
            lattice
                .neighbour(c, axis, false)
                .map_or(NONE, |nb| work.face_index[axis][nb])
        };
        if opposite != NONE {
            diagonal += mu / h2;
            work.entries.push((row, opposite, -mu / h2));
        } else if beyond_is_wall(lattice, state, c, axis, inward) {
            diagonal += mu / h2;
        }
        // Tangential: the neighbouring reservoir faces along the domain face.
        let other = 1 - axis;
        for side in [false, true] {
            let nb = lattice.neighbour(c, other, side);
            let nb_link = nb.and_then(|nb| {
                work.cell_links[nb].into_iter().find(|&k| {
                    k != NONE && {
                        let o = &lattice.reservoirs[k as usize];
                        o.axis == axis && o.upper == upper
                    }
                })
            });
            match (nb, nb_link) {
                (_, Some(k)) if work.link_index[k as usize] != NONE => {
                    diagonal += mu / h2;
                    work.entries
                        .push((row, work.link_index[k as usize], -mu / h2));
                }
                (None, _) => diagonal += 2.0 * mu / h2,
                (Some(nb), _) if state.state[nb] == CLOSED => diagonal += 2.0 * mu / h2,
                _ => {}
            }
        }
        work.entries.push((row, row, diagonal));
        // Gradient between the reservoir (at the face) and the cell centre, half a cell.
        let sign = if upper { -1.0 } else { 1.0 };
        let col = work.pressure_index[c];
        if col != NONE {
            work.entries.push((row, col, sign * 2.0 / dx));
        } else {
            work.rhs[row as usize] -= sign * 2.0 * state.pressure[c] / dx;
        }
        work.rhs[row as usize] += sign * 2.0 * pressure / dx;
    }
    // Continuity of full cells: outflow minus inflow, over dx.
    for c in 0..n {
        let row = work.pressure_index[c];
        if row == NONE {
            continue;
        }
        for axis in 0..2 {
            let up = work.face_index[axis][c];
            if up != NONE {
                work.entries.push((row, up, 1.0 / dx));
            }
            if let Some(lo) = lattice.neighbour(c, axis, false) {
                let idx = work.face_index[axis][lo];
                if idx != NONE {
                    work.entries.push((row, idx, -1.0 / dx));
                }
            }
        }
        for l in work.cell_links[c] {
            if l == NONE {
                continue;
            }
            let link = &lattice.reservoirs[l as usize];
            let idx = work.link_index[l as usize];
            if idx != NONE {
                let sign = if link.upper { 1.0 } else { -1.0 };
                work.entries.push((row, idx, sign / dx));
            }
        }
    }
    // Assemble the band and solve.
    let (mut lower, mut upper) = (0usize, 0usize);
    for &(i, j, _) in &work.entries {
        let (i, j) = (i as usize, j as usize);
        if i > j {
            lower = lower.max(i - j);
        } else {
            upper = upper.max(j - i);
        }
    }
    work.matrix.reset(unknowns, lower, upper);
    for &(i, j, v) in &work.entries {
        work.matrix.add(i as usize, j as usize, v);
    }
    if unknowns > 0 {
        work.matrix.factorise()?;
        work.matrix.solve(&mut work.rhs);
    }
    // Read the solution back.
    for c in 0..n {
        let col = work.pressure_index[c];
        if col != NONE {
            state.pressure[c] = work.rhs[col as usize];
        }
        for axis in 0..2 {
            let idx = work.face_index[axis][c];
            let u = if idx != NONE {
                work.rhs[idx as usize]
            } else {
                0.0
            };
            work.face_velocity[axis][c] = u;
            state.flux[axis][c] = u * dx;
        }
    }
    for (l, link) in lattice.reservoirs.iter().enumerate() {
        let idx = work.link_index[l];
        let w = if idx != NONE {
            work.rhs[idx as usize]
        } else {
            0.0
        };
        work.link_velocity[l] = w;
        state.reservoir_flux[l] = if link.upper { -w } else { w } * dx;
    }
    state.gather_inflow(lattice);
    cell_velocities(lattice, state, work);
    Ok(())
}

/// Face velocity of cell `c`'s lower face along `axis` (interior or reservoir face).
fn lower_face_velocity(lattice: &Lattice, work: &CrossSectionWork, c: usize, axis: usize) -> f64 {
    if let Some(lo) = lattice.neighbour(c, axis, false)
        && work.face_index[axis][lo] != NONE
    {
        return work.face_velocity[axis][lo];
    }
    link_velocity(lattice, work, c, axis, false)
}

fn link_velocity(
    lattice: &Lattice,
    work: &CrossSectionWork,
    c: usize,
    axis: usize,
    upper: bool,
) -> f64 {
    for l in work.cell_links[c] {
        if l != NONE {
            let link = &lattice.reservoirs[l as usize];
            if link.axis == axis && link.upper == upper {
                return work.link_velocity[l as usize];
            }
        }
    }
    0.0
}

/// Cell-centred velocities and the shear rate √(2 D:D) from central differences.
fn cell_velocities(lattice: &Lattice, state: &mut FlowState, work: &CrossSectionWork) {
    let n = lattice.len();
    for c in 0..n {
        for axis in 0..2 {
            state.velocity[axis][c] = if state.is_liquid(c) {
                let up = if work.face_index[axis][c] != NONE {
                    work.face_velocity[axis][c]
                } else {
                    link_velocity(lattice, work, c, axis, true)
                };
                0.5 * (up + lower_face_velocity(lattice, work, c, axis))
            } else {
                0.0
            };
        }
    }
    let dx = lattice.dx;
    for c in 0..n {
        if !state.is_liquid(c) {
            state.shear_rate[c] = 0.0;
            continue;
        }
        // ∂u_a/∂x_b by central differences of cell values (0 beyond walls).
        let mut grad = [[0.0; 2]; 2];
        for b in 0..2 {
            let value = |nb: Option<usize>, a: usize| {
                nb.map_or(0.0, |nb| {
                    if state.is_liquid(nb) {
                        state.velocity[a][nb]
                    } else if state.state[nb] == CLOSED {
                        -state.velocity[a][c]
                    } else {
                        state.velocity[a][c]
                    }
                })
            };
            for (a, row) in grad.iter_mut().enumerate() {
                let hi = value(lattice.neighbour(c, b, true), a);
                let lo = value(lattice.neighbour(c, b, false), a);
                row[b] = (hi - lo) / (2.0 * dx);
            }
        }
        let shear = grad[0][1] + grad[1][0];
        state.shear_rate[c] =
            (2.0 * grad[0][0].powi(2) + 2.0 * grad[1][1].powi(2) + shear * shear).sqrt();
    }
}

/// The velocity at a point, interpolated on the staggered faces (linear along the face
/// normal, linear across with a wall's ghost value −u, or the same value at a free surface).
pub(crate) fn sample_velocity(
    lattice: &Lattice,
    state: &FlowState,
    work: &CrossSectionWork,
    x: [f64; 2],
) -> [f64; 2] {
    let Some(c) = lattice.cell_of(x) else {
        return [0.0; 2];
    };
    if !state.is_liquid(c) {
        return [0.0; 2];
    }
    let centre = lattice.centre(c);
    let mut out = [0.0; 2];
    for (axis, value) in out.iter_mut().enumerate() {
        // Along the normal: between the cell's lower and upper face.
        let along = |cell: usize| {
            let up = if work.face_index[axis][cell] != NONE {
                work.face_velocity[axis][cell]
            } else {
                link_velocity(lattice, work, cell, axis, true)
            };
            let lo = lower_face_velocity(lattice, work, cell, axis);
            let s = ((x[axis] - centre[axis]) / lattice.dx + 0.5).clamp(0.0, 1.0);
            lo + s * (up - lo)
        };
        let here = along(c);
        let other = 1 - axis;
        let offset = (x[other] - centre[other]) / lattice.dx;
        let towards_upper = offset >= 0.0;
        let t = offset.abs();
        let there = match lattice.neighbour(c, other, towards_upper) {
            Some(nb) if state.is_liquid(nb) => along(nb),
            Some(nb) if state.state[nb] != CLOSED => here,
            _ => -here,
        };
        *value = here + t * (there - here);
    }
    out
}
