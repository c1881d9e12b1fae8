//! `mpm check-stability --map`: stability maps. Three scenes of the suite (the vibrating
//! bar, the Johnson–Cook impact, the near-incompressible block; cheaper variants) run at a
//! fixed time step of a CFL factor times their stable step, for every transfer × update
//! scheme × kernel and for implicit Newmark dynamics; each run is recorded as finished,
//! stopped, blown up or refused, with its energy error. A measurement, not a pass/fail
//! suite: `stability_map_plot` draws each case as a picture.

use crate::stability::{
    MAX_ENERGY_GROWTH, Ran, bar_time_step, diagnostic_note, impact, momentum_changes,
    near_incompressible, outcome_name, physics_failures, run_value,
};
use mpm_core::kernels::Kernel;
use mpm_core::material::Material;
use mpm_core::plugin::Registry;
use mpm_core::solver::{DimensionDispatch, RunError, Simulation, SimulationVisitor, dispatch};
use serde::Serialize;
use serde_json::{Value, json};
use std::path::Path;
use std::time::Instant;

/// The CFL factors of the default map: the fixed step as a multiple of the stable one.
pub const DEFAULT_FACTORS: [f64; 8] = [0.1, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0];

/// The largest CFL factor `--cfl` accepts.
pub const MAX_FACTOR: f64 = 100.0;

/// One scene of the map, in its explicit form (the rows change transfer, scheme, kernel
/// and mechanics; the columns the time step).
pub struct MapCase {
    /// Short name (`--only` matches it; the picture is `<name>.png`).
    pub name: &'static str,
    /// What it is, with its size.
    pub what: &'static str,
    /// The scene.
    pub scene: Value,
}

/// The map's scenes: the suite's own cases, made cheaper where they are expensive.
pub fn cases() -> Vec<MapCase> {
    let mut bar = bar_time_step(1.0, 1.0);
    if let Some(solver) = bar["solver"].as_object_mut() {
        solver.remove("dt");
        solver.remove("max_cfl");
    }
    let mut hit = impact(200.0);
    hit["domain"]["cell_size"] = json!(0.001);
    hit["solver"]["end_time"] = json!(1e-5);
    vec![
        MapCase {
            name: "bar",
            what: "vibrating bar (examples/vibrating-bar.json: cell 0.05 m, 320 particles, one period, 0.4 s)",
            scene: bar,
        },
        MapCase {
            name: "impact",
            what: "Johnson-Cook steel block on a rigid wall at 200 m/s (cell 1 mm, 200 particles, 10 µs)",
            scene: hit,
        },
        MapCase {
            name: "incompressible",
            what: "rubber block under gravity, nu = 0.49, no F-bar (cell 25 mm, 512 particles, 0.05 s)",
            scene: near_incompressible(0.49, false),
        },
    ]
}

/// One row of a map: how velocities return to the particles, when the stress is updated,
/// the kernel, and whether mechanics is explicit or implicit Newmark dynamics.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// `transfer/scheme/kernel`, or `implicit/kernel`.
    pub label: String,
    /// `pic`, `flip` (blend 0.99, the default), `apic`, `mls` (APIC with the MLS-MPM
    /// force) or `xpic` (order 2, the default); the implicit rows keep the default (APIC).
    pub transfer: &'static str,
    /// `usf`, `usl` or `musl`; none for the implicit rows.
    pub scheme: Option<&'static str>,
    /// `linear`, `gimp`, `bspline2`, `bspline3` or `cpdi2`.
    pub kernel: &'static str,
    /// Implicit Newmark dynamics (`solver.mechanics: {"implicit": {"form": "dynamic"}}`).
    pub implicit: bool,
    /// Total Lagrangian MPM (`solver.mechanics: "total_lagrangian"`), labelled `tlmpm/...`.
    pub total_lagrangian: bool,
}

const KERNELS: [&str; 4] = ["linear", "gimp", "bspline2", "bspline3"];

