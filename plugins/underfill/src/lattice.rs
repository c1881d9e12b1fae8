//! The control volumes of the flow: the background grid's cells, with the open fraction of
//! each (where the gap's particles are, less the solder bumps) and its links to the domain
//! faces (reservoirs and vents).

use crate::parameters::{BumpArray, FlowMode, Reservoir, VentRegion};
use mpm_core::scene::Side;

/// Cells with less open space than this take no part in the flow.
pub(crate) const MIN_OPEN: f64 = 0.02;

/// Coefficient a of the bump walls' drag 1 − a·h/(P − D) on the gap's conductance inside
/// a bump array, from the resolved 3D flow through one cell of a square array (D = 100 µm
/// bumps in a 50 µm gap): its permeability over potential flow's (Rayleigh) is 0.80, 0.90
/// and 0.955 at pitches 150, 200 and 300 µm, which a = 0.2 gives (0.80, 0.90, 0.95). It was
/// 0.63, a rectangular duct's correction for a channel as wide as the throat all along,
/// which made the array 2.4× too resistive at 150 µm (README, "The bump closure").
pub(crate) const BUMP_WALL_DRAG: f64 = 0.2;

/// Offsets of the four face neighbours: −x, +x, −y, +y.
pub(crate) const DIRECTIONS: [(usize, bool); 4] = [(0, false), (0, true), (1, false), (1, true)];

/// A cell face on a reservoir: liquid at a fixed gauge pressure behind it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ReservoirLink {
    /// The cell.
    pub cell: usize,
    /// Axis of the face normal.
    pub axis: usize,
    /// Whether the face is the cell's upper face along `axis`.
    pub upper: bool,
    /// Liquid gauge pressure, Pa.
    pub pressure: f64,
}

/// Cell geometry: cell `(i, j)` spans `origin + [i, i+1]·dx × [j, j+1]·dx` and has index
/// `i·n[1] + j`, the index of its lower-left grid node's (i, j) pair in a 2D grid's layout
/// of cells.
pub(crate) struct Lattice {
    /// Cells along x and y.
    pub n: [usize; 2],
    /// Lower corner of cell (0, 0).
    pub origin: [f64; 2],
    /// Cell size.
    pub dx: f64,
    /// Open fraction of each cell (0: closed, 1: entirely open gap).
    pub open: Vec<f64>,
    /// Capillary pressure 2σcosθ/h (+ bump walls) of a meniscus in each cell, Pa.
    pub capillary: Vec<f64>,
    /// Gap height at each cell, m (gap-averaged: the plate spacing; cross-section: 1, the
    /// unit depth of the section).
    pub depth: Vec<f64>,
    /// Factor on the gap conductance h³/12μ of each cell: the drag of the bump walls across
    /// a throat between bumps, 1 − [`BUMP_WALL_DRAG`]·h/(P − D) inside a bump array, 1
    /// elsewhere.
    pub drag: Vec<f64>,
    /// Faces on reservoirs.
    pub reservoirs: Vec<ReservoirLink>,
    /// Whether a cell touches a vent face.
    pub vented: Vec<bool>,
    /// First and one-past-last domain cell along each axis.
    pub domain: [[usize; 2]; 2],
}

impl Lattice {
    /// Cell count.
    pub fn len(&self) -> usize {
        self.n[0] * self.n[1]
    }

    /// Index stride along `axis`.
    #[inline]
    pub fn stride(&self, axis: usize) -> usize {
        if axis == 0 { self.n[1] } else { 1 }
    }

    /// (i, j) of a cell.
    #[inline]
    pub fn coords(&self, c: usize) -> [usize; 2] {
        [c / self.n[1], c % self.n[1]]
    }

    /// The face neighbour of `c` in direction (`axis`, `upper`), if inside the lattice.
    #[inline]
    pub fn neighbour(&self, c: usize, axis: usize, upper: bool) -> Option<usize> {
        let ij = self.coords(c);
        if upper {
            (ij[axis] + 1 < self.n[axis]).then(|| c + self.stride(axis))
        } else {
            (ij[axis] > 0).then(|| c - self.stride(axis))
        }
    }

    /// Whether a cell takes part in the flow.
    #[inline]
    pub fn is_open(&self, c: usize) -> bool {
        self.open[c] >= MIN_OPEN
    }

