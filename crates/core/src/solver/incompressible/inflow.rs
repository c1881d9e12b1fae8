//! Liquid entering through inlets (`inflow` bodies, `scene/inflow.rs`) in the
//! incompressible mode.
//!
//! An inflow's particles are made at the start and wait at their places across the inlet
//! face with no mass and no volume (`injected` = 0), so P2G, the liquid cells, the colour
//! field and every sum leave them out. Each step they are put back where they waited
//! after G2P (which would carry them with the grid) and those whose layer's entry time has
//! come enter: mass ρh^D, volume h^D, the entry velocity (U along the direction plus the
//! inlet's own), moved on from the face by that velocity for the time since their entry
//! time. Particle count and output arrays never change; a waiting particle is one with
//! `injected` = 0.
//!
//! The grid must make room for what entered: the projection keeps the nodal velocity
//! divergence-free, so on its own it holds the liquid at the inlet still and the entering
//! particles pile up (filling examples/liquid-inflow-tank.json put 513 particles in one
//! cell meant for 4). So in scenes with a rate inflow the pressure equation has a volume
//! source: a cell whose particle volume V differs from its own V_c gives or takes a share
//! β·r of the difference within the step, ∇·v = β·r(V − V_c)/(V_c·dt), which adds
//! β·r(V − V_c)/(2^D·dt²) to the right-hand side at each of its corners (mod.rs,
//! `VOLUME_CORRECTION` = β = 0.3), with r = min(1, dt / (cfl·dx/(|v|max + √(dx·|g|)))): β
//! is per velocity-CFL step, and a shorter step (a capillary or viscous bound, a step cut
//! to land on a frame) gives less in proportion. Cells inside the liquid correct both ways;
//! cells with a corner on the free surface only give (a surface cell is rightly part
//! empty). Measured on the tank, with β per step whatever its length: a source for only the
//! volume that entered in the last step left cells packed (up to 154 particles); only
//! giving, the liquid foamed; β = 1 threw particles through the far wall; β = 0.2 and 0.5
//! finished with the level 2.9% and 4.1% low. Per step, the correction's velocity grew as
//! 1/dt: a 3D inflow with surface tension at its capillary step (a fiftieth of the CFL
//! step) stirred the liquid at 0.3 m/s (median) where it entered at 0.05 m/s, and the
//! tank's steps cut short to land on frames kicked it (593 steps to 0.6 s; without the
//! kicks 356 at β = 0.2 and 371 at 0.3). With r, the tank's level at 0.6 s and the closed box of the stability suite
//! (`liquid-inflow-full-box`): β = 0.2 5.7% low (still 5.5% at 1.2 s), 0.3 2.6% low, 0.35
//! 3.4% low, 0.4 3.5% low and 0.5 3.5% low, but at 0.4 and 0.5 the full box pushed
//! particles 0.2 mm through its walls.
//!
//! A rate inlet whose face lies on a wall's plane is also a velocity condition on that
//! wall (wall_inlet.rs): the projection pushes its rate through the face, and the source
//! only moves what the particles misplace.
//!
//! The liquid cannot grow past the volume of the domain's open cells (not behind a wall,
//! not inside an obstacle): a layer that would take it past that stops the run with a
//! diagnostic naming the inflow, before the layer enters.

use super::super::DimensionDispatch;
use super::super::simulation::Simulation;
use super::pressure_inlet::{self, PressureDrive};
use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::grid::node_position;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector};
use crate::particles::Particles;
use crate::physics::PhysicsFault;
use crate::scene::{INJECTED, InflowLayout, Shape, ValidatedScene};

/// One inflow body's particles and schedule.
struct Plan<const D: usize> {
    /// The body's name (or its index) for diagnostics.
    name: String,
    /// Particle ids `first_id..end_id` belong to it, layer by layer.
    first_id: u32,
    end_id: u32,
    layout: InflowLayout,
    /// Velocity a particle enters with.
    velocity: Vector<D>,
    /// Volume h^D and mass ρh^D of one particle.
    volume: f64,
    mass: f64,
    /// A pressure inlet's state (pressure_inlet.rs); `None` at a set rate.
    drive: Option<PressureDrive>,
}