/// Every row: each transfer × scheme × kernel (the validator refuses some: they show as
/// refused), then implicit dynamics with each kernel, then total Lagrangian MPM with each
/// transfer × scheme × kernel it takes, then CPDI with each transfer × scheme it takes.
pub fn rows() -> Vec<Row> {
    let mut rows = Vec::new();
    let explicit = |prefix: &str, transfer, scheme, kernel, total_lagrangian| Row {
        label: format!("{prefix}{transfer}/{scheme}/{kernel}"),
        transfer,
        scheme: Some(scheme),
        kernel,
        implicit: false,
        total_lagrangian,
    };
    for transfer in ["pic", "flip", "apic", "mls", "xpic"] {
        for scheme in ["usf", "usl", "musl"] {
            for kernel in KERNELS {
                rows.push(explicit("", transfer, scheme, kernel, false));
            }
        }
    }
    for kernel in KERNELS {
        rows.push(Row {
            label: format!("implicit/{kernel}"),
            transfer: "apic",
            scheme: None,
            kernel,
            implicit: true,
            total_lagrangian: false,
        });
    }
    for transfer in ["pic", "flip", "apic"] {
        for scheme in ["usl", "musl"] {
            for kernel in KERNELS {
                rows.push(explicit("tlmpm/", transfer, scheme, kernel, true));
            }
        }
    }
    for transfer in ["pic", "flip", "apic"] {
        for scheme in ["usl", "musl"] {
            rows.push(explicit("", transfer, scheme, "cpdi2", false));
        }
    }
    rows
}

/// Whether `pattern` (e.g. `apic`, `usl/bspline2`, `apic/usl/bspline2`) names consecutive
/// `/`-separated parts of `label`: `pic` matches the PIC rows, not the APIC ones.
/// The total Lagrangian and CPDI rows answer only patterns that name `tlmpm` or `cpdi2`,
/// so `pic` or `usl/bspline2` pick the same rows as before they were added.
fn matches(label: &str, pattern: &str) -> bool {
    let parts: Vec<&str> = label.split('/').collect();
    let wanted: Vec<&str> = pattern.split('/').collect();
    for variant in ["tlmpm", "cpdi2"] {
        if parts.contains(&variant) && !wanted.contains(&variant) {
            return false;
        }
    }
    wanted.len() <= parts.len() && parts.windows(wanted.len()).any(|w| w == wanted.as_slice())
}

/// The rows that one of the comma-separated `patterns` names (see [`matches`]: whole
/// parts of the label, `transfer/scheme/kernel` or `implicit/kernel`); all rows without.
pub fn select_rows(patterns: Option<&str>) -> Result<Vec<Row>, String> {
    let all = rows();
    let Some(patterns) = patterns else {
        return Ok(all);
    };
    let wanted: Vec<&str> = patterns
        .split(',')
        .map(str::trim)
        .filter(|w| !w.is_empty())
        .collect();
    let chosen: Vec<Row> = all
        .iter()
        .filter(|r| wanted.iter().any(|w| matches(&r.label, w)))
        .cloned()
        .collect();
    if chosen.is_empty() {
        let labels: Vec<&str> = all.iter().map(|r| r.label.as_str()).collect();
        return Err(format!(
            "--rows {patterns}: names no row of the map (give whole parts of a label, e.g. apic, usl/bspline2); the rows are {}",
            labels.join(", ")
        ));
    }
    Ok(chosen)
}

/// Checks the CFL factors of `--cfl`: each finite, positive and at most [`MAX_FACTOR`].
pub fn check_factors(factors: &[f64]) -> Result<(), String> {
    if factors.is_empty() {
        return Err("--cfl: give at least one factor, e.g. --cfl 0.5,1,2".into());
    }
    for &f in factors {
        if !(f.is_finite() && f > 0.0 && f <= MAX_FACTOR) {
            return Err(format!(
                "--cfl {f}: a CFL factor must be a number in (0, {MAX_FACTOR}] (the fixed time step as a multiple of the stable step)"
            ));
        }
    }
    Ok(())
}

impl Row {
    /// `scene` with this row's transfer, scheme, kernel and mechanics.
    fn apply(&self, scene: &mut Value) {
        let solver = &mut scene["solver"];
        solver["kernel"] = json!(self.kernel);
        if self.implicit {
            solver["mechanics"] = json!({"implicit": {"form": "dynamic"}});
            return;
        }
        if self.total_lagrangian {
            solver["mechanics"] = json!("total_lagrangian");
        }
        if self.transfer == "mls" {
            solver["transfer"] = json!("apic");
            solver["mls"] = json!(true);
        } else {
            solver["transfer"] = json!(self.transfer);
        }
        if let Some(scheme) = self.scheme {
            solver["scheme"] = json!(scheme);
        }
    }

