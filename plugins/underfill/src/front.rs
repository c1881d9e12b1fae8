//! The liquid on the cells: fill fractions, cell states (full, front, empty), the advance of
//! the fill by the fluxes of a flow solve, and the step that keeps it stable.

use crate::lattice::{DIRECTIONS, Lattice};

/// Outside the gap (a bump, a wall, no particles).
pub(crate) const CLOSED: u8 = 0;
/// Open, holding air (possibly some liquid not yet connected to the flow).
pub(crate) const EMPTY: u8 = 1;
/// Open, partly filled, next to the liquid: holds the meniscus.
pub(crate) const FRONT: u8 = 2;
/// Full of liquid.
pub(crate) const FULL: u8 = 3;

/// A cell counts as full above this fill fraction.
pub(crate) const FULL_AT: f64 = 1.0 - 1e-9;

/// Liquid and flow on the cells, kept between steps.
pub(crate) struct FlowState {
    /// Liquid volume / open volume of each cell.
    pub fill: Vec<f64>,
    /// [`CLOSED`], [`EMPTY`], [`FRONT`] or [`FULL`].
    pub state: Vec<u8>,
    /// Liquid gauge pressure, Pa (solved in full cells, the meniscus value in front cells).
    pub pressure: Vec<f64>,
    /// Gauge pressure of the air in each cell's air region, Pa (0 where vented).
    pub air: Vec<f64>,
    /// Viscosity of each cell, Pa·s.
    pub viscosity: Vec<f64>,
    /// Characteristic shear rate of each cell from the last solve, 1/s.
    pub shear_rate: Vec<f64>,
    /// Volume rate across each cell's upper face along x and y, m³/s (per metre of depth in
    /// a cross-section); positive towards +axis.
    pub flux: [Vec<f64>; 2],
    /// Volume rate into the cell of each reservoir link, m³/s.
    pub reservoir_flux: Vec<f64>,
    /// Net volume rate into each cell, m³/s.
    pub inflow: Vec<f64>,
    /// Mean liquid velocity at each cell centre, m/s.
    pub velocity: [Vec<f64>; 2],
    /// Whether a cell has a reservoir face.
    pub at_reservoir: Vec<bool>,
    /// Liquid that found no room when a cell overfilled, m³ (a conservation check).
    pub lost_volume: f64,
}

impl FlowState {
    /// Zero flow; fill from `fill`.
    pub fn new(lattice: &Lattice, fill: Vec<f64>) -> Self {
        let n = lattice.len();
        let mut at_reservoir = vec![false; n];
        for r in &lattice.reservoirs {
            at_reservoir[r.cell] = true;
        }
        let mut s = Self {
            fill,
            state: vec![CLOSED; n],
            pressure: vec![0.0; n],
            air: vec![0.0; n],
            viscosity: vec![0.0; n],
            shear_rate: vec![0.0; n],
            flux: [vec![0.0; n], vec![0.0; n]],
            reservoir_flux: vec![0.0; lattice.reservoirs.len()],
            inflow: vec![0.0; n],
            velocity: [vec![0.0; n], vec![0.0; n]],
            at_reservoir,
            lost_volume: 0.0,
        };
        s.classify(lattice);
        s
    }

    /// Whether a cell holds connected liquid (full or front).
    #[inline]
    pub fn is_liquid(&self, c: usize) -> bool {
        self.state[c] >= FRONT
    }

    /// Sets the cell states from the fill: full, then front (open, not full, next to a full
    /// cell or a reservoir), else empty or closed.
    pub fn classify(&mut self, lattice: &Lattice) {
        for c in 0..lattice.len() {
            self.state[c] = if !lattice.is_open(c) {
                CLOSED
            } else if self.fill[c] >= FULL_AT {
                FULL
            } else {
                EMPTY
            };
        }
        for c in 0..lattice.len() {
            if self.state[c] != EMPTY {
                continue;
            }
            let wetted = self.at_reservoir[c]
                || DIRECTIONS.iter().any(|&(axis, upper)| {
                    lattice
                        .neighbour(c, axis, upper)
                        .is_some_and(|nb| self.state[nb] == FULL)
                });
            if wetted {
                self.state[c] = FRONT;
            }
        }
    }