    /// Open volume of a cell, m³ (per metre of depth in a cross-section).
    #[inline]
    pub fn volume(&self, c: usize) -> f64 {
        self.open[c] * self.dx * self.dx * self.depth[c]
    }

    /// Centre of a cell.
    pub fn centre(&self, c: usize) -> [f64; 2] {
        let ij = self.coords(c);
        [
            self.origin[0] + (ij[0] as f64 + 0.5) * self.dx,
            self.origin[1] + (ij[1] as f64 + 0.5) * self.dx,
        ]
    }

    /// The cell holding point `x`, if inside the lattice.
    #[inline]
    pub fn cell_of(&self, x: [f64; 2]) -> Option<usize> {
        let mut ij = [0usize; 2];
        for a in 0..2 {
            let s = ((x[a] - self.origin[a]) / self.dx).floor();
            if !(s >= 0.0 && (s as usize) < self.n[a]) {
                return None;
            }
            ij[a] = s as usize;
        }
        Some(ij[0] * self.n[1] + ij[1])
    }
}

/// What the lattice is built from.
pub(crate) struct LatticeInput<'a> {
    /// Cells along x and y, lower corner and size (the grid's).
    pub n: [usize; 2],
    /// Lower corner of the grid.
    pub origin: [f64; 2],
    /// Cell size.
    pub dx: f64,
    /// The scene's domain box.
    pub domain: ([f64; 2], [f64; 2]),
    /// Particles of the gap: positions and volumes.
    pub particles: &'a [([f64; 2], f64)],
    /// Flow mode.
    pub mode: FlowMode,
    /// σ·cosθ, N/m.
    pub wetting_tension: f64,
    /// Gap height (gap-averaged), or the plate spacing for the capillary pressure
    /// (cross-section; measured from the geometry when absent).
    pub gap: Option<f64>,
    /// Cross-section: axis across the gap.
    pub gap_axis: usize,
    /// Bump array (gap-averaged).
    pub bumps: Option<&'a BumpArray>,
    /// Reservoirs.
    pub reservoirs: &'a [Reservoir],
    /// Vent faces.
    pub vents: &'a [Side],
    /// Cross-section boxes that vent across the plane.
    pub vent_regions: &'a [VentRegion],
}