    /// Whether the row's transfer keeps angular momentum (APIC, MLS; implicit uses APIC).
    fn keeps_angular_momentum(&self) -> bool {
        matches!(self.transfer, "apic" | "mls")
    }
}

/// How one cell of the map ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MapOutcome {
    /// Ran to its end time with the physics holding (energy growth at most
    /// [`MAX_ENERGY_GROWTH`], momentum kept where nothing acts from outside).
    Finished,
    /// Stopped itself with a diagnostic other than a run-away (the fixed step outran the
    /// stable one as particles sped up, det F <= 0, a particle left the grid, Newton failed).
    Stopped,
    /// Ran away: energy grew past [`MAX_ENERGY_GROWTH`] (finished, or stopped by the
    /// run's energy check), a value became NaN or infinite, or it finished with momentum
    /// not kept.
    BlowUp,
    /// The scene was refused (the validator refuses the combination, or the step).
    Refused,
    /// The run failed otherwise (output, I/O): a bug, not a measurement.
    Error,
}

impl MapOutcome {
    /// The name used in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            MapOutcome::Finished => "finished",
            MapOutcome::Stopped => "stopped",
            MapOutcome::BlowUp => "blow-up",
            MapOutcome::Refused => "refused",
            MapOutcome::Error => "error",
        }
    }
}

/// One run of a map: a case, a row, a CFL factor.
#[derive(Clone, Debug, Serialize)]
pub struct MapCell {
    /// The case's name.
    pub case: String,
    /// The row's label.
    pub row: String,
    /// The CFL factor: the fixed step over the stable step at the start.
    pub cfl: f64,
    /// The fixed time step, s.
    pub dt: f64,
    /// How it ended.
    pub outcome: MapOutcome,
    /// The energy error (`metrics.energy_drift`: what the energy ledger does not explain,
    /// relative to the largest mechanical energy; negative = lost); none unless it ran.
    pub energy_drift: Option<f64>,
    /// The error against the case's reference solution (the bar's), where it has one.
    pub reference_error: Option<f64>,
    /// Steps taken.
    pub steps: u64,
    /// Particles (0 unless it ran).
    pub particles: usize,
    /// Wall seconds of the run (setup excluded).
    pub wall_seconds: f64,
    /// The diagnostic, refusal or failed check, if any.
    pub note: String,
}

/// The map of one case.
#[derive(Debug, Serialize)]
pub struct CaseMap {
    /// The case's name.
    pub case: String,
    /// What it is.
    pub what: String,
    /// The explicit stable step at the start (CFL factor 1), s.
    pub stable_dt: f64,
    /// The CFL factors (columns).
    pub factors: Vec<f64>,
    /// The row labels, top to bottom.
    pub rows: Vec<String>,
    /// Row by row, factor by factor.
    pub cells: Vec<MapCell>,
    /// Wall seconds of the whole map, setup included.
    pub wall_seconds: f64,
}

impl CaseMap {
    /// The cell of row `row` and column `column`.
    pub fn cell(&self, row: usize, column: usize) -> &MapCell {
        &self.cells[row * self.factors.len() + column]
    }
}

/// The stable step of a simulation at its start, after the initial stress.
struct StableStep;

impl SimulationVisitor for StableStep {
    type Output = Result<f64, RunError>;
    fn visit<const D: usize, K: Kernel>(self, mut sim: Simulation<D, K>) -> Self::Output
    where
        dyn Material: DimensionDispatch<D>,
    {
        sim.preflight()?;
        Ok(sim.stable_dt())
    }
}

/// The explicit stable step (Courant number 1) of `scene` at its start, s.
pub fn stable_step(scene: &Value, registry: &Registry) -> Result<f64, String> {
    let scene = mpm_core::scene::parse_scene_value(scene.clone(), registry, Path::new("."))
        .map_err(|e| format!("the map's scene is invalid: {e}"))?;
    let dt = dispatch(&scene, StableStep).map_err(|e| e.to_string())?;
    if dt.is_finite() && dt > 0.0 {
        Ok(dt)
    } else {
        Err(format!("the map's scene has no finite stable step ({dt})"))
    }
}

