//! The underfill operator: each step it evaluates the viscosity, solves the flow of the
//! connected liquid (gap-averaged or cross-section), advances the fill of the front cells,
//! finds the voids, and hands fill, pressure and velocity to the particles.

use crate::cross_section::{self, CrossSectionWork};
use crate::front::{FULL_AT, FlowState};
use crate::hele_shaw::{self, HeleShawWork};
use crate::lattice::{self, Lattice, LatticeInput};
use crate::parameters::{FlowMode, Fluid, InitialFill, UnderfillParameters};
use crate::voids::VoidTracker;
use mpm_core::physics::{PhysicsContext, PhysicsFault, PhysicsLaw, SharedFieldSpec, Stage};
use mpm_core::scene::{Scene, Side};
use std::sync::Mutex;

/// Name of the voids table in the metrics and the result store (`/tables/underfill_voids`).
pub const VOIDS_TABLE: &str = "underfill_voids";
/// Name of the fill-history table (`/tables/underfill_fill`).
pub const FILL_TABLE: &str = "underfill_fill";
/// Columns of the fill-history table.
pub const FILL_COLUMNS: [&str; 5] = [
    "time",
    "fill_fraction",
    "vented_air_volume",
    "trapped_air_area",
    "voids",
];

/// Particle fields the operator writes.
const FIELDS: [&str; 5] = [
    "fill",
    "pressure",
    "flow_velocity_x",
    "flow_velocity_y",
    "open_fraction",
];

/// Viscous underfill flow (see the crate documentation).
pub struct Underfill {
    params: UnderfillParameters,
    /// The liquid's properties (the `fluid` section's and the gap's `liquid` material's).
    fluid: Fluid,
    vents: Vec<Side>,
    domain: ([f64; 2], [f64; 2]),
    /// Longest step, s (the output interval): the step when nothing flows.
    longest_step: f64,
    workspace: Mutex<Option<Box<Workspace>>>,
}

/// Everything kept between steps.
struct Workspace {
    lattice: Lattice,
    state: FlowState,
    hele_shaw: Option<HeleShawWork>,
    cross_section: Option<CrossSectionWork>,
    voids: VoidTracker,
    /// Cell of each particle of the gap (u32::MAX: not in the gap).
    cell_of_particle: Vec<u32>,
    /// Per-cell sums for temperature and cure averages.
    sums: [Vec<f64>; 3],
    next_dt: f64,
    fill_time: Option<f64>,
    logged_fill: f64,
    logged_voids: usize,
}

impl Underfill {
    /// The operator for checked parameters of `scene`.
    pub fn new(params: UnderfillParameters, fluid: Fluid, scene: &Scene) -> Self {
        let vents = params.vents.clone().unwrap_or_else(|| {
            [Side::XMin, Side::XMax, Side::YMin, Side::YMax]
                .into_iter()
                .filter(|s| !params.reservoirs.iter().any(|r| r.sides.contains(s)))
                .filter(|s| {
                    // In a cross-section the plates are walls, not vents.
                    params.mode == FlowMode::GapAveraged || s.axis_and_upper().0 != params.gap_axis
                })
                .collect()
        });
        let d = &scene.domain;
        let pick = |v: &[f64]| {
            [
                v.first().copied().unwrap_or(0.0),
                v.get(1).copied().unwrap_or(0.0),
            ]
        };
        Self {
            vents,
            domain: (pick(&d.min), pick(&d.max)),
            longest_step: scene.solver.end_time / scene.output.frames.max(1) as f64,
            params,
            fluid,
            workspace: Mutex::new(None),
        }
    }

    fn in_gap(&self, material: &str) -> bool {
        self.params.materials.is_empty() || self.params.materials.iter().any(|m| m == material)
    }

