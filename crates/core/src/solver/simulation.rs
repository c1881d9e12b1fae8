//! The state of a run (grid, particles, boundaries, physics operators, statistics) and the
//! stages every time-integration mode is made of.

use super::DimensionDispatch;
use super::binning::{Reorder, SlabBins};
use super::grid_to_particle::{G2pParams, grid_to_particle, measure};
use super::grid_update::{GridParams, GridWork, update_grid};
use super::interpolation::build_compact_interpolation;
use super::mode::StepMode;
use super::multi_field::MultiField;
use super::particle_to_grid::{ForceTerm, P2gParams, particle_to_grid};
use super::stage_clock::{StageClock, StepStage};
use super::stats::{KinematicStats, ParticleFault};
use super::stress_update::{StressScratch, StressStats, update_stress};
use super::timestep::stable_time_step;
use super::volume_averaging::VolumeAverage;
use crate::boundary::Boundaries;
use crate::energy_ledger::EnergyLedger;
use crate::grid::Grid;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::Vector;
use crate::output::FieldInfo;
use crate::particles::Particles;
use crate::physics::{
    GroupView, Interpolation, ParticleView, Physics, PhysicsContext, PhysicsReport, Stage,
};
use crate::reference::Reference;
use crate::scene::{Mechanics, Scheme, Transfer};
use std::sync::Arc;
use std::time::Instant;

/// One physics operator of a run with its grid scratch arrays.
pub(super) struct PhysicsSlot {
    pub(super) physics: Arc<dyn Physics>,
    pub(super) scratch: Vec<Vec<f64>>,
}

/// Settings of the run taken from the scene.
#[derive(Clone, Debug)]
pub(super) struct Settings<const D: usize> {
    pub(super) transfer: Transfer,
    pub(super) flip_blend: f64,
    pub(super) xpic_order: u32,
    pub(super) mls: bool,
    pub(super) scheme: Scheme,
    pub(super) cfl: f64,
    pub(super) fixed_dt: Option<f64>,
    pub(super) max_cfl: f64,
    pub(super) end_time: f64,
    pub(super) end_when: Option<String>,
    pub(super) gravity: Vector<D>,
    pub(super) damping: f64,
    pub(super) sort_interval: u32,
    pub(super) frames: u32,
    pub(super) checkpoint: Option<crate::scene::CheckpointSchedule>,
    pub(super) max_speed: Option<f64>,
    pub(super) max_energy_growth: f64,
    pub(super) min_dt: f64,
    pub(super) mechanics: Mechanics,
}