/// Runs `case` for every row and factor; `report` sees each row once it is done. Fails
/// only when the case's stable step cannot be found (a bug in the case).
pub fn run_map(
    case: &MapCase,
    rows: &[Row],
    factors: &[f64],
    registry: &Registry,
    mut report: impl FnMut(&Row, &[MapCell]),
) -> Result<CaseMap, String> {
    let start = Instant::now();
    let stable_dt =
        stable_step(&case.scene, registry).map_err(|e| format!("{}: {e}", case.name))?;
    let mut cells = Vec::with_capacity(rows.len() * factors.len());
    for row in rows {
        let first = cells.len();
        for &factor in factors {
            cells.push(run_cell(case, row, factor, stable_dt, registry));
        }
        report(row, &cells[first..]);
    }
    Ok(CaseMap {
        case: case.name.into(),
        what: case.what.into(),
        stable_dt,
        factors: factors.to_vec(),
        rows: rows.iter().map(|r| r.label.clone()).collect(),
        cells,
        wall_seconds: start.elapsed().as_secs_f64(),
    })
}

/// One cell: the case with the row's settings at `factor` times the stable step. The
/// largest Courant number allowed (`max_cfl`) is twice the factor (at least 2), so the step
/// is not refused, and a run stops itself only when particles speed up enough to double it.
fn run_cell(
    case: &MapCase,
    row: &Row,
    factor: f64,
    stable_dt: f64,
    registry: &Registry,
) -> MapCell {
    let dt = factor * stable_dt;
    let mut scene = case.scene.clone();
    row.apply(&mut scene);
    scene["solver"]["dt"] = json!(dt);
    scene["solver"]["max_cfl"] = json!(2.0 * factor.max(1.0));
    let mut cell = MapCell {
        case: case.name.into(),
        row: row.label.clone(),
        cfl: factor,
        dt,
        outcome: MapOutcome::Refused,
        energy_drift: None,
        reference_error: None,
        steps: 0,
        particles: 0,
        wall_seconds: 0.0,
        note: String::new(),
    };
    let (metrics, wall_seconds) = match run_value(&scene, registry) {
        Ran::Invalid(note) | Ran::Refused(note) => {
            cell.note = note;
            return cell;
        }
        Ran::Error(note) => {
            cell.outcome = MapOutcome::Error;
            cell.note = note;
            return cell;
        }
        Ran::Done {
            metrics,
            wall_seconds,
        } => (metrics, wall_seconds),
    };
    cell.steps = metrics.steps;
    cell.particles = metrics.particles;
    cell.wall_seconds = wall_seconds;
    cell.energy_drift = Some(metrics.energy_drift);
    cell.reference_error = metrics.error;
    cell.note = diagnostic_note(&metrics);
    let drift = metrics.energy_drift;
    let finished = outcome_name(&metrics) == "finished";
    // What a finished run got wrong: energy growth past the suite's bound, momentum.
    let wrong = if finished {
        let (momentum, angular) = momentum_changes(&metrics);
        physics_failures(drift, momentum, angular, row.keeps_angular_momentum())
    } else {
        Vec::new()
    };
    if !wrong.is_empty() {
        cell.note = wrong.join("; ");
    }
    // The implicit solver's own stop carries no value (NaN): not a run-away.
    let ran_away = drift.is_nan()
        || drift > MAX_ENERGY_GROWTH
        || !wrong.is_empty()
        || metrics.diagnostic.as_ref().is_some_and(|d| {
            d.field == "energy" || (!d.value.is_finite() && d.field != "implicit")
        });
    cell.outcome = match outcome_name(&metrics) {
        "cancelled" => {
            cell.note = "the run was cancelled".into();
            MapOutcome::Error
        }
        _ if ran_away => MapOutcome::BlowUp,
        "finished" => MapOutcome::Finished,
        _ => MapOutcome::Stopped,
    };
    cell
}

