//! The fill of a region by liquid particles (`physics.liquid_voids.fill_region`, say the
//! gap under a die): its filled fraction (liquid cells over the cells open to liquid), its
//! history in the `underfill_fill` table, and its fill time: the first time no air in the
//! region has a way out to a vent, so that what air remains there is trapped. This is the
//! gap-averaged mode's definition, on the grid cells of the particles.

use crate::particle_cells::GridCells;
use crate::underfill::{FILL_COLUMNS, FILL_TABLE};
use crate::voids::{AirSummary, VoidTracker};
use mpm_core::physics::PhysicsReport;

/// Columns of the fill-history table in a 3D scene: as [`FILL_COLUMNS`], with the trapped
/// air's volume in place of its area.
pub(crate) const FILL_COLUMNS_3D: [&str; 5] = [
    "time",
    "fill_fraction",
    "vented_air_volume",
    "trapped_air_volume",
    "voids",
];

/// The fill of one region, followed from step to step.
pub(crate) struct FillTimer {
    /// The region's cells that are not closed.
    cells: Vec<u32>,
    fill_time: Option<f64>,
    logged_fill: f64,
    logged_voids: usize,
}

impl FillTimer {
    /// The timer of the cells of `grid` whose centres lie in the box `min`–`max`.
    pub fn new(grid: &GridCells, min: [f64; 3], max: [f64; 3]) -> Self {
        let d = grid.dimension;
        let cells = (0..grid.closed.len())
            .filter(|&c| {
                let x = grid.centre(c);
                !grid.closed[c] && (0..d).all(|a| x[a] >= min[a] && x[a] <= max[a])
            })
            .map(|c| c as u32)
            .collect();
        Self {
            cells,
            fill_time: None,
            logged_fill: f64::NEG_INFINITY,
            logged_voids: usize::MAX,
        }
    }

    /// Records the region's fill after `tracker` labelled `grid`'s air at `time`:
    /// `underfill.fill_fraction`, `underfill.fill_time` once filled, and a row of the
    /// fill history when the fill moved by 0.2% or the voids changed.
    pub fn record(
        &mut self,
        grid: &GridCells,
        tracker: &VoidTracker,
        air: &AirSummary,
        time: f64,
        report: &mut PhysicsReport,
    ) {
        let (mut open, mut liquid, mut vented) = (0usize, 0usize, 0usize);
        for &c in &self.cells {
            let c = c as usize;
            open += 1;
            if grid.liquid[c] {
                liquid += 1;
            } else if tracker.vented_air(c) {
                vented += 1;
            }
        }
        if open == 0 {
            return;
        }
        let fill = liquid as f64 / open as f64;
        report.record_max("underfill.fill_fraction", fill);
        let just_filled = vented == 0 && self.fill_time.is_none() && time > 0.0;
        if just_filled {
            self.fill_time = Some(time);
            report.record_max("underfill.fill_time", time);
        }
        if (fill - self.logged_fill).abs() >= 2e-3 || air.voids != self.logged_voids || just_filled
        {
            self.logged_fill = fill;
            self.logged_voids = air.voids;
            let three_d = grid.dimension == 3;
            let columns: &[&str] = if three_d {
                &FILL_COLUMNS_3D
            } else {
                &FILL_COLUMNS
            };
            let trapped = if three_d {
                air.trapped_volume
            } else {
                air.trapped_area
            };
            report.table_mut(FILL_TABLE, columns).rows.push(vec![
                time,
                fill,
                vented as f64 * grid.measure(),
                trapped,
                air.voids as f64,
            ]);
        }
    }
}