/// An explicit MPM simulation in `D` dimensions with kernel `K`.
pub struct Simulation<const D: usize, K: Kernel> {
    /// The background grid.
    pub grid: Grid<D>,
    /// The particles.
    pub particles: Particles<D>,
    pub(super) boundaries: Boundaries<D>,
    pub(super) settings: Settings<D>,
    pub(super) bins: SlabBins,
    pub(super) reorder: Reorder,
    /// Wall time per stage of the step.
    pub(super) clock: StageClock,
    pub(super) reference: Option<Box<dyn Reference>>,
    pub(super) fields: Vec<FieldInfo>,
    pub(super) staging: Vec<Vec<f64>>,
    pub(super) scene_json: serde_json::Value,
    pub(super) name: String,
    pub(super) time: f64,
    /// The step the controller chose for the step being taken, s: longer than the step
    /// when it was cut short to land on an output time (or the end), else the same.
    pub(super) chosen_dt: f64,
    pub(super) steps: u64,
    pub(super) kinematics: KinematicStats<D>,
    pub(super) stresses: StressStats,
    /// Work done on the bodies and energy dissipated, by cause, since the run started.
    pub(super) ledger: EnergyLedger,
    /// Total (kinetic + strain + gravity + surface) energy at the start of the run.
    pub(super) energy0: f64,
    /// Energy stored in the liquids' surfaces (incompressible mode with surface tension):
    /// σ times the free surface's area, plus (γ_SL − γ_SV) = −σ cos θ times the area the
    /// liquid wets on walls and obstacles with a contact angle, J (J/m in 2D); 0 elsewhere.
    /// Measured at the positions the last step started from.
    pub(super) surface_energy: f64,
    pub(super) volume_average: Option<VolumeAverage>,
    pub(super) physics: Vec<PhysicsSlot>,
    pub(super) interpolation: Interpolation<D>,
    pub(super) needs_interpolation: bool,
    pub(super) group_views: Vec<GroupView>,
    pub(super) report: PhysicsReport,
    pub(super) stress_scratch: StressScratch<D>,
    /// Smallest stable step of the explicit physics operators, after the last step.
    pub(super) physics_dt: f64,
    /// The clock obstacles see during quasi-static relaxation (the end of the step).
    pub(super) relax_time: Option<f64>,
    /// Mechanical steps taken, for the reordering interval.
    pub(super) sort_counter: u64,
    /// Grid velocity fields of contact between bodies (`None` without a `contact` section).
    pub(super) contact: Option<MultiField<D>>,
    /// What a staged run adds to every checkpoint's state (`stage`: the stage's index and
    /// the summaries of the stages before); `Null` outside staged runs.
    pub(super) stage_tag: serde_json::Value,
    /// Liquid entering through inlets (`inflow` bodies; incompressible mode only).
    pub(super) inflow: Option<super::incompressible::inflow::Inflows<D>>,
    /// The time-integration mode (taken out while it advances the simulation).
    pub(super) mode: Option<Box<dyn StepMode<D, K>>>,
    pub(super) _kernel: std::marker::PhantomData<K>,
}

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// The scene's walls and obstacles as they act on the grid (reduced-order runs reuse
    /// them for their own grid updates).
    pub fn boundaries(&self) -> &Boundaries<D> {
        &self.boundaries
    }

    /// Simulated time.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Total momentum of the particles after the last step.
    pub fn momentum(&self) -> Vector<D> {
        self.kinematics.momentum
    }

    /// Work done on the bodies and energy dissipated so far, by cause.
    pub fn energy_ledger(&self) -> EnergyLedger {
        self.ledger
    }

    /// Kinetic + strain + gravitational + surface energy after the last step.
    pub fn total_energy(&self) -> f64 {
        self.kinematics.kinetic_energy
            + self.stresses.batch.strain_energy
            + self.kinematics.gravity_energy
            + self.surface_energy
    }

    /// Lets the mode measure the energy it stores itself (the liquids' surface energy) at
    /// the current positions, before a run or a stage takes its starting energy.
    /// A mode that stores none leaves 0 (a stage after a liquid one does not keep its
    /// surface energy).
    pub(super) fn measure_stored_energy(&mut self) {
        self.surface_energy = 0.0;
        if let Some(mut mode) = self.mode.take() {
            mode.measure_stored_energy(self);
            self.mode = Some(mode);
        }
    }

    /// The largest stable step for the current state (Courant number 1), as the run's
    /// time-integration mode bounds it.
    pub fn stable_dt(&self) -> f64 {
        self.mode
            .as_ref()
            .map_or(self.physics_dt, |mode| mode.stable_dt(self))
    }

    /// The mechanical (CFL) bound on the step at Courant number 1.
    pub(super) fn mechanical_dt(&self) -> f64 {
        stable_time_step(
            self.grid.dx,
            self.kinematics.max_speed,
            self.stresses.batch.max_wave_speed,
        )
    }

    /// Calls `visit` with every physics operator, in order, and its context for a step of
    /// `dt` ending at `time`.
    pub(super) fn each_physics(
        &mut self,
        dt: f64,
        time: f64,
        mut visit: impl FnMut(&dyn Physics, PhysicsContext<'_, D>),
    ) {
        let Particles {
            position,
            mass,
            volume0,
            deformation_gradient,
            stress,
            shared,
            contact_field,
            ..
        } = &mut self.particles;
        for slot in &mut self.physics {
            let ctx = PhysicsContext {
                dt,
                time,
                grid: &self.grid,
                interpolation: &self.interpolation,
                particles: ParticleView {
                    position,
                    mass,
                    volume0,
                    deformation_gradient,
                    stress,
                    groups: &self.group_views,
                    contact_field,
                },
                boundaries: &self.boundaries,
                fields: shared,
                scratch: &mut slot.scratch,
                report: &mut self.report,
            };
            visit(slot.physics.as_ref(), ctx);
        }
    }

    /// Runs one stage of every physics operator, in order.
    pub(super) fn physics_stage(&mut self, stage: Stage, dt: f64) {
        self.each_physics(dt, self.time + dt, |physics, ctx| {
            <dyn Material as DimensionDispatch<D>>::physics_stage(physics, stage, ctx)
        });
    }

    /// The smallest stable step of the physics operators (infinite for implicit ones).
    pub(super) fn compute_physics_dt(&mut self) -> f64 {
        let mut dt = f64::INFINITY;
        self.each_physics(0.0, self.time, |physics, ctx| {
            dt = dt.min(<dyn Material as DimensionDispatch<D>>::physics_stable_dt(
                physics, ctx,
            ));
        });
        dt
    }

    /// Advances every physics operator by `dt` (between the kinematic and the stress
    /// update); `moved`: particles moved since the stencils were built.
    pub(super) fn advance_physics(&mut self, dt: f64, moved: bool) {
        if self.physics.is_empty() {
            return;
        }
        let start = Instant::now();
        if self.needs_interpolation && (moved || self.interpolation.node.is_empty()) {
            self.build_physics_stencils();
        }
        for stage in [Stage::Prepare, Stage::Advance, Stage::Finish] {
            self.physics_stage(stage, dt);
        }
        self.physics_dt = self.compute_physics_dt();
        self.clock.add(StepStage::Physics, start);
    }

    /// Builds the physics operators' stencils with compact rows at the current positions
    /// and sizes each operator's scratch arrays to them.
    pub(super) fn build_physics_stencils(&mut self) {
        build_compact_interpolation::<D, K>(&self.grid, &self.particles, &mut self.interpolation);
        let rows = self.interpolation.row_count(self.grid.len());
        // An operator without stencils keeps one row per grid node (set-up).
        for slot in self
            .physics
            .iter_mut()
            .filter(|s| s.physics.needs_interpolation())
        {
            let len = rows * slot.physics.values_per_row();
            for a in &mut slot.scratch {
                a.resize(len, 0.0);
            }
        }
    }

    /// Stress update of every material (none with mechanics off).
    pub(super) fn update_stresses(&mut self, dt: f64) {
        if self.settings.mechanics != Mechanics::Off {
            let start = Instant::now();
            self.stresses = update_stress(&mut self.particles, dt, &mut self.stress_scratch);
            self.clock.add(StepStage::Stress, start);
            self.ledger.free_strain += self.stresses.free_strain_work;
            self.ledger.plastic += self.stresses.plastic_work;
        }
    }

    /// Reorders the particles by cell every `solver.sort_interval` steps (this one
    /// counted): the start of every mode's step.
    pub(super) fn reorder_if_due(&mut self) {
        let sort = self.settings.sort_interval;
        if sort > 0 && self.sort_counter.is_multiple_of(sort as u64) {
            let start = Instant::now();
            let applied = self.stress_scratch.applied_mut();
            self.reorder.apply(&self.grid, &mut self.particles, applied);
            self.clock.add(StepStage::Sort, start);
        }
        self.sort_counter += 1;
    }

    /// The internal-force term of P2G: the MLS-MPM form or the standard one.
    pub(super) fn force_term(&self) -> ForceTerm {
        if self.settings.mls {
            ForceTerm::Mls
        } else {
            ForceTerm::Standard
        }
    }

    pub(super) fn inertia(&self) -> f64 {
        K::APIC_INERTIA.unwrap_or(0.25)
    }

    /// Whether P2G keeps the forces apart and the grid update the velocity before them:
    /// FLIP's velocity change and XPIC's extrapolation need both.
    pub(super) fn forces_apart(&self) -> bool {
        matches!(self.settings.transfer, Transfer::Flip | Transfer::Xpic)
    }

    pub(super) fn p2g(&mut self, dt: f64, mass: bool, force: ForceTerm) {
        let params = P2gParams {
            dt,
            mass,
            force,
            force_apart: self.forces_apart(),
            affine: self.settings.transfer == Transfer::Apic,
            inertia: self.inertia(),
            gravity: self.settings.gravity,
        };
        let start = Instant::now();
        particle_to_grid::<D, K>(&mut self.grid, &self.particles, &self.bins, params);
        self.clock.add(StepStage::P2g, start);
    }

    pub(super) fn grid_update(&mut self, dt: f64, forces: bool) {
        let work = self.grid_update_work(dt, forces);
        if forces {
            self.ledger.boundaries += work.boundaries;
            self.ledger.damping += work.damping;
            self.ledger.friction += work.friction;
        }
    }

    pub(super) fn grid_update_work(&mut self, dt: f64, forces: bool) -> GridWork {
        let params = GridParams {
            dt,
            forces,
            flip: forces && self.forces_apart(),
            damping: self.settings.damping,
            time: self.relax_time.unwrap_or(self.time + dt),
        };
        let start = Instant::now();
        let work = update_grid(&mut self.grid, &self.boundaries, params);
        self.clock.add(StepStage::GridUpdate, start);
        work
    }

    pub(super) fn g2p(&mut self, dt: f64, velocity: bool, position: bool, deformation: bool) {
        let params = G2pParams {
            dt,
            transfer: self.settings.transfer,
            flip_blend: self.settings.flip_blend,
            velocity,
            position,
            deformation,
            gradient_from_affine: self.settings.mls && velocity && deformation,
            gravity: self.settings.gravity,
        };
        let fields = self.contact.as_ref().map_or(&[][..], |c| &c.grids[..]);
        if velocity && self.settings.transfer == Transfer::Xpic {
            let start = Instant::now();
            let order = self.settings.xpic_order;
            super::xpic::extrapolate::<D, K>(
                &mut self.grid,
                &self.particles,
                &self.bins,
                &self.boundaries,
                order,
                self.relax_time.unwrap_or(self.time + dt),
            );
            self.clock.add(StepStage::G2p, start);
        }
        let start = Instant::now();
        let stats = grid_to_particle::<D, K>(&self.grid, fields, &mut self.particles, params);
        self.clock.add(StepStage::G2p, start);
        self.take_kinematics(stats, velocity);
    }

    /// Keeps a G2P pass's statistics: all of them after a pass that updated velocities,
    /// else the F and position checks only.
    pub(super) fn take_kinematics(&mut self, stats: KinematicStats<D>, velocity: bool) {
        if velocity {
            self.kinematics = stats;
        } else {
            // A pass that did not change velocities still reports F and position checks.
            self.kinematics.min_det_f = stats.min_det_f;
            self.kinematics.min_det_particle = stats.min_det_particle;
            self.kinematics.non_finite =
                ParticleFault::first(self.kinematics.non_finite, stats.non_finite);
            self.kinematics.escaped = ParticleFault::first(self.kinematics.escaped, stats.escaped);
            self.kinematics.gravity_energy = stats.gravity_energy;
        }
    }

    /// F-bar: averages J over the grid before the stress update (when the scene asks).
    /// `moved`: particles moved since the bins were built, so rebuild them.
    pub(super) fn average_volume(&mut self, moved: bool, dt: f64) {
        if let Some(average) = &mut self.volume_average {
            let start = Instant::now();
            if moved {
                self.bins.rebuild::<D, K>(&self.grid, &self.particles);
            }
            average.apply::<D, K>(&self.grid, &mut self.particles, &self.bins, dt);
            self.clock.add(StepStage::VolumeAverage, start);
        }
    }

    /// Advances one step of size `dt` with the scene's time-integration mode.
    pub fn step(&mut self, dt: f64) {
        if let Some(mut mode) = self.mode.take() {
            let (start, timed) = (Instant::now(), self.clock.total());
            mode.advance(self, dt);
            // What the stages inside did not time is the mode's own work.
            let inner = self.clock.total() - timed;
            let rest = (start.elapsed().as_secs_f64() - inner).max(0.0);
            self.clock.add_seconds(StepStage::Solve, rest);
            self.mode = Some(mode);
        }
        if let Some(g) = self
            .stress_scratch
            .generalized
            .as_ref()
            .filter(|g| g.most_evaluations > 0)
        {
            // Generalized plane strain: how far the section contracts or stretches along z,
            // and how its solve went (nothing while no stress update ran: mechanics off).
            let report = &mut self.report;
            report.record_max("generalized_plane_strain.largest_strain", g.strain.abs());
            report.record_max(
                "generalized_plane_strain.most_evaluations",
                g.most_evaluations as f64,
            );
            report.record_max(
                "generalized_plane_strain.unbalanced",
                f64::from(u8::from(g.unbalanced)),
            );
        }
        self.time += dt;
        self.steps += 1;
    }

    /// The stress and statistics of the initial state (F = I), before the first step; the
    /// physics operators set their initial fields.
    pub(super) fn initialise(&mut self) {
        if !self.physics.is_empty() {
            if self.needs_interpolation {
                self.build_physics_stencils();
            }
            for stage in [Stage::Initialise, Stage::Prepare, Stage::Finish] {
                self.physics_stage(stage, 0.0);
            }
            self.physics_dt = self.compute_physics_dt();
        }
        // The stage clock times steps, not this set-up.
        let clock = self.clock.clone();
        self.update_stresses(0.0);
        self.ledger = EnergyLedger::default();
        self.kinematics = measure(&self.particles, self.settings.gravity);
        self.measure_stored_energy();
        self.clock = clock;
        self.energy0 = self.total_energy();
    }
}
