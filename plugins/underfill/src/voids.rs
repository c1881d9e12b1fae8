//! Voids: air regions the liquid has cut off from every vent. Each step the air cells (open
//! and not full) are grouped into connected regions; a region with no vent cell is a void.
//! A void keeps its identity from step to step through the cells it shares with the last
//! step's void, and its trapped air may resist as an ideal gas (p·V constant).

use crate::front::{CLOSED, EMPTY, FULL, FlowState};
use crate::lattice::{DIRECTIONS, Lattice};
use crate::parameters::Air;

const NONE: u32 = u32::MAX;

/// Columns of the `underfill_voids` table.
pub(crate) const VOID_COLUMNS: [&str; 9] = [
    "id",
    "closed_time",
    "x",
    "y",
    "area",
    "closed_area",
    "volume",
    "pressure",
    "filled_time",
];

/// One void over its life.
#[derive(Clone, Debug)]
pub(crate) struct VoidRecord {
    /// Number, from 0 in order of closing.
    pub id: u32,
    /// Time it was enclosed, s.
    pub closed_time: f64,
    /// Centroid of its air, m.
    pub centroid: [f64; 2],
    /// Air area in the plane of the scene now, m² (0 once filled).
    pub area: f64,
    /// Air area when it closed, m².
    pub closed_area: f64,
    /// Air volume now, m³ (per metre of depth in a cross-section).
    pub volume: f64,
    /// Air volume when it closed, m³.
    pub closed_volume: f64,
    /// Gauge pressure of its air, Pa.
    pub pressure: f64,
    /// Time its last air went, s (NaN while it holds air).
    pub filled_time: f64,
}

impl VoidRecord {
    /// Writes the table row, in [`VOID_COLUMNS`] order, into `row` (reusing its storage).
    pub fn write_row(&self, row: &mut Vec<f64>) {
        row.clear();
        row.extend_from_slice(&[
            self.id as f64,
            self.closed_time,
            self.centroid[0],
            self.centroid[1],
            self.area,
            self.closed_area,
            self.volume,
            self.pressure,
            self.filled_time,
        ]);
    }
}

/// Air accounting of one step.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct AirSummary {
    /// Air volume still connected to a vent, m³.
    pub vented_volume: f64,
    /// Air volume in voids, m³.
    pub trapped_volume: f64,
    /// Air area in voids, m².
    pub trapped_area: f64,
    /// Voids holding air.
    pub voids: usize,
    /// Whether a void closed, merged or filled this step.
    pub changed: bool,
}

/// Region labelling and void records.
pub(crate) struct VoidTracker {
    /// Void id of each cell at the last step.
    void_of_cell: Vec<u32>,
    region: Vec<u32>,
    queue: Vec<u32>,
    /// Every void so far.
    pub records: Vec<VoidRecord>,
    claimed: Vec<bool>,
}

/// One connected air region.
#[derive(Default)]
struct Region {
    vented: bool,
    volume: f64,
    area: f64,
    moment: [f64; 2],
    previous: u32,
}

impl VoidTracker {
    /// Empty tracker for `n` cells.
    pub fn new(n: usize) -> Self {
        Self {
            void_of_cell: vec![NONE; n],
            region: vec![NONE; n],
            queue: Vec::with_capacity(n),
            records: Vec::new(),
            claimed: Vec::new(),
        }
    }

