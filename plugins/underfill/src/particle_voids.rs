//! Voids among liquid particles (`physics.liquid_voids`): each step the grid cells inside
//! the domain that are neither closed (behind a wall, inside an obstacle or a held body)
//! nor hold a liquid particle are air; air regions
//! that touch no vent face are voids, reported in the same `underfill_voids` table as the
//! gap-averaged mode. The incompressible projection takes air for free surface, so a void
//! here does not resist: it records where and when the liquid closed around air, and when
//! the air left (its cells filled or reached a vent). With a `fill_region` the region's
//! fill and fill time are recorded too (`crate::particle_fill`).

use crate::lattice::side_of;
use crate::particle_cells::GridCells;
use crate::particle_fill::{FillRegion, FillTimer};
use crate::voids::VoidTracker;
use mpm_core::physics::{PhysicsContext, PhysicsLaw, SharedFieldSpec, Stage};
use mpm_core::scene::{Issue, Mechanics, Scene, Side};
use schemars::JsonSchema;
use serde::Deserialize;
use std::sync::Mutex;

/// Scene section `physics.liquid_voids`: air the liquid particles enclose.
#[derive(Clone, Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LiquidVoidsParameters {
    /// Materials whose particles are the liquid (default: every `liquid` material).
    #[serde(default)]
    pub materials: Vec<String>,
    /// Domain faces open to the air: air that loses its path to all of them is a void.
    /// Default: every face without a wall.
    #[serde(default)]
    pub vents: Option<Vec<Side>>,
    /// Smallest enclosed air reported as a void, in cells (area in 2D, volume in 3D); a
    /// cell or two without a particle inside moving liquid is not air.
    #[serde(default = "default_min_void_cells")]
    pub min_void_cells: f64,
    /// A box whose fill is timed, say the gap under a die: its filled fraction, its fill
    /// history (`underfill_fill`) and its fill time. Default: none.
    #[serde(default)]
    pub fill_region: Option<FillRegion>,
}

fn default_min_void_cells() -> f64 {
    4.0
}

impl LiquidVoidsParameters {
    /// Every problem with the section, by JSON path below `path`.
    pub fn check(&self, path: &str, scene: &Scene) -> Vec<Issue> {
        let mut issues = Vec::new();
        if !matches!(scene.solver.mechanics, Mechanics::Incompressible(_)) {
            issues.push(Issue::new(
                path.to_string(),
                "voids among liquid particles need solver.mechanics incompressible (the gap-averaged mode finds its own, physics.underfill)",
            ));
        }
        for (k, m) in self.materials.iter().enumerate() {
            if !scene.materials.contains_key(m) {
                issues.push(Issue::new(
                    format!("{path}.materials[{k}]"),
                    format!("no material named {m:?}"),
                ));
            }
        }
        if self.liquids(scene).is_empty() {
            issues.push(Issue::new(
                format!("{path}.materials"),
                "the scene has no liquid material whose particles could enclose air",
            ));
        }
        let dim = scene.dimension as usize;
        for (k, side) in self.vents.iter().flatten().enumerate() {
            if side.axis_and_upper().0 >= dim {
                issues.push(Issue::new(
                    format!("{path}.vents[{k}]"),
                    format!("a {dim}D domain has no such face"),
                ));
            }
        }
        if !(self.min_void_cells.is_finite() && self.min_void_cells > 0.0) {
            issues.push(Issue::new(
                format!("{path}.min_void_cells"),
                format!(
                    "must be a finite number of cells > 0 (got {})",
                    self.min_void_cells
                ),
            ));
        }
        if let Some(region) = &self.fill_region {
            issues.extend(region.check(&format!("{path}.fill_region"), scene));
        }
        issues
    }

    /// The liquid's materials: those named, or every `liquid` material of the scene.
    fn liquids(&self, scene: &Scene) -> Vec<String> {
        if !self.materials.is_empty() {
            return self.materials.clone();
        }
        scene
            .materials
            .iter()
            .filter(|(_, m)| m.get("type").and_then(|t| t.as_str()) == Some("liquid"))
            .map(|(name, _)| name.clone())
            .collect()
    }
}

/// The operator: labels the air each step and keeps the void table.
pub struct LiquidVoids {
    liquids: Vec<String>,
    vents: Vec<Side>,
    min_void_cells: f64,
    domain: ([f64; 3], [f64; 3]),
    fill_region: Option<FillRegion>,
    workspace: Mutex<Option<Workspace>>,
}

/// The cells and their labels, kept between steps.
struct Workspace {
    cells: GridCells,
    tracker: VoidTracker,
    fill: Option<FillTimer>,
}

