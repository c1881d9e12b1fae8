//! The explicit MPM step pipeline and the run loop.
//!
//! One step (USL): P2G → grid update → G2P (velocity, position, F) → stress update.
//! USF updates F and stress from the P2G velocity before the momentum update; MUSL maps the
//! updated particle velocities back to the grid before updating F (see [`Simulation::step`]).

mod binning;
mod grid_to_particle;
pub mod grid_update;
mod interpolation;
mod parallel;
mod particle_to_grid;
mod stats;
pub mod stencil;
mod stress_update;
mod timestep;
mod volume_averaging;

use crate::boundary::Boundaries;
use crate::grid::Grid;
use crate::kernels::{CubicBSpline, Kernel, Linear, QuadraticBSpline, UniformGimp};
use crate::material::{BatchStats, FieldInit, Material, StressBatch};
use crate::math::{Matrix, Vector, determinant, vector_from_slice};
use crate::output::{
    Diagnostic, FRAME_DIAGNOSTICS, FieldInfo, Frame, Metrics, Outcome, OutputError, OutputSink,
    RunInfo,
};
use crate::particles::{MaterialGroup, Particles};
use crate::physics::{
    GroupView, Interpolation, ParticleFields, ParticleView, Physics, PhysicsContext, PhysicsReport,
    Stage,
};
use crate::reference::ReferenceTracker;
use crate::scene::{KernelName, Mechanics, Scheme, Transfer, ValidatedScene};
use binning::{Reorder, SlabBins};
use grid_to_particle::{G2pParams, grid_to_particle, measure};
use grid_update::{GridParams, update_grid};
use interpolation::build_interpolation;
use particle_to_grid::{ForceTerm, P2gParams, particle_to_grid};
use stats::{KinematicStats, ParticleFault};
use std::sync::Arc;
use std::time::Instant;
use stress_update::{StressScratch, StressStats, update_stress};
use volume_averaging::VolumeAverage;

pub use timestep::stable_time_step;

/// Selects the 2D or 3D entry points of plugin objects (a [`Material`]'s stress update, a
/// [`Physics`] operator's stages); implemented for D = 2 and 3 so the solver can stay
/// generic over the dimension.
pub trait DimensionDispatch<const D: usize> {
    /// Updates one batch.
    fn update(&self, batch: StressBatch<'_, D>) -> BatchStats;
    /// Runs one stage of a physics operator.
    fn physics_stage(physics: &dyn Physics, stage: Stage, ctx: PhysicsContext<'_, D>);
    /// A physics operator's stable step.
    fn physics_stable_dt(physics: &dyn Physics, ctx: PhysicsContext<'_, D>) -> f64;
}

impl DimensionDispatch<2> for dyn Material {
    fn update(&self, batch: StressBatch<'_, 2>) -> BatchStats {
        self.update_stress_2d(batch)
    }
    fn physics_stage(physics: &dyn Physics, stage: Stage, ctx: PhysicsContext<'_, 2>) {
        physics.stage_2d(stage, ctx)
    }
    fn physics_stable_dt(physics: &dyn Physics, ctx: PhysicsContext<'_, 2>) -> f64 {
        physics.stable_dt_2d(ctx)
    }
}

impl DimensionDispatch<3> for dyn Material {
    fn update(&self, batch: StressBatch<'_, 3>) -> BatchStats {
        self.update_stress_3d(batch)
    }
    fn physics_stage(physics: &dyn Physics, stage: Stage, ctx: PhysicsContext<'_, 3>) {
        physics.stage_3d(stage, ctx)
    }
    fn physics_stable_dt(physics: &dyn Physics, ctx: PhysicsContext<'_, 3>) -> f64 {
        physics.stable_dt_3d(ctx)
    }
}

/// One physics operator of a run with its grid scratch arrays.
struct PhysicsSlot {
    physics: Arc<dyn Physics>,
    scratch: Vec<Vec<f64>>,
}

/// Failures that are not a run stopping on its own checks.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The result writer failed.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The scene cannot start (a fixed time step above the stable one, say).
    #[error("{path}: {message}")]
    Refused {
        /// JSON path of the setting at fault.
        path: String,
        /// Why.
        message: String,
    },
}

/// Progress of a run, reported after every step.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Steps taken.
    pub step: u64,
    /// Simulated time.
    pub time: f64,
    /// Simulated end time.
    pub end_time: f64,
    /// Last time step.
    pub dt: f64,
    /// Wall seconds since the start of the loop.
    pub wall_seconds: f64,
}

/// What an observer tells the run after a progress report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Control {
    /// Go on.
    Continue,
    /// Stop now, keeping what was written.
    Cancel,
}

/// Watches a run (progress bars, job services, cancellation).
pub trait RunObserver {
    /// Called after every step; cheap implementations only.
    fn progress(&mut self, progress: &Progress) -> Control;
}

impl<F: FnMut(&Progress) -> Control> RunObserver for F {
    fn progress(&mut self, progress: &Progress) -> Control {
        self(progress)
    }
}

