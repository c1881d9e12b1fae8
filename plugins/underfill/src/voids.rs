//! Voids: air regions the liquid has cut off from every vent. Each step the air cells are
//! grouped into connected regions; a region with no vent cell is a void. A void keeps its
//! identity from step to step through the cells it shares with the last step's void. The
//! labelling works on any cells ([`AirCells`]): the gap-averaged lattice, whose trapped
//! air may resist as an ideal gas (p·V constant), and the grid cells of liquid particles
//! (`crate::particle_voids`).

use crate::front::{CLOSED, EMPTY, FULL, FlowState};
use crate::lattice::{DIRECTIONS, Lattice};
use crate::parameters::Air;
use crate::underfill::VOIDS_TABLE;
use mpm_core::physics::PhysicsReport;

/// Cells whose air regions a [`VoidTracker`] labels.
pub(crate) trait AirCells {
    /// Number of cells.
    fn len(&self) -> usize;
    /// Whether cell `c` holds air.
    fn is_air(&self, c: usize) -> bool;
    /// Whether cell `c` touches a vent.
    fn vented(&self, c: usize) -> bool;
    /// The air of cell `c`: its measure (area in a plane scene, volume in 3D: what the
    /// smallest void and the centroid are measured by), its volume, and its centre.
    fn air(&self, c: usize) -> (f64, f64, [f64; 3]);
    /// Calls `f` with each face neighbour of cell `c`.
    fn for_each_neighbour(&self, c: usize, f: impl FnMut(usize));
}

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