impl LiquidVoids {
    /// The operator for checked parameters of `scene`.
    pub fn new(params: &LiquidVoidsParameters, scene: &Scene) -> Self {
        let dim = scene.dimension as usize;
        let walled: Vec<Side> = scene
            .domain
            .walls
            .iter()
            .flat_map(|w| w.sides.iter().copied())
            .collect();
        let vents = params.vents.clone().unwrap_or_else(|| {
            [
                Side::XMin,
                Side::XMax,
                Side::YMin,
                Side::YMax,
                Side::ZMin,
                Side::ZMax,
            ]
            .into_iter()
            .filter(|s| s.axis_and_upper().0 < dim && !walled.contains(s))
            .collect()
        });
        let pick = |v: &[f64]| [0, 1, 2].map(|a| v.get(a).copied().unwrap_or(0.0));
        Self {
            liquids: params.liquids(scene),
            vents,
            min_void_cells: params.min_void_cells,
            domain: (pick(&scene.domain.min), pick(&scene.domain.max)),
            fill_region: params.fill_region.clone(),
            workspace: Mutex::new(None),
        }
    }

    /// The grid's cells, with those outside the domain or solid marked closed and those on a
    /// vent face marked vented.
    fn cells<const D: usize>(&self, ctx: &PhysicsContext<'_, D>) -> GridCells {
        let grid = ctx.grid;
        let n = [0, 1, 2].map(|a| if a < D { grid.cells[a] } else { 1 });
        let origin = [0, 1, 2].map(|a| if a < D { grid.origin[a] } else { 0.0 });
        let mut cells = GridCells::new(n, grid.dx, origin, D);
        let count = cells.closed.len();
        for c in 0..count {
            let ijk = cells.coords(c);
            let centre = cells.centre(c);
            let mut inside = true;
            for (a, &at) in centre.iter().enumerate().take(D) {
                let (lo, hi) = (self.domain.0[a], self.domain.1[a]);
                if at < lo || at > hi {
                    inside = false;
                }
                // A cell whose face lies on a vent face, within half a cell of it.
                for (upper, face) in [(false, lo), (true, hi)] {
                    let side = side_of(a, upper);
                    if (at - face).abs() <= 0.5 * grid.dx * (1.0 + 1e-9)
                        && self.vents.contains(&side)
                    {
                        cells.vented[c] = true;
                    }
                }
            }
            let mut x = mpm_core::math::Vector::<D>::zeros();
            for a in 0..D {
                x[a] = centre[a];
            }
            cells.closed[c] = !inside || ctx.boundaries.cell_is_solid(ijk, &x);
        }
        cells
    }

    fn update<const D: usize>(&self, ctx: PhysicsContext<'_, D>) {
        let mut guard = self.workspace.lock().unwrap_or_else(|e| e.into_inner());
        let ws = guard.get_or_insert_with(|| {
            let cells = self.cells(&ctx);
            let tracker = VoidTracker::new(cells.closed.len());
            let fill = self
                .fill_region
                .as_ref()
                .map(|region| FillTimer::new(&cells, region));
            Workspace {
                cells,
                tracker,
                fill,
            }
        });
        let cells = &mut ws.cells;
        cells.liquid.fill(false);
        let pv = &ctx.particles;
        for g in pv.groups.iter().filter(|g| self.liquids.contains(&g.name)) {
            for x in &pv.position[g.range.clone()] {
                if let Some(c) = cells.cell_of(x.as_slice()) {
                    cells.liquid[c] = true;
                }
            }
        }
        let cell_measure = cells.measure();
        let summary = ws
            .tracker
            .label(&ws.cells, ctx.time, self.min_void_cells * cell_measure);
        let report = &mut *ctx.report;
        if let Some(fill) = &mut ws.fill {
            fill.record(&ws.cells, &ws.tracker, &summary, ctx.time, report);
        }
        report.record_max("underfill.voids", summary.voids as f64);
        report.record_max("underfill.trapped_air_volume", summary.trapped_volume);
        report.record_last("underfill.voids_left", summary.voids as f64);
        report.record_last("underfill.trapped_air_left", summary.trapped_volume);
        if summary.changed || summary.voids > 0 {
            ws.tracker.write_table(report, D == 3);
        }
    }
}

impl PhysicsLaw for LiquidVoids {
    fn fields(&self) -> Vec<SharedFieldSpec> {
        Vec::new()
    }

    fn hidden_state(&self) -> Option<&'static str> {
        Some("its void labels and records")
    }

    fn needs_interpolation(&self) -> bool {
        false
    }

    fn stage<const D: usize>(&self, stage: Stage, ctx: PhysicsContext<'_, D>) {
        if matches!(stage, Stage::Initialise | Stage::Finish) {
            self.update(ctx);
        }
    }
}