/// Settings of the run taken from the scene.
#[derive(Clone, Debug)]
struct Settings<const D: usize> {
    transfer: Transfer,
    flip_blend: f64,
    mls: bool,
    scheme: Scheme,
    cfl: f64,
    fixed_dt: Option<f64>,
    max_cfl: f64,
    end_time: f64,
    gravity: Vector<D>,
    damping: f64,
    sort_interval: u32,
    frames: u32,
    max_speed: Option<f64>,
    max_energy_growth: f64,
    min_dt: f64,
    mechanics: Mechanics,
}

/// An explicit MPM simulation in `D` dimensions with kernel `K`.
pub struct Simulation<const D: usize, K: Kernel> {
    /// The background grid.
    pub grid: Grid<D>,
    /// The particles.
    pub particles: Particles<D>,
    boundaries: Boundaries<D>,
    settings: Settings<D>,
    bins: SlabBins,
    reorder: Reorder,
    reference: Option<ReferenceTracker>,
    fields: Vec<FieldInfo>,
    staging: Vec<Vec<f64>>,
    scene_json: serde_json::Value,
    name: String,
    time: f64,
    steps: u64,
    kinematics: KinematicStats<D>,
    stresses: StressStats,
    boundary_work: f64,
    volume_average: Option<VolumeAverage>,
    physics: Vec<PhysicsSlot>,
    interpolation: Interpolation<D>,
    needs_interpolation: bool,
    group_views: Vec<GroupView>,
    report: PhysicsReport,
    stress_scratch: StressScratch<D>,
    /// Smallest stable step of the explicit physics operators, after the last step.
    physics_dt: f64,
    /// The clock obstacles see during quasi-static relaxation (the end of the step).
    relax_time: Option<f64>,
    /// Mechanical steps taken, for the reordering interval.
    sort_counter: u64,
    _kernel: std::marker::PhantomData<K>,
}

/// Receives a simulation built for the scene's dimension and kernel (see [`dispatch`]).
pub trait SimulationVisitor {
    /// What the visit returns.
    type Output;
    /// Called with the concrete simulation.
    fn visit<const D: usize, K: Kernel>(self, simulation: Simulation<D, K>) -> Self::Output
    where
        dyn Material: DimensionDispatch<D>;
}

/// Builds the simulation for a validated scene and hands it to `visitor`: the one place that
/// turns the scene's dimension and kernel into types.
pub fn dispatch<V: SimulationVisitor>(scene: &ValidatedScene, visitor: V) -> V::Output {
    match (scene.scene.dimension, scene.scene.solver.kernel) {
        (2, KernelName::Linear) => visitor.visit(Simulation::<2, Linear>::new(scene)),
        (2, KernelName::Gimp) => visitor.visit(Simulation::<2, UniformGimp>::new(scene)),
        (2, KernelName::Bspline2) => visitor.visit(Simulation::<2, QuadraticBSpline>::new(scene)),
        (2, KernelName::Bspline3) => visitor.visit(Simulation::<2, CubicBSpline>::new(scene)),
        (_, KernelName::Linear) => visitor.visit(Simulation::<3, Linear>::new(scene)),
        (_, KernelName::Gimp) => visitor.visit(Simulation::<3, UniformGimp>::new(scene)),
        (_, KernelName::Bspline2) => visitor.visit(Simulation::<3, QuadraticBSpline>::new(scene)),
        (_, KernelName::Bspline3) => visitor.visit(Simulation::<3, CubicBSpline>::new(scene)),
    }
}

/// Runs a validated scene to its end time (or until it stops), writing to `sink`.
pub fn run_scene(
    scene: &ValidatedScene,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RunError> {
    struct Run<'a> {
        sink: &'a mut dyn OutputSink,
        observer: &'a mut dyn RunObserver,
    }
    impl SimulationVisitor for Run<'_> {
        type Output = Result<Metrics, RunError>;
        fn visit<const D: usize, K: Kernel>(self, mut sim: Simulation<D, K>) -> Self::Output
        where
            dyn Material: DimensionDispatch<D>,
        {
            sim.run(self.sink, self.observer)
        }
    }
    dispatch(scene, Run { sink, observer })
}

/// Checks what only the built simulation can tell (the fixed time step against the stable
/// one), without running a step. `mpm validate` and job submission call it.
pub fn preflight(scene: &ValidatedScene) -> Result<(), RunError> {
    struct Check;
    impl SimulationVisitor for Check {
        type Output = Result<(), RunError>;
        fn visit<const D: usize, K: Kernel>(self, mut sim: Simulation<D, K>) -> Self::Output
        where
            dyn Material: DimensionDispatch<D>,
        {
            sim.preflight()
        }
    }
    dispatch(scene, Check)
}