    /// Labels the air regions, updates the void records at `time` and sets the air gauge
    /// pressure of every cell (ideal gas in voids when `gas` is set, else 0).
    pub fn update(
        &mut self,
        lattice: &Lattice,
        state: &mut FlowState,
        time: f64,
        air: &Air,
    ) -> AirSummary {
        let (ambient, gas) = (air.ambient_pressure, air.trapped_gas);
        // Frozen void cells from the last step take part in the labelling again.
        let smallest = air.min_void_area.unwrap_or(2.0 * lattice.dx * lattice.dx);
        let n = lattice.len();
        let is_air =
            |state: &FlowState, c: usize| state.state[c] != CLOSED && state.state[c] != FULL;
        self.region.iter_mut().for_each(|r| *r = NONE);
        let mut summary = AirSummary::default();
        self.claimed.clear();
        self.claimed.resize(self.records.len(), false);
        let area_of =
            |c: usize, fill: f64| (1.0 - fill.min(1.0)) * lattice.open[c] * lattice.dx * lattice.dx;
        let mut label = 0u32;
        for start in 0..n {
            if self.region[start] != NONE || !is_air(state, start) {
                continue;
            }
            // Flood the region.
            let mut region = Region {
                previous: NONE,
                ..Region::default()
            };
            self.queue.clear();
            self.queue.push(start as u32);
            self.region[start] = label;
            let mut head = 0;
            while head < self.queue.len() {
                let c = self.queue[head] as usize;
                head += 1;
                let fill = state.fill[c];
                let a = area_of(c, fill);
                region.area += a;
                region.volume += (1.0 - fill.min(1.0)) * lattice.volume(c);
                let x = lattice.centre(c);
                region.moment[0] += a * x[0];
                region.moment[1] += a * x[1];
                region.vented |= lattice.vented[c];
                let prev = self.void_of_cell[c];
                if prev != NONE && region.previous == NONE && !self.claimed[prev as usize] {
                    region.previous = prev;
                }
                for (axis, upper) in DIRECTIONS {
                    if let Some(nb) = lattice.neighbour(c, axis, upper)
                        && self.region[nb] == NONE
                        && is_air(state, nb)
                    {
                        self.region[nb] = label;
                        self.queue.push(nb as u32);
                    }
                }
            }
            if region.vented || (region.previous == NONE && region.area < smallest) {
                // Vented, or enclosed below the grid's resolution (under two cells of air
                // by default): not reported, offers no resistance.
                summary.vented_volume += region.volume;
                for &c in &self.queue {
                    state.air[c as usize] = 0.0;
                    self.void_of_cell[c as usize] = NONE;
                }
            } else {
                // A void: the same one as last step, or a new one.
                let id = if region.previous != NONE {
                    region.previous
                } else {
                    summary.changed = true;
                    let id = self.records.len() as u32;
                    self.records.push(VoidRecord {
                        id,
                        closed_time: time,
                        centroid: [0.0; 2],
                        area: region.area,
                        closed_area: region.area,
                        volume: region.volume,
                        closed_volume: region.volume,
                        pressure: 0.0,
                        filled_time: f64::NAN,
                    });
                    self.claimed.push(false);
                    id
                };
                self.claimed[id as usize] = true;
                let record = &mut self.records[id as usize];
                record.area = region.area;
                record.volume = region.volume;
                if region.area > 0.0 {
                    record.centroid = [
                        region.moment[0] / region.area,
                        region.moment[1] / region.area,
                    ];
                }
                // Trapped gas is held at its enclosed volume: at capillary pressures
                // (~kPa) against an ambient ~100 kPa an ideal gas would give up ~1% of it,
                // and an explicit gas pressure would make the step follow the stiffness of
                // the smallest void. Its cells leave the flow (their fill stays).
                record.pressure = if gas && record.closed_volume > 0.0 {
                    let v = region.volume.max(1e-3 * record.closed_volume);
                    ambient * (record.closed_volume / v - 1.0)
                } else {
                    0.0
                };
                for &c in &self.queue {
                    let c = c as usize;
                    state.air[c] = 0.0;
                    self.void_of_cell[c] = id;
                    if gas {
                        state.state[c] = EMPTY;
                    }
                }
                summary.trapped_volume += region.volume;
                summary.trapped_area += region.area;
                summary.voids += 1;
            }
            label += 1;
        }
        // Voids that lost all their air (or merged into another) this step.
        for (record, claimed) in self.records.iter_mut().zip(&self.claimed) {
            if !claimed && record.filled_time.is_nan() {
                record.filled_time = time;
                record.area = 0.0;
                record.volume = 0.0;
                summary.changed = true;
            }
        }
        // Cells that hold no air any more belong to no void.
        for c in 0..n {
            if self.region[c] == NONE {
                self.void_of_cell[c] = NONE;
            }
        }
        summary
    }
}