impl<const D: usize> Plan<D> {
    /// Whether its particle `index` (in the inflow's order, from 0) enters within the step
    /// that ends at `now`.
    fn is_due(&self, index: usize, now: f64) -> bool {
        match &self.drive {
            Some(drive) => drive.entry(index).is_some(),
            None => self.layout.entry_time(index / self.layout.offsets.len()) <= now,
        }
    }

    /// Where its particle `index`, which waited at `waiting`, lies when it enters at `now`,
    /// and its velocity.
    fn entry(&self, index: usize, waiting: Vector<D>, now: f64) -> (Vector<D>, Vector<D>) {
        let layout = &self.layout;
        let Some((k, past, speed)) = self.drive.as_ref().and_then(|d| d.entry(index)) else {
            let entry = layout.entry_time(index / layout.offsets.len());
            return (waiting + self.velocity * (now - entry), self.velocity);
        };
        let (c, o, n) = (layout.center_at(now), layout.offsets[k], layout.direction);
        let place = Vector::<D>::from_fn(|a, _| c[a] + o[a] + past * n[a]);
        let velocity = Vector::<D>::from_fn(|a, _| layout.inlet_velocity[a] + speed * n[a]);
        (place, velocity)
    }
}

/// The scene's inlets (inflow bodies) and outlets (open faces with `outflow`), and the
/// step's waiting places.
pub(in crate::solver) struct Inflows<const D: usize> {
    plans: Vec<Plan<D>>,
    /// The open faces liquid leaves through (outflow.rs), with `outflow` on.
    pub(super) outlets: Option<super::outflow::Outlets>,
    /// Waiting particles (index, place) before G2P, put back after it.
    parked: Vec<(usize, Vector<D>)>,
    /// Volume of the domain's open cells, measured on the first step.
    open_volume: Option<f64>,
    /// The particles that entered in the last step (for their pumping work).
    entered: Vec<usize>,
}

impl<const D: usize> Inflows<D> {
    /// The inlets and outlets of a validated scene (`None` without either); `first_id[b]`
    /// is the first particle id of body `b`.
    pub(in crate::solver) fn new(v: &ValidatedScene, first_id: &[usize]) -> Option<Self> {
        let s = &v.scene;
        let plans: Vec<Plan<D>> = v
            .bodies
            .iter()
            .filter_map(|b| {
                let body = &s.bodies[b.body];
                let Shape::Inflow(inflow) = &body.shape else {
                    return None;
                };
                let layout = inflow.layout(D, b.spacing, s.solver.end_time);
                let volume = b.spacing.powi(D as i32);
                let density = v.materials[&body.material].density();
                let entry = layout.entry_velocity();
                let name = if body.name.is_empty() {
                    format!("bodies[{}]", b.body)
                } else {
                    body.name.clone()
                };
                Some(Plan {
                    name,
                    first_id: first_id[b.body] as u32,
                    end_id: (first_id[b.body] + b.volumes.len()) as u32,
                    velocity: Vector::<D>::from_fn(|a, _| entry[a]),
                    drive: layout
                        .pressure
                        .map(|p| PressureDrive::new(p, density, &layout)),
                    layout,
                    volume,
                    mass: density * volume,
                })
            })
            .collect();
        let outlets = super::outflow::Outlets::new(s, D);
        (!plans.is_empty() || outlets.is_some()).then(|| Self {
            plans,
            outlets,
            parked: Vec::new(),
            open_volume: None,
            entered: Vec::new(),
        })
    }

    /// The particles that entered in the last step.
    pub(super) fn entered(&self) -> &[usize] {
        &self.entered
    }

    /// Whether liquid enters anywhere at a set rate (the pressure equation's volume source
    /// is for them). A pressure inlet lets liquid in only where the flow made room for it,
    /// so it needs none: with it, the source's corrections of the particles' drift in a
    /// sheared channel kicked the pressure by twice the inlet's (pressure_inlet.rs).
    pub(super) fn has_inlets(&self) -> bool {
        self.plans.iter().any(|p| p.drive.is_none())
    }

    /// Every inlet's plan index, layout, and whether it is a pressure inlet.
    pub(super) fn layouts(&self) -> impl Iterator<Item = (usize, &InflowLayout, bool)> {
        self.plans
            .iter()
            .enumerate()
            .map(|(k, p)| (k, &p.layout, p.drive.is_some()))
    }