    /// Net inflow of every cell from the face and reservoir fluxes.
    pub fn gather_inflow(&mut self, lattice: &Lattice) {
        for c in 0..lattice.len() {
            let mut q = 0.0;
            for axis in 0..2 {
                q -= self.flux[axis][c];
                if let Some(lower) = lattice.neighbour(c, axis, false) {
                    q += self.flux[axis][lower];
                }
            }
            self.inflow[c] = q;
        }
        for (link, q) in lattice.reservoirs.iter().zip(&self.reservoir_flux) {
            self.inflow[link.cell] += q;
        }
    }

    /// Time to fill a whole cell (open or not: cells cut by bumps pass their overflow on)
    /// at the fastest front cell's inflow, s (infinite when nothing fills).
    pub fn fill_time_scale(&self, lattice: &Lattice) -> f64 {
        let mut dt = f64::INFINITY;
        for c in 0..lattice.len() {
            if self.state[c] != FRONT {
                continue;
            }
            let whole = lattice.dx * lattice.dx * lattice.depth[c];
            if self.inflow[c] > 0.0 {
                dt = dt.min(whole / self.inflow[c]);
            } else if self.inflow[c] < 0.0 && self.fill[c] > 0.0 {
                // Draining (trapped air pushing back): do not empty more than the cell holds.
                dt = dt.min(self.fill[c].max(0.1) * whole / -self.inflow[c]);
            }
        }
        dt
    }

    /// Advances the fill of the front cells by `dt` with the current inflow. Liquid beyond
    /// a full cell goes on to its open, not-full neighbours (in proportion to their room);
    /// what finds no room is counted in [`Self::lost_volume`].
    pub fn advance(&mut self, lattice: &Lattice, dt: f64) {
        for c in 0..lattice.len() {
            if self.state[c] == FRONT {
                let v = lattice.volume(c);
                self.fill[c] = (self.fill[c] + dt * self.inflow[c] / v).max(0.0);
            }
        }
        for c in 0..lattice.len() {
            if self.state[c] != FRONT || self.fill[c] <= 1.0 {
                continue;
            }
            let v = lattice.volume(c);
            let mut excess = (self.fill[c] - 1.0) * v;
            self.fill[c] = 1.0;
            let mut room = 0.0;
            for (axis, upper) in DIRECTIONS {
                if let Some(nb) = lattice.neighbour(c, axis, upper)
                    && lattice.is_open(nb)
                    && self.fill[nb] < 1.0
                {
                    room += (1.0 - self.fill[nb]) * lattice.volume(nb);
                }
            }
            if room > 0.0 {
                let share = (excess / room).min(1.0);
                for (axis, upper) in DIRECTIONS {
                    if let Some(nb) = lattice.neighbour(c, axis, upper)
                        && lattice.is_open(nb)
                        && self.fill[nb] < 1.0
                    {
                        let add = share * (1.0 - self.fill[nb]);
                        excess -= add * lattice.volume(nb);
                        self.fill[nb] += add;
                    }
                }
            }
            self.lost_volume += excess.max(0.0);
        }
        self.classify(lattice);
    }

    /// Liquid volume and open volume of the gap, m³.
    pub fn volumes(&self, lattice: &Lattice) -> (f64, f64) {
        let (mut liquid, mut open) = (0.0, 0.0);
        for c in 0..lattice.len() {
            if lattice.is_open(c) {
                let v = lattice.volume(c);
                liquid += self.fill[c].min(1.0) * v;
                open += v;
            }
        }
        (liquid, open)
    }
}