/// A cell as text: the energy error where the run finished; else its outcome, with the
/// energy error and the steps it took where it ran.
pub fn cell_text(cell: &MapCell) -> String {
    match (cell.outcome, cell.energy_drift) {
        (MapOutcome::Finished, Some(e)) => format!("{e:+.1e}"),
        (MapOutcome::Stopped | MapOutcome::BlowUp, Some(e)) => {
            format!("{} {e:+.1e} @{}", cell.outcome.name(), cell.steps)
        }
        (outcome, _) => outcome.name().into(),
    }
}

/// The map of one case as a Markdown table: a row per scheme, a column per CFL factor.
pub fn table(map: &CaseMap) -> String {
    let mut out = format!(
        "{} — {}; stable step {:.4e} s; {:.1} s\n\n| row |",
        map.case, map.what, map.stable_dt, map.wall_seconds
    );
    for f in &map.factors {
        out += &format!(" CFL {f} |");
    }
    out += "\n|---|";
    out += &"---|".repeat(map.factors.len());
    out += "\n";
    for (r, label) in map.rows.iter().enumerate() {
        out += &format!("| {label} |");
        for c in 0..map.factors.len() {
            out += &format!(" {} |", cell_text(map.cell(r, c)));
        }
        out += "\n";
    }
    out
}

/// One line counting the outcomes of `cells`.
pub fn summary(cells: &[MapCell]) -> String {
    let count = |o: MapOutcome| cells.iter().filter(|c| c.outcome == o).count();
    format!(
        "{} runs: {} finished, {} stopped, {} blow-up, {} refused, {} error",
        cells.len(),
        count(MapOutcome::Finished),
        count(MapOutcome::Stopped),
        count(MapOutcome::BlowUp),
        count(MapOutcome::Refused),
        count(MapOutcome::Error)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_factors_are_refused_with_a_reason() {
        assert!(check_factors(&[0.5, 1.0, 2.0]).is_ok());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e3] {
            let e = check_factors(&[0.5, bad]).unwrap_err();
            assert!(e.contains("CFL factor"), "{e}");
        }
        assert!(check_factors(&[]).is_err());
    }

    #[test]
    fn rows_cover_every_combination_and_filter_by_label() {
        let all = rows();
        assert_eq!(all.len(), 5 * 3 * 4 + 4 + 3 * 2 * 4 + 3 * 2);
        let some = select_rows(Some("apic/usl/bspline2, implicit/bspline2")).unwrap();
        let labels: Vec<&str> = some.iter().map(|r| r.label.as_str()).collect();
        assert_eq!(labels, ["apic/usl/bspline2", "implicit/bspline2"]);
        assert!(
            select_rows(Some("nothing"))
                .unwrap_err()
                .contains("the rows are")
        );
        // Whole parts: `pic` is not APIC, `implicit` is every implicit row.
        assert!(
            select_rows(Some("pic"))
                .unwrap()
                .iter()
                .all(|r| r.transfer == "pic")
        );
        assert_eq!(select_rows(Some("pic")).unwrap().len(), 12);
        assert_eq!(select_rows(Some("implicit")).unwrap().len(), 4);
        assert_eq!(select_rows(Some("usl/linear")).unwrap().len(), 5);
        // The total Lagrangian rows answer patterns that name them.
        assert_eq!(select_rows(Some("tlmpm")).unwrap().len(), 24);
        assert_eq!(select_rows(Some("tlmpm/pic")).unwrap().len(), 8);
        assert_eq!(
            select_rows(Some("tlmpm/apic/usl/bspline2")).unwrap().len(),
            1
        );
        // So do the CPDI rows.
        assert_eq!(select_rows(Some("cpdi2")).unwrap().len(), 6);
        assert_eq!(select_rows(Some("apic/usl/cpdi2")).unwrap().len(), 1);
        assert_eq!(select_rows(Some("musl/cpdi2")).unwrap().len(), 3);
    }

    #[test]
    fn a_row_sets_its_solver_options() {
        let mut scene = json!({"solver": {"end_time": 1.0}});
        let mls = rows()
            .into_iter()
            .find(|r| r.label == "mls/usl/bspline3")
            .unwrap();
        mls.apply(&mut scene);
        assert_eq!(
            scene["solver"],
            json!({"end_time": 1.0, "kernel": "bspline3", "transfer": "apic", "mls": true, "scheme": "usl"})
        );
    }
}