    fn initialise<const D: usize>(&self, mut ctx: PhysicsContext<'_, D>) {
        let grid = ctx.grid;
        let pv = &ctx.particles;
        let mut particles = Vec::new();
        for g in pv.groups {
            if self.in_gap(&g.name) {
                for p in g.range.clone() {
                    particles.push(([pv.position[p][0], pv.position[p][1]], pv.volume0[p]));
                }
            }
        }
        let p = &self.params;
        let lattice = lattice::build(&LatticeInput {
            n: [grid.cells[0], grid.cells[1]],
            origin: [grid.origin[0], grid.origin[1]],
            dx: grid.dx,
            domain: self.domain,
            particles: &particles,
            mode: p.mode,
            wetting_tension: self.fluid.wetting_tension(),
            gap: p.gap,
            gap_axis: p.gap_axis,
            bumps: p.bumps.as_ref(),
            reservoirs: &p.reservoirs,
            vents: &self.vents,
            vent_regions: &p.vent_regions,
        });
        let n = lattice.len();
        let fill: Vec<f64> = (0..n)
            .map(|c| {
                if !lattice.is_open(c) {
                    return 0.0;
                }
                match &p.initial_fill {
                    InitialFill::Empty => 0.0,
                    InitialFill::Full => 1.0,
                    InitialFill::Box { min, max } => {
                        let x = lattice.centre(c);
                        let inside = (0..2).all(|a| x[a] >= min[a] && x[a] <= max[a]);
                        if inside { 1.0 } else { 0.0 }
                    }
                }
            })
            .collect();
        let state = FlowState::new(&lattice, fill);
        let mut ws = Box::new(Workspace {
            hele_shaw: (p.mode == FlowMode::GapAveraged).then(|| HeleShawWork::new(n)),
            cross_section: (p.mode == FlowMode::CrossSection)
                .then(|| CrossSectionWork::new(&lattice)),
            voids: VoidTracker::new(n),
            cell_of_particle: vec![u32::MAX; pv.position.len()],
            sums: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            next_dt: self.longest_step,
            fill_time: None,
            logged_fill: -1.0,
            logged_voids: 0,
            lattice,
            state,
        });
        self.locate(&mut ws, &ctx);
        self.viscosity(&mut ws, &ctx);
        let air = ws.voids.update(&ws.lattice, &mut ws.state, 0.0, &p.air);
        // A first solve for the fluxes that set the first step (a steady one in a
        // cross-section, whose velocities are then dropped: the liquid starts at rest).
        if !self.solve(&mut ws, &mut ctx, 1e30) {
            return;
        }
        if let Some(cs) = ws.cross_section.as_mut() {
            cs.face_velocity.iter_mut().for_each(|v| v.fill(0.0));
            cs.link_velocity.fill(0.0);
        }
        ws.next_dt = ws.state.fill_time_scale(&ws.lattice).min(self.longest_step);
        self.record(&mut ws, &mut ctx, 0.0, air);
        self.write_particles(&ws, &mut ctx);
        *self.workspace.lock().unwrap_or_else(|e| e.into_inner()) = Some(ws);
    }

    /// Bins the gap's particles into cells.
    fn locate<const D: usize>(&self, ws: &mut Workspace, ctx: &PhysicsContext<'_, D>) {
        let pv = &ctx.particles;
        ws.cell_of_particle.fill(u32::MAX);
        for g in pv.groups {
            if !self.in_gap(&g.name) {
                continue;
            }
            for p in g.range.clone() {
                let x = [pv.position[p][0], pv.position[p][1]];
                if let Some(c) = ws.lattice.cell_of(x) {
                    ws.cell_of_particle[p] = c as u32;
                }
            }
        }
    }

    /// Cell viscosities from the particles' temperature and cure (where physics gives
    /// them) and the last step's shear rate.
    fn viscosity<const D: usize>(&self, ws: &mut Workspace, ctx: &PhysicsContext<'_, D>) {
        let law = &self.fluid.viscosity;
        let temperature = ctx.fields.get("temperature");
        let cure = if law.uses_cure() {
            ctx.fields.get("cure")
        } else {
            None
        };
        let [count, t_sum, a_sum] = &mut ws.sums;
        if temperature.is_some() || cure.is_some() {
            count.fill(0.0);
            t_sum.fill(0.0);
            a_sum.fill(0.0);
            for (p, &c) in ws.cell_of_particle.iter().enumerate() {
                if c == u32::MAX {
                    continue;
                }
                let c = c as usize;
                count[c] += 1.0;
                t_sum[c] += temperature.map_or(self.params.temperature, |t| t[p]);
                a_sum[c] += cure.map_or(0.0, |a| a[p]);
            }
        }
        let shear = law.shear_thinning();
        for c in 0..ws.lattice.len() {
            let (t, a) = if count[c] > 0.0 {
                (t_sum[c] / count[c], a_sum[c] / count[c])
            } else {
                (self.params.temperature, 0.0)
            };
            let rate = if shear { ws.state.shear_rate[c] } else { 0.0 };
            ws.state.viscosity[c] = law.at(t, rate, a);
        }
    }

    /// Solves the flow for a step of `dt`; false (and a fault) when the solve failed.
    fn solve<const D: usize>(
        &self,
        ws: &mut Workspace,
        ctx: &mut PhysicsContext<'_, D>,
        dt: f64,
    ) -> bool {
        let p = &self.params;
        if let Some(work) = ws.hele_shaw.as_mut() {
            let solved = hele_shaw::solve_pressure(
                &ws.lattice,
                &mut ws.state,
                work,
                p.tolerance,
                p.max_iterations,
            );
            ctx.report
                .record_max("underfill.solver_iterations", solved.iterations as f64);
            if !solved.converged {
                ctx.report.fail(PhysicsFault {
                    field: "pressure".into(),
                    particle: None,
                    value: solved.iterations as f64,
                    message: format!(
                        "the underfill pressure solve did not reach its tolerance in {} iterations (raise physics.underfill.max_iterations or loosen tolerance)",
                        p.max_iterations
                    ),
                });
                return false;
            }
        }
        if let Some(work) = ws.cross_section.as_mut()
            && let Err(e) =
                cross_section::solve_step(&ws.lattice, &mut ws.state, work, self.fluid.density, dt)
        {
            let c = ws.lattice.coords(e.column.min(ws.lattice.len() - 1));
            ctx.report.fail(PhysicsFault {
                field: "pressure".into(),
                particle: None,
                value: e.column as f64,
                message: format!(
                    "the cross-section flow system is singular (unknown {} near cell {c:?}): a pocket of liquid with no meniscus, reservoir or wall to hold its pressure",
                    e.column
                ),
            });
            return false;
        }
        true
    }