/// Builds the lattice.
pub(crate) fn build(input: &LatticeInput<'_>) -> Lattice {
    let n = input.n;
    let dx = input.dx;
    let count = n[0] * n[1];
    let mut covered = vec![0.0f64; count];
    let mut lattice = Lattice {
        n,
        origin: input.origin,
        dx,
        open: vec![0.0; count],
        capillary: vec![0.0; count],
        depth: vec![1.0; count],
        drag: vec![1.0; count],
        reservoirs: Vec::new(),
        vented: vec![false; count],
        domain: [[0, 0]; 2],
    };
    for &(x, v) in input.particles {
        if let Some(c) = lattice.cell_of(x) {
            covered[c] += v;
        }
    }
    let area = dx * dx;
    for (open, covered) in lattice.open.iter_mut().zip(&covered) {
        let phi = (covered / area).min(1.0);
        *open = match input.mode {
            // A cross-section cell is wall or liquid space, nothing between.
            FlowMode::CrossSection => {
                if phi >= 0.5 {
                    1.0
                } else {
                    0.0
                }
            }
            FlowMode::GapAveraged => phi,
        };
    }
    if let Some(b) = input.bumps {
        cut_bumps(&mut lattice, b);
    }
    for (a, range) in lattice.domain.iter_mut().enumerate() {
        let lo = ((input.domain.0[a] - input.origin[a]) / dx)
            .round()
            .max(0.0) as usize;
        let hi = ((input.domain.1[a] - input.origin[a]) / dx - 1e-9)
            .ceil()
            .max(0.0) as usize;
        *range = [lo, hi.min(n[a])];
    }
    // Capillary pressure and depth.
    match input.mode {
        FlowMode::GapAveraged => {
            let h = input.gap.unwrap_or(1.0);
            let wetting = input.bumps.filter(|b| b.wetting);
            for c in 0..count {
                lattice.depth[c] = h;
                let mut curvature = 2.0 / h;
                let x = lattice.centre(c);
                let in_array = |b: &BumpArray| (0..2).all(|a| x[a] >= b.min[a] && x[a] <= b.max[a]);
                if let Some(b) = wetting
                    && in_array(b)
                {
                    curvature += b.wetted_perimeter_per_area();
                }
                if let Some(b) = input.bumps
                    && in_array(b)
                {
                    lattice.drag[c] = (1.0 - BUMP_WALL_DRAG * h / (b.pitch - b.diameter)).max(0.05);
                }
                lattice.capillary[c] = input.wetting_tension * curvature;
            }
        }
        FlowMode::CrossSection => {
            let a = input.gap_axis;
            let other = 1 - a;
            // Open run across the gap through each cell.
            for line in 0..n[other] {
                let mut k = 0;
                while k < n[a] {
                    let at = |k: usize| {
                        let mut ij = [0; 2];
                        ij[a] = k;
                        ij[other] = line;
                        ij[0] * n[1] + ij[1]
                    };
                    if !lattice.is_open(at(k)) {
                        k += 1;
                        continue;
                    }
                    let start = k;
                    while k < n[a] && lattice.is_open(at(k)) {
                        k += 1;
                    }
                    let h = input.gap.unwrap_or((k - start) as f64 * dx);
                    for m in start..k {
                        lattice.capillary[at(m)] = 2.0 * input.wetting_tension / h;
                    }
                }
            }
        }
    }
    // Reservoir and vent faces.
    for c in 0..count {
        if !lattice.is_open(c) {
            continue;
        }
        let ij = lattice.coords(c);
        let centre = lattice.centre(c);
        for (axis, upper) in DIRECTIONS {
            let on_face = if upper {
                ij[axis] + 1 == lattice.domain[axis][1]
            } else {
                ij[axis] == lattice.domain[axis][0]
            };
            if !on_face {
                continue;
            }
            let side = side_of(axis, upper);
            for r in input.reservoirs {
                let along = centre[1 - axis];
                let in_span = r.span.is_none_or(|[s0, s1]| along >= s0 && along <= s1);
                if r.sides.contains(&side) && in_span {
                    lattice.reservoirs.push(ReservoirLink {
                        cell: c,
                        axis,
                        upper,
                        pressure: r.pressure,
                    });
                }
            }
            if input.vents.contains(&side) {
                lattice.vented[c] = true;
            }
        }
    }
    for c in 0..count {
        if lattice.is_open(c)
            && input
                .vent_regions
                .iter()
                .any(|r| r.contains(lattice.centre(c)))
        {
            lattice.vented[c] = true;
        }
    }
    lattice
}

/// The domain face on `axis`, lower or upper.
pub(crate) fn side_of(axis: usize, upper: bool) -> Side {
    match (axis, upper) {
        (0, false) => Side::XMin,
        (0, true) => Side::XMax,
        (1, false) => Side::YMin,
        (1, true) => Side::YMax,
        (2, false) => Side::ZMin,
        _ => Side::ZMax,
    }
}

/// Removes the area of every bump from the open fraction (8×8 samples per cell).
fn cut_bumps(lattice: &mut Lattice, bumps: &BumpArray) {
    const SAMPLES: usize = 8;
    let r = 0.5 * bumps.diameter;
    let dx = lattice.dx;
    for centre in bumps.centres() {
        let lo = lattice.cell_of([centre[0] - r, centre[1] - r]);
        let hi = lattice.cell_of([centre[0] + r, centre[1] + r]);
        let (Some(lo), Some(hi)) = (lo, hi) else {
            continue;
        };
        let (lo, hi) = (lattice.coords(lo), lattice.coords(hi));
        for i in lo[0]..=hi[0] {
            for j in lo[1]..=hi[1] {
                let c = i * lattice.n[1] + j;
                let x0 = lattice.origin[0] + i as f64 * dx;
                let y0 = lattice.origin[1] + j as f64 * dx;
                let mut inside = 0usize;
                for a in 0..SAMPLES {
                    for b in 0..SAMPLES {
                        let x = x0 + (a as f64 + 0.5) * dx / SAMPLES as f64;
                        let y = y0 + (b as f64 + 0.5) * dx / SAMPLES as f64;
                        if (x - centre[0]).powi(2) + (y - centre[1]).powi(2) <= r * r {
                            inside += 1;
                        }
                    }
                }
                let blocked = inside as f64 / (SAMPLES * SAMPLES) as f64;
                lattice.open[c] = (lattice.open[c] - blocked).max(0.0);
            }
        }
    }
}