/// Columns of the `underfill_voids` table in a 3D scene (2D scenes use [`VOID_COLUMNS`],
/// with the area in the plane and the volume per metre of depth).
pub(crate) const VOID_COLUMNS_3D: [&str; 9] = [
    "id",
    "closed_time",
    "x",
    "y",
    "z",
    "volume",
    "closed_volume",
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
    /// Centroid of its air, m (z is 0 in 2D).
    pub centroid: [f64; 3],
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
    /// Writes the table row into `row` (reusing its storage): in [`VOID_COLUMNS`] order in
    /// a plane scene, in [`VOID_COLUMNS_3D`] order (centroid z, the volume as the measure)
    /// when `three_d`.
    pub fn write_row(&self, row: &mut Vec<f64>, three_d: bool) {
        let [x, y, z] = self.centroid;
        let place_and_size = if three_d {
            [x, y, z, self.volume, self.closed_volume]
        } else {
            [x, y, self.area, self.closed_area, self.volume]
        };
        row.clear();
        row.extend_from_slice(&[self.id as f64, self.closed_time]);
        row.extend_from_slice(&place_and_size);
        row.extend_from_slice(&[self.pressure, self.filled_time]);
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
    /// Whether each air region of the last labelling (by label) reaches a vent.
    region_vented: Vec<bool>,
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
    moment: [f64; 3],
    previous: u32,
}

impl VoidTracker {
    /// Empty tracker for `n` cells.
    pub fn new(n: usize) -> Self {
        Self {
            void_of_cell: vec![NONE; n],
            region: vec![NONE; n],
            region_vented: Vec::new(),
            queue: Vec::with_capacity(n),
            records: Vec::new(),
            claimed: Vec::new(),
        }
    }

    /// Writes every void so far into the `underfill_voids` table of `report` (a row per
    /// void, rewritten while it lives; nothing before the first void).
    pub fn write_table(&self, report: &mut PhysicsReport, three_d: bool) {
        if self.records.is_empty() {
            return;
        }
        let columns: &[&str] = if three_d {
            &VOID_COLUMNS_3D
        } else {
            &VOID_COLUMNS
        };
        let table = report.table_mut(VOIDS_TABLE, columns);
        table.rows.resize_with(self.records.len(), Vec::new);
        for (row, record) in table.rows.iter_mut().zip(&self.records) {
            record.write_row(row, three_d);
        }
    }

    /// The void cell `c` belongs to since the last labelling, if any.
    pub fn void_of(&self, c: usize) -> Option<u32> {
        let id = self.void_of_cell[c];
        (id != NONE).then_some(id)
    }

    /// Whether cell `c` held air at the last labelling.
    pub fn was_air(&self, c: usize) -> bool {
        self.region[c] != NONE
    }

    /// Whether cell `c` held air with a way out to a vent at the last labelling (air
    /// enclosed below the smallest reported void is not vented).
    pub fn vented_air(&self, c: usize) -> bool {
        let r = self.region[c];
        r != NONE && self.region_vented[r as usize]
    }

    /// Labels the gap-averaged lattice's air regions, updates the void records at `time`
    /// and sets the air gauge pressure of every cell (ideal gas in voids when `gas` is
    /// set, else 0); with `gas`, void cells leave the flow (their fill stays).
    pub fn update(
        &mut self,
        lattice: &Lattice,
        state: &mut FlowState,
        time: f64,
        air: &Air,
    ) -> AirSummary {
        let (ambient, gas) = (air.ambient_pressure, air.trapped_gas);
        let smallest = air.min_void_area.unwrap_or(2.0 * lattice.dx * lattice.dx);
        let summary = self.label(&GapCells { lattice, state }, time, smallest);
        for record in self.records.iter_mut().filter(|r| r.filled_time.is_nan()) {
            // Trapped gas is held at its enclosed volume: at capillary pressures (~kPa)
            // against an ambient ~100 kPa an ideal gas would give up ~1% of it, and an
            // explicit gas pressure would make the step follow the stiffness of the
            // smallest void.
            record.pressure = if gas && record.closed_volume > 0.0 {
                let v = record.volume.max(1e-3 * record.closed_volume);
                ambient * (record.closed_volume / v - 1.0)
            } else {
                0.0
            };
        }
        for c in 0..lattice.len() {
            if self.was_air(c) {
                state.air[c] = 0.0;
                if gas && self.void_of(c).is_some() {
                    state.state[c] = EMPTY;
                }
            }
        }
        summary
    }

    /// Labels the air regions of `cells` and updates the void records at `time`: a region
    /// without a vent is a void, the same one as a void it shares a cell with at the last
    /// labelling, else a new one if its measure reaches `smallest`. Voids that lost all
    /// their air (or merged into another) are marked filled.
    pub fn label(&mut self, cells: &impl AirCells, time: f64, smallest: f64) -> AirSummary {
        let n = cells.len();
        self.region.iter_mut().for_each(|r| *r = NONE);
        let mut summary = AirSummary::default();
        self.claimed.clear();
        self.claimed.resize(self.records.len(), false);
        self.region_vented.clear();
        let mut label = 0u32;
        for start in 0..n {
            if self.region[start] != NONE || !cells.is_air(start) {
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
                let (a, v, x) = cells.air(c);
                region.area += a;
                region.volume += v;
                for (m, x) in region.moment.iter_mut().zip(x) {
                    *m += a * x;
                }
                region.vented |= cells.vented(c);
                let prev = self.void_of_cell[c];
                if prev != NONE && region.previous == NONE && !self.claimed[prev as usize] {
                    region.previous = prev;
                }
                let (region_of, queue) = (&mut self.region, &mut self.queue);
                cells.for_each_neighbour(c, |nb| {
                    if region_of[nb] == NONE && cells.is_air(nb) {
                        region_of[nb] = label;
                        queue.push(nb as u32);
                    }
                });
            }
            self.region_vented.push(region.vented);
            if region.vented || (region.previous == NONE && region.area < smallest) {
                // Vented, or enclosed below the resolution (under two cells of air by
                // default): not reported.
                summary.vented_volume += region.volume;
                for &c in &self.queue {
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
                        centroid: [0.0; 3],
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
                    record.centroid = region.moment.map(|m| m / region.area);
                }
                for &c in &self.queue {
                    self.void_of_cell[c as usize] = id;
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

/// The gap-averaged lattice's cells: air where open and not full.
struct GapCells<'a> {
    lattice: &'a Lattice,
    state: &'a FlowState,
}

impl AirCells for GapCells<'_> {
    fn len(&self) -> usize {
        self.lattice.len()
    }

    fn is_air(&self, c: usize) -> bool {
        self.state.state[c] != CLOSED && self.state.state[c] != FULL
    }

    fn vented(&self, c: usize) -> bool {
        self.lattice.vented[c]
    }

    fn air(&self, c: usize) -> (f64, f64, [f64; 3]) {
        let (lattice, empty) = (self.lattice, 1.0 - self.state.fill[c].min(1.0));
        let [x, y] = lattice.centre(c);
        (
            empty * lattice.open[c] * lattice.dx * lattice.dx,
            empty * lattice.volume(c),
            [x, y, 0.0],
        )
    }

    fn for_each_neighbour(&self, c: usize, mut f: impl FnMut(usize)) {
        for (axis, upper) in DIRECTIONS {
            if let Some(nb) = self.lattice.neighbour(c, axis, upper) {
                f(nb);
            }
        }
    }
}