    fn advance<const D: usize>(&self, mut ctx: PhysicsContext<'_, D>) {
        let mut guard = self.workspace.lock().unwrap_or_else(|e| e.into_inner());
        let Some(ws) = guard.as_mut() else {
            return;
        };
        let dt = ctx.dt;
        if dt <= 0.0 {
            return;
        }
        self.locate(ws, &ctx);
        self.viscosity(ws, &ctx);
        if !self.solve(ws, &mut ctx, dt) {
            return;
        }
        ws.next_dt = ws.state.fill_time_scale(&ws.lattice).min(self.longest_step);
        ws.state.advance(&ws.lattice, dt);
        let p = &self.params;
        let air = ws
            .voids
            .update(&ws.lattice, &mut ws.state, ctx.time, &p.air);
        let time = ctx.time;
        self.record(ws, &mut ctx, time, air);
        self.write_particles(ws, &mut ctx);
    }

    /// Metrics, the void table and the fill history.
    fn record<const D: usize>(
        &self,
        ws: &mut Workspace,
        ctx: &mut PhysicsContext<'_, D>,
        time: f64,
        air: crate::voids::AirSummary,
    ) {
        let (liquid, open) = ws.state.volumes(&ws.lattice);
        let fill = if open > 0.0 { liquid / open } else { 0.0 };
        let report = &mut *ctx.report;
        report.record_max("underfill.fill_fraction", fill);
        report.record_max("underfill.voids", air.voids as f64);
        report.record_max("underfill.trapped_air_area", air.trapped_area);
        report.record_last("underfill.voids_left", air.voids as f64);
        report.record_last("underfill.trapped_air_left", air.trapped_volume);
        if open > 0.0 {
            report.record_max(
                "underfill.lost_volume_fraction",
                ws.state.lost_volume / open,
            );
        }
        // Filled: no air left with a way out (what remains is trapped).
        let done = air.vented_volume <= 1e-9 * open || fill >= FULL_AT;
        let just_filled = done && ws.fill_time.is_none() && time > 0.0;
        if just_filled {
            ws.fill_time = Some(time);
            report.record_max("underfill.fill_time", time);
        }
        ws.voids.write_table(report, false);
        if fill - ws.logged_fill >= 2e-3 || air.voids != ws.logged_voids || just_filled {
            ws.logged_fill = fill;
            ws.logged_voids = air.voids;
            report.table_mut(FILL_TABLE, &FILL_COLUMNS).rows.push(vec![
                time,
                fill,
                air.vented_volume,
                air.trapped_area,
                air.voids as f64,
            ]);
        }
    }

    /// Fill, pressure, velocity and open fraction of each particle's cell.
    fn write_particles<const D: usize>(&self, ws: &Workspace, ctx: &mut PhysicsContext<'_, D>) {
        let [Some(fill), Some(pressure), Some(vx), Some(vy), Some(open)] =
            ctx.fields.many_mut(FIELDS)
        else {
            return;
        };
        let (lattice, state) = (&ws.lattice, &ws.state);
        for (p, &c) in ws.cell_of_particle.iter().enumerate() {
            if c == u32::MAX {
                continue;
            }
            let c = c as usize;
            // Liquid share of the particle's area (bumps hold none).
            fill[p] = state.fill[c].min(1.0) * lattice.open[c];
            open[p] = lattice.open[c];
            pressure[p] = if state.is_liquid(c) {
                state.pressure[c]
            } else {
                state.air[c]
            };
            let v = match &ws.cross_section {
                Some(work) => {
                    let x = ctx.particles.position[p];
                    cross_section::sample_velocity(lattice, state, work, [x[0], x[1]])
                }
                None => [state.velocity[0][c], state.velocity[1][c]],
            };
            vx[p] = v[0];
            vy[p] = v[1];
        }
    }
}

impl PhysicsLaw for Underfill {
    fn hidden_state(&self) -> Option<&'static str> {
        Some("its cell state (fill fractions, front, voids)")
    }

    fn fields(&self) -> Vec<SharedFieldSpec> {
        FIELDS
            .iter()
            .map(|&name| SharedFieldSpec { name, initial: 0.0 })
            .collect()
    }

    fn needs_interpolation(&self) -> bool {
        false
    }

    fn stable_dt<const D: usize>(&self, _ctx: PhysicsContext<'_, D>) -> f64 {
        let guard = self.workspace.lock().unwrap_or_else(|e| e.into_inner());
        guard
            .as_ref()
            .map_or(self.longest_step, |ws| ws.next_dt.max(1e-300))
    }

    fn stage<const D: usize>(&self, stage: Stage, ctx: PhysicsContext<'_, D>) {
        if D != 2 {
            return;
        }
        match stage {
            Stage::Initialise => self.initialise(ctx),
            Stage::Advance => self.advance(ctx),
            Stage::Prepare | Stage::Finish => {}
        }
    }
}