    /// The index of the plan particle id `id` belongs to.
    pub(super) fn plan_index(&self, id: u32) -> Option<usize> {
        self.plans
            .iter()
            .position(|p| (p.first_id..p.end_id).contains(&id))
    }

    /// The pressure inlets' layouts and states, in the order of the bodies.
    pub(super) fn drives_mut(
        &mut self,
    ) -> impl Iterator<Item = (&InflowLayout, &mut PressureDrive)> {
        self.plans
            .iter_mut()
            .filter_map(|p| p.drive.as_mut().map(|d| (&p.layout, d)))
    }

    /// The pressure inlets' layouts and states, in the order of the bodies.
    pub(super) fn drives(&self) -> impl Iterator<Item = (&InflowLayout, &PressureDrive)> {
        self.plans
            .iter()
            .filter_map(|p| p.drive.as_ref().map(|d| (&p.layout, d)))
    }

    /// Writes the pressure inlets' state into a checkpoint.
    pub(in crate::solver) fn save(&self, c: &mut Checkpoint) {
        pressure_inlet::save(self.drives().map(|(_, d)| d), c);
    }

    /// Reads the pressure inlets' state back: `strict` for a resume, else a stage taking
    /// over (which keeps the closed state where the stage before had no pressure inlet).
    pub(in crate::solver) fn restore(
        &mut self,
        c: &Checkpoint,
        strict: bool,
    ) -> Result<(), CheckpointError> {
        let n = self.drives().count();
        pressure_inlet::restore(self.drives_mut().map(|(_, d)| d), n, c, strict)
    }

    /// Sets `injected` to 0 for every inflow particle (setup: they all start waiting).
    pub(in crate::solver) fn mark_waiting(&self, particles: &mut Particles<D>) {
        let Particles { id, shared, .. } = particles;
        let Some(injected) = shared.get_mut(INJECTED) else {
            return;
        };
        for (flag, &pid) in injected.iter_mut().zip(id.iter()) {
            if self.plan_of(pid).is_some() {
                *flag = 0.0;
            }
        }
    }

    fn plan_of(&self, id: u32) -> Option<&Plan<D>> {
        self.plans
            .iter()
            .find(|p| (p.first_id..p.end_id).contains(&id))
    }
}

/// Notes where the waiting particles are, before G2P moves them.
pub(super) fn park<const D: usize, K: Kernel>(sim: &mut Simulation<D, K>)
where
    dyn Material: DimensionDispatch<D>,
{
    let Some(inflows) = sim.inflow.as_mut() else {
        return;
    };
    inflows.parked.clear();
    let Some(injected) = sim.particles.shared.get(INJECTED) else {
        return;
    };
    for (i, flag) in injected.iter().enumerate() {
        if *flag < 0.5 {
            inflows.parked.push((i, sim.particles.position[i]));
        }
    }
}