/// Particle storage a scene allocates, bytes per particle, without running it.
pub fn bytes_per_particle(scene: &ValidatedScene) -> f64 {
    struct Bytes;
    impl SimulationVisitor for Bytes {
        type Output = f64;
        fn visit<const D: usize, K: Kernel>(self, sim: Simulation<D, K>) -> f64
        where
            dyn Material: DimensionDispatch<D>,
        {
            sim.particles.bytes_per_particle()
        }
    }
    dispatch(scene, Bytes)
}

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Builds grid and particles for a validated scene; allocates only what it needs.
    pub fn new(v: &ValidatedScene) -> Self {
        let s = &v.scene;
        let dx = s.domain.cell_size;
        let pad = crate::boundary::GRID_PADDING;
        let mut min: Vector<D> = vector_from_slice(&s.domain.min);
        let mut domain_cells = [1usize; 3];
        let mut cells = [1usize; 3];
        for d in 0..D {
            domain_cells[d] = ((s.domain.max[d] - s.domain.min[d]) / dx - 1e-9).ceil() as usize;
            cells[d] = domain_cells[d] + 2 * pad;
            min[d] -= pad as f64 * dx;
        }
        let flip = s.solver.transfer == Transfer::Flip;
        let grid = Grid::new(min, cells, dx, flip);

        let reference = s.reference.clone().map(ReferenceTracker::new);
        // F-bar averages this step's volume change, which it reads from the gradient.
        let needs_gradient = v.materials.values().any(|m| m.needs_velocity_gradient())
            || s.solver.anti_locking == crate::scene::AntiLocking::Fbar;
        let n = v.particle_count();
        let alloc_if = |yes: bool| if yes { n } else { 0 };
        let mut particles = Particles::<D> {
            position: Vec::with_capacity(n),
            velocity: Vec::with_capacity(n),
            mass: Vec::with_capacity(n),
            volume0: Vec::with_capacity(n),
            deformation_gradient: vec![Matrix::<D>::identity(); n],
            stress: vec![Matrix::<D>::zeros(); n],
            affine: vec![Matrix::<D>::zeros(); alloc_if(s.solver.transfer == Transfer::Apic)],
            velocity_gradient: vec![Matrix::<D>::zeros(); alloc_if(needs_gradient)],
            half_size: Vec::with_capacity(alloc_if(K::USES_PARTICLE_SIZE)),
            initial_position: Vec::with_capacity(alloc_if(
                reference
                    .as_ref()
                    .is_some_and(|r| r.needs_initial_positions()),
            )),
            id: Vec::with_capacity(n),
            groups: Vec::new(),
            shared: ParticleFields::default(),
        };
        for (_, physics) in &v.physics {
            for spec in physics.fields() {
                particles.shared.add(spec, n);
            }
        }
        // Bodies of one material are stored together so each law sees contiguous batches.
        let mut order: Vec<&crate::scene::BodyParticles> = v.bodies.iter().collect();
        order.sort_by_key(|b| &s.bodies[b.body].material);
        let mut output_index = vec![0usize; v.bodies.len()];
        let mut next = 0;
        for b in &v.bodies {
            output_index[b.body] = next;
            next += b.volumes.len();
        }
        for body in order {
            let name = &s.bodies[body.body].material;
            let material = v.materials[name].clone();
            let start = particles.position.len();
            let count = body.volumes.len();
            if particles.groups.last().is_none_or(|g| &g.name != name) {
                particles.groups.push(MaterialGroup {
                    name: name.clone(),
                    material: material.clone(),
                    range: start..start,
                    state: Vec::new(),
                });
            }
            for p in 0..count {
                let x: Vector<D> = vector_from_slice(&body.positions[p * D..]);
                particles.position.push(x);
                particles
                    .velocity
                    .push(vector_from_slice(&body.velocities[p * D..]));
                particles.volume0.push(body.volumes[p]);
                particles.mass.push(body.volumes[p] * material.density());
                particles.id.push((output_index[body.body] + p) as u32);
                if K::USES_PARTICLE_SIZE {
                    particles.half_size.push(0.5 * body.spacing / dx);
                }
                if particles.initial_position.capacity() > 0 {
                    particles.initial_position.push(x);
                }
            }
            particles.groups.last_mut().unwrap().range.end = start + count;
        }
        for group in &mut particles.groups {
            let count = group.range.len();
            group.state = group
                .material
                .state_fields()
                .iter()
                .map(|spec| {
                    let c = spec.components;
                    let mut field = vec![0.0; count * c];
                    match spec.initial {
                        FieldInit::Zero => {}
                        FieldInit::Identity => {
                            for p in 0..count {
                                for d in 0..D {
                                    field[p * c + d * D + d] = 1.0;
                                }
                            }
                        }
                        FieldInit::Constant(value) => field.fill(value),
                        FieldInit::Values(values) => {
                            for chunk in field.chunks_exact_mut(c) {
                                for (x, v) in chunk.iter_mut().zip(values) {
                                    *x = *v;
                                }
                            }
                        }
                    }
                    field
                })
                .collect();
        }

        let fields = output_fields::<D>(&s.output.fields, &particles);
        let staging = fields
            .iter()
            .map(|f| vec![0.0; f.components() * n])
            .collect();
        let settings = Settings {
            transfer: s.solver.transfer,
            flip_blend: s.solver.flip_blend,
            mls: s.solver.mls,
            scheme: s.solver.scheme,
            cfl: s.solver.cfl,
            fixed_dt: s.solver.dt,
            max_cfl: s.solver.max_cfl,
            end_time: s.solver.end_time,
            gravity: s
                .solver
                .gravity
                .as_deref()
                .map(vector_from_slice)
                .unwrap_or_else(Vector::<D>::zeros),
            damping: s.solver.damping,
            sort_interval: s.solver.sort_interval,
            frames: s.output.frames,
            max_speed: s.stop.max_speed,
            max_energy_growth: s.stop.max_energy_growth,
            min_dt: s.stop.min_dt,
            mechanics: s.solver.mechanics,
        };
        let group_views = particles
            .groups
            .iter()
            .map(|g| GroupView {
                name: g.name.clone(),
                range: g.range.clone(),
            })
            .collect();
        let physics: Vec<PhysicsSlot> = v
            .physics
            .iter()
            .map(|(_, p)| PhysicsSlot {
                physics: p.clone(),
                scratch: vec![vec![0.0; grid.len()]; p.grid_arrays()],
            })
            .collect();
        let needs_interpolation = physics.iter().any(|p| p.physics.needs_interpolation());
        let bins = SlabBins::new(grid.nodes[0], K::SPAN, n);
        let grid_nodes = grid.len();
        Self {
            boundaries: Boundaries::new(&s.domain.walls, &s.obstacles, domain_cells),
            grid,
            particles,
            settings,
            bins,
            reorder: Reorder::new(n),
            reference,
            fields,
            staging,
            scene_json: v.json.clone(),
            name: s.name.clone(),
            time: 0.0,
            steps: 0,
            kinematics: KinematicStats::default(),
            stresses: StressStats::default(),
            boundary_work: 0.0,
            volume_average: (s.solver.anti_locking == crate::scene::AntiLocking::Fbar)
                .then(|| VolumeAverage::new(grid_nodes)),
            physics,
            interpolation: Interpolation::default(),
            needs_interpolation,
            group_views,
            report: PhysicsReport::default(),
            stress_scratch: StressScratch::default(),
            physics_dt: f64::INFINITY,
            relax_time: None,
            sort_counter: 0,
            _kernel: std::marker::PhantomData,
        }
    }

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

    /// Work done on the body by moving obstacles so far.
    pub fn boundary_work(&self) -> f64 {
        self.boundary_work
    }

    /// Kinetic + strain + gravitational energy after the last step.
    pub fn total_energy(&self) -> f64 {
        self.kinematics.kinetic_energy
            + self.stresses.batch.strain_energy
            + self.kinematics.gravity_energy
    }

    /// The largest stable step for the current state (Courant number 1): the mechanical
    /// bound (dynamics only) and every explicit physics operator's.
    pub fn stable_dt(&self) -> f64 {
        match self.settings.mechanics {
            Mechanics::Dynamic => self.mechanical_dt().min(self.physics_dt),
            Mechanics::Off | Mechanics::QuasiStatic { .. } => self.physics_dt,
        }
    }

    /// The mechanical (CFL) bound on the step at Courant number 1.
    fn mechanical_dt(&self) -> f64 {
        stable_time_step(
            self.grid.dx,
            self.kinematics.max_speed,
            self.stresses.batch.max_wave_speed,
        )
    }

    /// Calls `visit` with every physics operator, in order, and its context for a step of
    /// `dt` ending at `time`.
    fn each_physics(
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
                },
                fields: shared,
                scratch: &mut slot.scratch,
                report: &mut self.report,
            };
            visit(slot.physics.as_ref(), ctx);
        }
    }

    /// Runs one stage of every physics operator, in order.
    fn physics_stage(&mut self, stage: Stage, dt: f64) {
        self.each_physics(dt, self.time + dt, |physics, ctx| {
            <dyn Material as DimensionDispatch<D>>::physics_stage(physics, stage, ctx)
        });
    }

    /// The smallest stable step of the physics operators (infinite for implicit ones).
    fn compute_physics_dt(&mut self) -> f64 {
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
    fn advance_physics(&mut self, dt: f64, moved: bool) {
        if self.physics.is_empty() {
            return;
        }
        if self.needs_interpolation && (moved || self.interpolation.node.is_empty()) {
            build_interpolation::<D, K>(&self.grid, &self.particles, &mut self.interpolation);
        }
        for stage in [Stage::Prepare, Stage::Advance, Stage::Finish] {
            self.physics_stage(stage, dt);
        }
        self.physics_dt = self.compute_physics_dt();
    }

    /// Stress update of every material (none with mechanics off).
    fn update_stresses(&mut self, dt: f64) {
        if self.settings.mechanics != Mechanics::Off {
            self.stresses = update_stress(&mut self.particles, dt, &mut self.stress_scratch);
            self.boundary_work += self.stresses.free_strain_work;
        }
    }

    fn inertia(&self) -> f64 {
        K::APIC_INERTIA.unwrap_or(0.25)
    }

    fn p2g(&mut self, dt: f64, mass: bool, force: ForceTerm) {
        let params = P2gParams {
            dt,
            mass,
            force,
            force_apart: self.settings.transfer == Transfer::Flip,
            affine: self.settings.transfer == Transfer::Apic,
            inertia: self.inertia(),
            gravity: self.settings.gravity,
        };
        particle_to_grid::<D, K>(&mut self.grid, &self.particles, &self.bins, params);
    }

    fn grid_update(&mut self, dt: f64, forces: bool) {
        let work = self.grid_update_work(dt, forces);
        if forces {
            self.boundary_work += work;
        }
    }

    fn grid_update_work(&mut self, dt: f64, forces: bool) -> f64 {
        let params = GridParams {
            dt,
            forces,
            flip: forces && self.settings.transfer == Transfer::Flip,
            damping: self.settings.damping,
            time: self.relax_time.unwrap_or(self.time + dt),
        };
        update_grid(&mut self.grid, &self.boundaries, params)
    }

    fn g2p(&mut self, dt: f64, velocity: bool, position: bool, deformation: bool) {
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
        let stats = grid_to_particle::<D, K>(&self.grid, &mut self.particles, params);
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
    fn average_volume(&mut self, moved: bool, dt: f64) {
        if let Some(average) = &mut self.volume_average {
            if moved {
                self.bins.rebuild::<D, K>(&self.grid, &self.particles);
            }
            average.apply::<D, K>(&self.grid, &mut self.particles, &self.bins, dt);
        }
    }

    /// Advances one step of size `dt`: physics, and mechanics as the scene says.
    pub fn step(&mut self, dt: f64) {
        match self.settings.mechanics {
            Mechanics::Dynamic => self.mechanical_step(dt, true),
            Mechanics::Off => self.advance_physics(dt, false),
            Mechanics::QuasiStatic {
                max_iterations,
                tolerance,
                damping,
            } => {
                self.advance_physics(dt, true);
                self.relax(dt, max_iterations, tolerance, damping);
            }
        }
        self.time += dt;
        self.steps += 1;
    }

    /// One explicit mechanical step with the scene's update scheme; with `physics`, the
    /// physics operators advance between the kinematic and the stress update.
    fn mechanical_step(&mut self, dt: f64, physics: bool) {
        let sort = self.settings.sort_interval;
        if sort > 0 && self.sort_counter.is_multiple_of(sort as u64) {
            self.reorder.apply(&self.grid, &mut self.particles);
        }
        self.sort_counter += 1;
        self.bins.rebuild::<D, K>(&self.grid, &self.particles);
        let force = if self.settings.mls {
            ForceTerm::Mls
        } else {
            ForceTerm::Standard
        };
        self.grid.clear();
        match self.settings.scheme {
            Scheme::Usl => {
                self.p2g(dt, true, force);
                self.grid_update(dt, true);
                self.g2p(dt, true, true, true);
                self.average_volume(true, dt);
                if physics {
                    self.advance_physics(dt, true);
                }
                self.update_stresses(dt);
            }
            Scheme::Usf => {
                self.p2g(dt, true, ForceTerm::None);
                self.grid_update(dt, false);
                self.g2p(dt, false, false, true);
                self.average_volume(false, dt);
                if physics {
                    self.advance_physics(dt, true);
                }
                self.update_stresses(dt);
                self.grid.clear();
                self.p2g(dt, true, force);
                self.grid_update(dt, true);
                self.g2p(dt, true, true, false);
            }
            Scheme::Musl => {
                self.p2g(dt, true, force);
                self.grid_update(dt, true);
                self.g2p(dt, true, false, false);
                // Map the new particle momentum back (mass is unchanged: same positions).
                self.grid.momentum.fill(Vector::<D>::zeros());
                self.p2g(dt, false, ForceTerm::None);
                self.grid_update(dt, false);
                let velocity_stats = self.kinematics;
                self.g2p(dt, false, true, true);
                self.kinematics.kinetic_energy = velocity_stats.kinetic_energy;
                self.average_volume(true, dt);
                if physics {
                    self.advance_physics(dt, true);
                }
                self.update_stresses(dt);
            }
        }
    }

    /// Quasi-static mechanics: damped explicit iterations (pseudo-time, the clock stands at
    /// the end of the step) until the kinetic energy is a `tolerance` fraction of the strain
    /// energy; then the body is brought to rest. Not converging stops the run.
    fn relax(&mut self, dt: f64, max_iterations: u32, tolerance: f64, damping: Option<f64>) {
        let saved_damping = self.settings.damping;
        let auto = || {
            let extent = (0..D)
                .map(|d| self.grid.cells[d] as f64 * self.grid.dx)
                .fold(0.0, f64::max);
            2.0 * std::f64::consts::PI * self.stresses.batch.max_wave_speed / extent.max(1e-300)
        };
        self.settings.damping = damping.unwrap_or_else(auto);
        self.relax_time = Some(self.time + dt);
        let mut peak = 0.0f64;
        let mut converged = false;
        let mut iterations = 0;
        while iterations < max_iterations {
            iterations += 1;
            let pseudo = self.settings.cfl * self.mechanical_dt();
            if !(pseudo.is_finite() && pseudo > 0.0) {
                break;
            }
            self.mechanical_step(pseudo, false);
            let kinetic = self.kinematics.kinetic_energy;
            if !kinetic.is_finite() || self.check(0.0).is_some() {
                break;
            }
            peak = peak.max(kinetic);
            let scale = self.stresses.batch.strain_energy.max(peak);
            if iterations >= 10 && kinetic <= tolerance * scale {
                converged = true;
                break;
            }
        }
        self.relax_time = None;
        self.settings.damping = saved_damping;
        self.particles.velocity.fill(Vector::<D>::zeros());
        self.particles.affine.fill(Matrix::<D>::zeros());
        let stats = measure(&self.particles, self.settings.gravity);
        self.kinematics.kinetic_energy = 0.0;
        self.kinematics.max_speed = 0.0;
        self.kinematics.momentum = stats.momentum;
        self.report
            .record_max("quasi_static.iterations", iterations as f64);
        if !converged && self.check(0.0).is_none() {
            self.report.fail(crate::physics::PhysicsFault {
                field: "relaxation".into(),
                particle: None,
                value: iterations as f64,
                message: format!(
                    "quasi-static relaxation did not reach equilibrium in {max_iterations} iterations (raise solver.mechanics.quasi_static.max_iterations or the damping, or take smaller steps)"
                ),
            });
        }
    }

    /// The stress and statistics of the initial state (F = I), before the first step; the
    /// physics operators set their initial fields.
    fn initialise(&mut self) {
        if !self.physics.is_empty() {
            if self.needs_interpolation {
                build_interpolation::<D, K>(&self.grid, &self.particles, &mut self.interpolation);
            }
            for stage in [Stage::Initialise, Stage::Prepare, Stage::Finish] {
                self.physics_stage(stage, 0.0);
            }
            self.physics_dt = self.compute_physics_dt();
        }
        self.update_stresses(0.0);
        self.boundary_work = 0.0;
        self.kinematics = measure(&self.particles, self.settings.gravity);
    }

    /// The first failed check after a step, as a diagnostic.
    fn check(&self, energy_growth: f64) -> Option<Diagnostic> {
        let make = |fault: ParticleFault, message: &str| Diagnostic {
            step: self.steps,
            time: self.time,
            particle: Some(self.particles.id[fault.particle] as usize),
            field: fault.field.into(),
            value: fault.value,
            message: message.into(),
        };
        if let Some(f) = self.kinematics.non_finite {
            return Some(make(f, "a particle value became NaN or infinite"));
        }
        if let Some(f) = self.stresses.non_finite {
            return Some(make(f, "a particle stress became NaN or infinite"));
        }
        if let Some(fault) = &self.report.fault {
            return Some(Diagnostic {
                step: self.steps,
                time: self.time,
                particle: fault.particle.map(|p| self.particles.id[p] as usize),
                field: fault.field.clone(),
                value: fault.value,
                message: fault.message.clone(),
            });
        }
        for name in self.particles.shared.names() {
            let values = self.particles.shared.get(name).unwrap_or(&[]);
            if let Some(p) = values.iter().position(|v| !v.is_finite()) {
                return Some(Diagnostic {
                    step: self.steps,
                    time: self.time,
                    particle: Some(self.particles.id[p] as usize),
                    field: (*name).into(),
                    value: values[p],
                    message: format!("the particle field `{name}` became NaN or infinite"),
                });
            }
        }
        if self.kinematics.min_det_f <= 0.0 {
            let f = ParticleFault {
                particle: self.kinematics.min_det_particle,
                field: "det_f",
                value: self.kinematics.min_det_f,
            };
            return Some(make(
                f,
                "det F <= 0: a particle was inverted (time step too large or the mesh is tangled)",
            ));
        }
        if let Some(f) = self.kinematics.escaped {
            return Some(make(
                f,
                "a particle left the grid (add walls or enlarge the domain)",
            ));
        }
        if let Some(limit) = self.settings.max_speed
            && self.kinematics.max_speed > limit
        {
            return Some(Diagnostic {
                step: self.steps,
                time: self.time,
                particle: None,
                field: "speed".into(),
                value: self.kinematics.max_speed,
                message: format!("the largest particle speed exceeds stop.max_speed = {limit}"),
            });
        }
        if self.settings.mechanics.is_dynamic() && energy_growth > self.settings.max_energy_growth {
            return Some(Diagnostic {
                step: self.steps,
                time: self.time,
                particle: None,
                field: "energy".into(),
                value: energy_growth,
                message: format!(
                    "total energy grew by {:.3} of the largest mechanical energy, past stop.max_energy_growth = {}",
                    energy_growth, self.settings.max_energy_growth
                ),
            });
        }
        None
    }

    fn write_frame(
        &mut self,
        sink: &mut dyn OutputSink,
        index: usize,
        dt: f64,
    ) -> Result<(), OutputError> {
        fill_staging(&self.particles, &self.fields, &mut self.staging);
        let k = &self.kinematics;
        let strain = self.stresses.batch.strain_energy;
        let diagnostics = [
            self.steps as f64,
            dt,
            k.kinetic_energy,
            strain,
            k.gravity_energy,
            k.kinetic_energy + strain + k.gravity_energy,
            k.max_speed,
            k.min_det_f,
            k.momentum.norm(),
            self.boundary_work,
        ];
        debug_assert_eq!(diagnostics.len(), FRAME_DIAGNOSTICS.len());
        sink.write_frame(&Frame {
            index,
            time: self.time,
            values: &self.staging,
            diagnostics: &diagnostics,
        })
    }

    /// Computes the initial stress and refuses a fixed time step above the stable one.
    pub fn preflight(&mut self) -> Result<(), RunError> {
        self.initialise();
        let stable = self.stable_dt();
        if let Some(dt) = self.settings.fixed_dt
            && dt > self.settings.max_cfl * stable
        {
            return Err(RunError::Refused {
                path: "solver.dt".into(),
                message: format!(
                    "the fixed time step {dt:e} s exceeds the stable step {stable:e} s by a factor \
                     {:.3}; solver.max_cfl allows at most {} (lower dt, or raise max_cfl at your risk)",
                    dt / stable,
                    self.settings.max_cfl
                ),
            });
        }
        if self.settings.fixed_dt.is_none() && !stable.is_finite() {
            return Err(RunError::Refused {
                path: "solver.dt".into(),
                message: "needed: nothing in this scene bounds the time step (mechanics is not \
                          dynamic and every physics operator is implicit), so give the step size"
                    .into(),
            });
        }
        Ok(())
    }

    /// Runs to the end time, writing frames to `sink` and reporting to `observer`.
    pub fn run(
        &mut self,
        sink: &mut dyn OutputSink,
        observer: &mut dyn RunObserver,
    ) -> Result<Metrics, RunError> {
        self.preflight()?;
        let n = self.particles.len();
        sink.begin(&RunInfo {
            name: &self.name,
            dimension: D,
            particles: n,
            fields: &self.fields,
            scene: &self.scene_json,
        })?;
        let start = Instant::now();
        let end_time = self.settings.end_time;
        let frame_dt = end_time / self.settings.frames as f64;
        let mut frame = 0usize;
        let mut dt;
        self.write_frame(sink, frame, 0.0)?;
        if let Some(r) = &mut self.reference {
            r.observe(&self.particles, 0.0, false);
        }
        frame += 1;
        let energy0 = self.total_energy();
        let mut mechanical_max = self.kinematics.kinetic_energy + self.stresses.batch.strain_energy;
        let mut drift = 0.0f64;
        let mut max_drift = 0.0f64;
        let mut min_det = self.kinematics.min_det_f;
        let mut max_speed = self.kinematics.max_speed;
        let mut max_momentum = self.kinematics.momentum.norm();
        let mut outcome = Outcome::Finished;
        let mut diagnostic = None;
        let eps = 1e-9 * frame_dt;
        while self.time < end_time - eps {
            let stable = self.stable_dt();
            dt = match self.settings.fixed_dt {
                Some(fixed) => {
                    if fixed > self.settings.max_cfl * stable {
                        outcome = Outcome::Stopped;
                        diagnostic = Some(Diagnostic {
                            step: self.steps,
                            time: self.time,
                            particle: None,
                            field: "dt".into(),
                            value: fixed,
                            message: format!(
                                "the fixed time step exceeds {} times the stable step {stable:e} s \
                                 (particles sped up); stopped before it could blow up",
                                self.settings.max_cfl
                            ),
                        });
                        break;
                    }
                    fixed
                }
                None => self.settings.cfl * stable,
            };
            if dt < self.settings.min_dt || !dt.is_finite() {
                outcome = Outcome::Stopped;
                diagnostic = Some(Diagnostic {
                    step: self.steps,
                    time: self.time,
                    particle: None,
                    field: "dt".into(),
                    value: dt,
                    message: format!(
                        "the time step fell below stop.min_dt = {:e} s",
                        self.settings.min_dt
                    ),
                });
                break;
            }
            // Land exactly on output times.
            let next_frame_time = (frame as f64 * frame_dt).min(end_time);
            if self.time + dt > next_frame_time - eps {
                dt = next_frame_time - self.time;
            }
            self.step(dt);
            let k = &self.kinematics;
            let mechanical = k.kinetic_energy + self.stresses.batch.strain_energy;
            mechanical_max = mechanical_max.max(mechanical);
            // Energy balance: what the body gained beyond the work done on it from outside.
            let energy = self.total_energy() - self.boundary_work;
            drift = if mechanical_max > 0.0 {
                (energy - energy0) / mechanical_max
            } else {
                0.0
            };
            if drift.is_finite() {
                max_drift = max_drift.max(drift.abs());
            }
            min_det = min_det.min(k.min_det_f);
            max_speed = max_speed.max(k.max_speed);
            max_momentum = max_momentum.max(k.momentum.norm());
            if let Some(d) = self.check(if drift.is_nan() { f64::INFINITY } else { drift }) {
                outcome = Outcome::Stopped;
                diagnostic = Some(d);
                break;
            }
            if self.time >= next_frame_time - eps {
                let last = self.time >= end_time - eps;
                self.write_frame(sink, frame, dt)?;
                if let Some(r) = &mut self.reference {
                    r.observe(&self.particles, self.time, last);
                }
                frame += 1;
            }
            let progress = Progress {
                step: self.steps,
                time: self.time,
                end_time,
                dt,
                wall_seconds: start.elapsed().as_secs_f64(),
            };
            if observer.progress(&progress) == Control::Cancel {
                outcome = Outcome::Cancelled;
                break;
            }
        }
        let wall = start.elapsed().as_secs_f64();
        let metrics = Metrics {
            outcome: Some(outcome),
            wall_seconds: wall,
            steps: self.steps,
            simulated_time: self.time,
            particles: n,
            particle_steps_per_second: if wall > 0.0 {
                self.steps as f64 * n as f64 / wall
            } else {
                0.0
            },
            bytes_per_particle: self.particles.bytes_per_particle(),
            grid_bytes: self.grid.bytes()
                + self.volume_average.as_ref().map_or(0, VolumeAverage::bytes),
            energy_drift: drift,
            max_energy_drift: max_drift,
            error: self.reference.as_ref().and_then(|r| r.error()),
            error_kind: self.reference.as_ref().map(|r| r.kind().to_string()),
            reference_value: self.reference.as_ref().and_then(|r| r.expected()),
            measured_value: self.reference.as_ref().and_then(|r| r.measured()),
            comparisons: self
                .reference
                .as_ref()
                .map_or_else(Vec::new, |r| r.comparisons()),
            min_det_f: min_det,
            max_speed,
            max_momentum,
            boundary_work: self.boundary_work,
            frames: frame,
            threads: rayon::current_num_threads(),
            diagnostic,
            physics: self.report.maxima.iter().cloned().collect(),
            tables: self.report.tables.iter().cloned().collect(),
        };
        sink.finish(&metrics)?;
        Ok(metrics)
    }
}

/// The output fields with their per-particle shapes, in the scene's order.
fn output_fields<const D: usize>(names: &[String], particles: &Particles<D>) -> Vec<FieldInfo> {
    names
        .iter()
        .map(|name| {
            let shape = match name.as_str() {
                "x" | "v" => vec![D],
                "stress" | "F" => vec![D, D],
                "J" | "mass" | "volume" | "material" => vec![],
                other if particles.shared.contains(other) => vec![],
                other => {
                    let comps = particles
                        .groups
                        .iter()
                        .flat_map(|g| g.material.state_fields().iter())
                        .find(|s| s.name == other)
                        .map_or(1, |s| s.components);
                    if comps == 1 { vec![] } else { vec![comps] }
                }
            };
            FieldInfo {
                name: name.clone(),
                shape,
            }
        })
        .collect()
}

/// Copies particle fields into the staging buffers in output (id) order.
fn fill_staging<const D: usize>(p: &Particles<D>, fields: &[FieldInfo], staging: &mut [Vec<f64>]) {
    for (field, out) in fields.iter().zip(staging.iter_mut()) {
        let c = field.components();
        match field.name.as_str() {
            "x" | "v" => {
                let src = if field.name == "x" {
                    &p.position
                } else {
                    &p.velocity
                };
                for (i, v) in src.iter().enumerate() {
                    let o = p.id[i] as usize * c;
                    out[o..o + D].copy_from_slice(v.as_slice());
                }
            }
            "stress" | "F" => {
                let src = if field.name == "F" {
                    &p.deformation_gradient
                } else {
                    &p.stress
                };
                for (i, m) in src.iter().enumerate() {
                    let o = p.id[i] as usize * c;
                    // Row-major [row, column] as numpy expects.
                    for r in 0..D {
                        for col in 0..D {
                            out[o + r * D + col] = m[(r, col)];
                        }
                    }
                }
            }
            "J" | "volume" => {
                for (i, f) in p.deformation_gradient.iter().enumerate() {
                    let j = determinant(f);
                    out[p.id[i] as usize] = if field.name == "J" {
                        j
                    } else {
                        j * p.volume0[i]
                    };
                }
            }
            "mass" => {
                for (i, m) in p.mass.iter().enumerate() {
                    out[p.id[i] as usize] = *m;
                }
            }
            "material" => {
                for (g, group) in p.groups.iter().enumerate() {
                    for i in group.range.clone() {
                        out[p.id[i] as usize] = g as f64;
                    }
                }
            }
            name if p.shared.contains(name) => {
                let values = p.shared.get(name).unwrap_or(&[]);
                for (i, v) in values.iter().enumerate() {
                    out[p.id[i] as usize] = *v;
                }
            }
            name => {
                for group in &p.groups {
                    let specs = group.material.state_fields();
                    let position = specs.iter().position(|s| s.name == name);
                    for (k, i) in group.range.clone().enumerate() {
                        let o = p.id[i] as usize * c;
                        match position {
                            Some(f) => {
                                out[o..o + c].copy_from_slice(&group.state[f][k * c..(k + 1) * c])
                            }
                            None => out[o..o + c].fill(0.0),
                        }
                    }
                }
            }
        }
    }
}
