//! The fill of a region by liquid particles (`physics.liquid_voids.fill_region`, say the
//! gap under a die): its filled fraction (liquid cells over the cells open to liquid), its
//! history in the `underfill_fill` table, and its fill time: the first time the air in the
//! region that still has a way out to a vent is down to `vented_air_tolerance` of its open
//! cells, so that what air remains there is trapped. With no tolerance this is the
//! gap-averaged mode's definition; the default 1% lets the few cells a meniscus rounds off
//! in the far corners (against a stick die at the vent plane) count as filled.

use crate::particle_cells::GridCells;
use crate::underfill::{FILL_COLUMNS, FILL_TABLE};
use crate::voids::{AirSummary, VoidTracker};
use mpm_core::physics::PhysicsReport;
use mpm_core::scene::{Issue, Scene};
use schemars::JsonSchema;
use serde::Deserialize;

/// Scene section `physics.liquid_voids.fill_region`: the box whose fill is timed.
#[derive(Clone, Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FillRegion {
    /// Lower corner, m.
    pub min: Vec<f64>,
    /// Upper corner, m.
    pub max: Vec<f64>,
    /// The region counts as filled once its air with a way out to a vent is at most this
    /// fraction of its open cells (default 0.01; 0 asks for every such cell filled).
    #[serde(default = "default_vented_air_tolerance")]
    pub vented_air_tolerance: f64,
}

fn default_vented_air_tolerance() -> f64 {
    0.01
}

impl FillRegion {
    /// Every problem with the section, by JSON path below `path`: each corner a point of
    /// the scene's dimension, min below max, the box overlapping the domain, and the
    /// tolerance in [0, 1).
    pub fn check(&self, path: &str, scene: &Scene) -> Vec<Issue> {
        let mut issues = Vec::new();
        if !(self.vented_air_tolerance >= 0.0 && self.vented_air_tolerance < 1.0) {
            issues.push(Issue::new(
                format!("{path}.vented_air_tolerance"),
                format!(
                    "must be a fraction in [0, 1) (got {})",
                    self.vented_air_tolerance
                ),
            ));
        }
        let dim = scene.dimension as usize;
        let mut shaped = true;
        for (name, corner) in [("min", &self.min), ("max", &self.max)] {
            if corner.len() != dim || corner.iter().any(|v| !v.is_finite()) {
                issues.push(Issue::new(
                    format!("{path}.{name}"),
                    format!("must be {dim} finite coordinates (got {corner:?})"),
                ));
                shaped = false;
            }
        }
        if !shaped {
            return issues;
        }
        let domain =
            |corner: &[f64], a: usize, outside: f64| corner.get(a).copied().unwrap_or(outside);
        if (0..dim).any(|a| self.min[a] >= self.max[a]) {
            issues.push(Issue::new(
                format!("{path}.max"),
                "must lie above min along every axis",
            ));
        } else if (0..dim).any(|a| {
            self.max[a] <= domain(&scene.domain.min, a, f64::NEG_INFINITY)
                || self.min[a] >= domain(&scene.domain.max, a, f64::INFINITY)
        }) {
            issues.push(Issue::new(path.to_string(), "lies outside the domain"));
        }
        issues
    }
}

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
    tolerance: f64,
    fill_time: Option<f64>,
    logged_fill: f64,
    logged_voids: usize,
}

impl FillTimer {
    /// The timer of the open cells of `grid` whose centres lie in `region`'s box.
    pub fn new(grid: &GridCells, region: &FillRegion) -> Self {
        let d = grid.dimension;
        let inside = |x: [f64; 3]| (0..d).all(|a| x[a] >= region.min[a] && x[a] <= region.max[a]);
        let cells = (0..grid.closed.len())
            .filter(|&c| !grid.closed[c] && inside(grid.centre(c)))
            .map(|c| c as u32)
            .collect();
        Self {
            cells,
            tolerance: region.vented_air_tolerance,
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
        // Closed cells stay closed, so every cell kept is open.
        let open = self.cells.len();
        let (mut liquid, mut vented) = (0usize, 0usize);
        for &c in &self.cells {
            let c = c as usize;
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
        let drained = vented as f64 <= self.tolerance * open as f64;
        let just_filled = drained && self.fill_time.is_none() && time > 0.0;
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