/// After G2P: puts the waiting particles back and lets in those whose entry time falls
/// within the step that ends at `sim.time + dt`; stops the run when they would fill more
/// than the domain's open volume.
pub(super) fn enter<const D: usize, K: Kernel>(sim: &mut Simulation<D, K>, dt: f64)
where
    dyn Material: DimensionDispatch<D>,
{
    let Some(mut inflows) = sim.inflow.take() else {
        return;
    };
    let open_volume = *inflows
        .open_volume
        .get_or_insert_with(|| open_volume(&sim.grid, &sim.boundaries));
    for (layout, drive) in inflows.drives_mut() {
        drive.step(layout, &sim.particles, sim.time, dt);
    }
    let now = sim.time + dt;
    let gravity = sim.settings.gravity;
    let (kinematics, ledger) = (&mut sim.kinematics, &mut sim.ledger);
    let Particles {
        position,
        velocity,
        mass,
        volume0,
        stress,
        stress_zz,
        affine,
        velocity_gradient,
        id,
        shared,
        ..
    } = &mut sim.particles;
    let Some(injected) = shared.get_mut(INJECTED) else {
        // Set-up allocates it with the inflows; nothing can enter without it.
        sim.inflow = Some(inflows);
        return;
    };
    inflows.entered.clear();
    let mut entering = 0.0;
    let mut due = 0usize;
    for &(i, x) in &inflows.parked {
        position[i] = x;
        velocity[i] = Vector::<D>::zeros();
        // Particles that left through an outlet (−1) never come back.
        if injected[i] != 0.0 {
            continue;
        }
        if let Some(plan) = inflows.plan_of(id[i])
            && plan.is_due((id[i] - plan.first_id) as usize, now)
        {
            entering += plan.volume;
            due += 1;
        }
    }
    if due == 0 {
        sim.inflow = Some(inflows);
        return;
    }
    let liquid: f64 = volume0.iter().sum();
    if liquid + entering > open_volume * (1.0 + 1e-12) {
        // Name the inlet of the first particle that is due (a pressure inlet's reservoir
        // holds more than the domain: the flow it drives would go on filling it).
        let plan = inflows.parked.iter().find_map(|&(i, _)| {
            let plan = inflows.plan_of(id[i])?;
            (injected[i] == 0.0 && plan.is_due((id[i] - plan.first_id) as usize, now))
                .then_some(plan)
        });
        let name = plan.map_or_else(String::new, |p| p.name.clone());
        let remedy = if plan.is_some_and(|p| p.drive.is_some()) {
            "give its reservoir a smaller `volume`, end the inflow sooner with its `end`"
        } else {
            "end the inflow sooner with its `end`, lower its `rate`"
        };
        sim.report.fail(PhysicsFault {
            field: INJECTED.into(),
            particle: None,
            value: liquid + entering,
            message: format!(
                "inflow `{name}`: {due} entering particles would take the liquid to {:.4e} \
                 of volume, past the {open_volume:.4e} the domain holds outside walls and \
                 obstacles: the liquid has nowhere to go ({remedy}, or enlarge the domain)",
                liquid + entering
            ),
        });
        sim.inflow = Some(inflows);
        return;
    }
    for &(i, waiting) in &inflows.parked {
        if injected[i] != 0.0 {
            continue;
        }
        let Some(plan) = inflows.plan_of(id[i]) else {
            continue;
        };
        let index = (id[i] - plan.first_id) as usize;
        if !plan.is_due(index, now) {
            continue;
        }
        let (place, entry_velocity) = plan.entry(index, waiting, now);
        position[i] = place;
        velocity[i] = entry_velocity;
        mass[i] = plan.mass;
        // The step's statistics were taken before it entered: count it in them and book
        // the energy it brings, so the energy balance stays the method's own error.
        let speed2 = entry_velocity.norm_squared();
        let energy = plan.mass * (0.5 * speed2 - gravity.dot(&position[i]));
        kinematics.kinetic_energy += 0.5 * plan.mass * speed2;
        kinematics.gravity_energy -= plan.mass * gravity.dot(&position[i]);
        kinematics.momentum += entry_velocity * plan.mass;
        ledger.openings += energy;
        volume0[i] = plan.volume;
        stress[i] = Matrix::<D>::zeros();
        if let Some(zz) = stress_zz.get_mut(i) {
            *zz = 0.0;
        }
        if let Some(b) = affine.get_mut(i) {
            *b = Matrix::<D>::zeros();
        }
        if let Some(l) = velocity_gradient.get_mut(i) {
            *l = Matrix::<D>::zeros();
        }
        injected[i] = 1.0;
        inflows.entered.push(i);
    }
    sim.inflow = Some(inflows);
}

/// Volume of the domain's cells that are neither behind a wall nor inside an obstacle.
fn open_volume<const D: usize>(
    grid: &crate::grid::Grid<D>,
    boundaries: &crate::boundary::Boundaries<D>,
) -> f64 {
    let pad = crate::boundary::GRID_PADDING;
    let mut inside = [1usize; 3];
    for (n, cells) in inside.iter_mut().zip(&grid.cells[..D]) {
        *n = cells.saturating_sub(2 * pad);
    }
    let mut open = 0usize;
    for k in 0..inside[2] {
        for j in 0..inside[1] {
            for i in 0..inside[0] {
                let mut ijk = [i + pad, j + pad, 0];
                if D == 3 {
                    ijk[2] = k + pad;
                }
                let mut centre = node_position(&grid.origin, grid.dx, ijk);
                for d in 0..D {
                    centre[d] += 0.5 * grid.dx;
                }
                if !boundaries.cell_is_solid(ijk, &centre) {
                    open += 1;
                }
            }
        }
    }
    open as f64 * grid.dx.powi(D as i32)
}
