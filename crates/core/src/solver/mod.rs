//! The solver: a [`Simulation`] (grid, particles, physics operators), the time-integration
//! modes that advance it one step, and the run loop every mode shares.
//!
//! - `simulation` holds the state and the stages every mode uses (P2G, grid update, G2P,
//!   stress update, physics operators); `setup` builds it from a validated scene.
//! - `mode` is the [`StepMode`](mode::StepMode) trait; each mode is a file of its own:
//!   `explicit` (the explicit MPM step, USL/USF/MUSL), `quasi_static` (physics, then damped
//!   explicit relaxation to equilibrium), `implicit` (Newton–Krylov equilibrium or Newmark
//!   dynamics per step, `implicit/`), `mechanics_off` (physics operators only).
//! - `run_loop` is the run loop every mode shares: time step choice, output frames, the
//!   reference, stop checks; `output_staging` copies particle fields into output order.
//! - contact between bodies: `multi_field` (one grid velocity field per contact body),
//!   `contact` (the law where fields meet), `cohesive` (bonded interfaces that can
//!   delaminate), `contact_step` (the USL step that uses them).

mod binning;
mod checkpointing;
mod cohesive;
mod conservation;
mod contact;
mod contact_step;
mod conversion;
mod cpdi;
mod cpdi_stencils;
mod explicit;
mod failure_watch;
mod gather_transfer;
mod generalized_plane_strain;
mod grid_to_particle;
pub mod grid_update;
mod hand_over;
mod implicit;
mod incompressible;
mod interpolation;
mod mechanics_off;
mod mode;
mod multi_field;
mod output_staging;
pub(crate) mod parallel;
mod particle_to_grid;
mod quasi_static;
mod refined;
mod run_loop;
mod separable;
mod setup;
mod simulation;
mod stage_clock;
mod stages;
mod state_averaging;
mod stats;
pub mod stencil;
mod stress_derivative;
mod stress_update;
mod timestep;
mod total_lagrangian;
mod volume_averaging;
mod xpic;

use crate::kernels::{Cpdi, CubicBSpline, Kernel, Linear, QuadraticBSpline, UniformGimp};
use crate::material::{BatchStats, Material, StressBatch, TangentBatch, ViscosityBatch};
use crate::output::{Metrics, OutputError, OutputSink};
use crate::physics::{Physics, PhysicsContext, Stage};
use crate::reference::{Frame as ReferenceFrame, Reference};
use crate::scene::{KernelName, ValidatedScene};

pub use simulation::Simulation;
pub use stage_clock::NAMES as STEP_STAGES;

pub use timestep::stable_time_step;

/// Selects the 2D or 3D entry points of plugin objects (a [`Material`]'s stress update, a
/// [`Physics`] operator's stages); implemented for D = 2 and 3 so the solver can stay
/// generic over the dimension.
pub trait DimensionDispatch<const D: usize> {
    /// Updates one batch.
    fn update(&self, batch: StressBatch<'_, D>) -> BatchStats;
    /// The stress derivative of one batch (laws that have one).
    fn derivative(&self, batch: TangentBatch<'_, D>);
    /// A liquid's particle viscosities of one batch.
    fn viscosities(&self, batch: ViscosityBatch<'_, D>);
    /// Runs one stage of a physics operator.
    fn physics_stage(physics: &dyn Physics, stage: Stage, ctx: PhysicsContext<'_, D>);
    /// A physics operator's stable step.
    fn physics_stable_dt(physics: &dyn Physics, ctx: PhysicsContext<'_, D>) -> f64;
    /// Shows a reference one output frame.
    fn observe_reference(reference: &mut dyn Reference, frame: ReferenceFrame<'_, D>);
}

impl DimensionDispatch<2> for dyn Material {
    fn update(&self, batch: StressBatch<'_, 2>) -> BatchStats {
        self.update_stress_2d(batch)
    }
    fn derivative(&self, batch: TangentBatch<'_, 2>) {
        self.stress_derivative_2d(batch)
    }
    fn viscosities(&self, batch: ViscosityBatch<'_, 2>) {
        self.liquid_viscosities_2d(batch)
    }
    fn physics_stage(physics: &dyn Physics, stage: Stage, ctx: PhysicsContext<'_, 2>) {
        physics.stage_2d(stage, ctx)
    }
    fn physics_stable_dt(physics: &dyn Physics, ctx: PhysicsContext<'_, 2>) -> f64 {
        physics.stable_dt_2d(ctx)
    }
    fn observe_reference(reference: &mut dyn Reference, frame: ReferenceFrame<'_, 2>) {
        reference.observe_2d(frame)
    }
}

impl DimensionDispatch<3> for dyn Material {
    fn update(&self, batch: StressBatch<'_, 3>) -> BatchStats {
        self.update_stress_3d(batch)
    }
    fn derivative(&self, batch: TangentBatch<'_, 3>) {
        self.stress_derivative_3d(batch)
    }
    fn viscosities(&self, batch: ViscosityBatch<'_, 3>) {
        self.liquid_viscosities_3d(batch)
    }
    fn physics_stage(physics: &dyn Physics, stage: Stage, ctx: PhysicsContext<'_, 3>) {
        physics.stage_3d(stage, ctx)
    }
    fn physics_stable_dt(physics: &dyn Physics, ctx: PhysicsContext<'_, 3>) -> f64 {
        physics.stable_dt_3d(ctx)
    }
    fn observe_reference(reference: &mut dyn Reference, frame: ReferenceFrame<'_, 3>) {
        reference.observe_3d(frame)
    }
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
        (2, KernelName::Cpdi2) => visitor.visit(Simulation::<2, Cpdi>::new(scene)),
        (_, KernelName::Linear) => visitor.visit(Simulation::<3, Linear>::new(scene)),
        (_, KernelName::Gimp) => visitor.visit(Simulation::<3, UniformGimp>::new(scene)),
        (_, KernelName::Bspline2) => visitor.visit(Simulation::<3, QuadraticBSpline>::new(scene)),
        (_, KernelName::Bspline3) => visitor.visit(Simulation::<3, CubicBSpline>::new(scene)),
        (_, KernelName::Cpdi2) => visitor.visit(Simulation::<3, Cpdi>::new(scene)),
    }
}

/// Runs a validated scene to its end time (or until it stops), writing to `sink`.
pub fn run_scene(
    scene: &ValidatedScene,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RunError> {
    if !scene.stages.is_empty() {
        return stages::run_stages(scene, sink, observer, stages::StagedStart::First);
    }
    dispatch(
        scene,
        Run {
            sink,
            observer,
            from: RunFrom::Start,
        },
    )
}

/// Continues a run of `scene` from `checkpoint` (the latest one its store holds) to the
/// end time; `sink` continues the store after the checkpoint's frames.
pub fn resume_scene(
    scene: &ValidatedScene,
    checkpoint: &crate::checkpoint::Checkpoint,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RunError> {
    if !scene.stages.is_empty() {
        return stages::run_stages(
            scene,
            sink,
            observer,
            stages::StagedStart::Resume(checkpoint),
        );
    }
    dispatch(
        scene,
        Run {
            sink,
            observer,
            from: RunFrom::Resume(checkpoint),
        },
    )
}

/// Runs an unstaged `scene` from the state `handed_over` (a checkpoint of another run on the
/// same bodies, materials and domain: `mpm run --from STORE`) to its end time, as a stage
/// takes over from the stage before: the particles with every field both runs have, the
/// clock and the contact state; energy balance, reference and mode start afresh.
pub fn run_scene_from(
    scene: &ValidatedScene,
    handed_over: &crate::checkpoint::Checkpoint,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RunError> {
    if !scene.stages.is_empty() {
        return Err(RunError::Refused {
            path: "stages".into(),
            message: "a staged scene starts from its own first stage, or at a later stage from \
                      the end of the stage before it in a staged run's store \
                      (`run_scene_from_stage`, `mpm run SCENE --from STORE --stage NAME`); \
                      not from an unstaged run's state"
                .into(),
        });
    }
    dispatch(
        scene,
        Run {
            sink,
            observer,
            from: RunFrom::TakeOver(handed_over),
        },
    )
}

/// Runs a staged `scene` from its stage `index` on, from `stage_end`: the state its stage
/// `index - 1` ended with in another run whose stages before `index` were the same
/// (`mpm run SCENE --from STORE --stage NAME`, which checks that; the store's
/// `stages/<i>-<name>/end_state`). Stage `index` takes it over as it would in one run, its
/// `remove` and `convert` rules included, so with nothing changed the frames from stage
/// `index` on are the other run's bit for bit. The metrics list the earlier stages too.
pub fn run_scene_from_stage(
    scene: &ValidatedScene,
    index: usize,
    stage_end: &crate::checkpoint::Checkpoint,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RunError> {
    stages::run_stages(
        scene,
        sink,
        observer,
        stages::StagedStart::AtStage(index, stage_end),
    )
}

/// Where an unstaged run starts.
enum RunFrom<'a> {
    /// The scene's initial state.
    Start,
    /// A checkpoint of the same run (`mpm run --resume`).
    Resume(&'a crate::checkpoint::Checkpoint),
    /// Another run's state, taken over as a stage takes over (`mpm run --from`).
    TakeOver(&'a crate::checkpoint::Checkpoint),
}

/// A run from the start, from a checkpoint of it, or from another run's state.
struct Run<'a> {
    sink: &'a mut dyn OutputSink,
    observer: &'a mut dyn RunObserver,
    from: RunFrom<'a>,
}

impl SimulationVisitor for Run<'_> {
    type Output = Result<Metrics, RunError>;
    fn visit<const D: usize, K: Kernel>(self, mut sim: Simulation<D, K>) -> Self::Output
    where
        dyn Material: DimensionDispatch<D>,
    {
        match self.from {
            RunFrom::Start => sim.run(self.sink, self.observer),
            RunFrom::Resume(c) => sim.resume(self.sink, self.observer, c),
            RunFrom::TakeOver(c) => sim
                .run_stage(self.sink, self.observer, Some(c), false)
                .map(|(metrics, _)| metrics),
        }
    }
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
    if scene.stages.is_empty() {
        return dispatch(scene, Check);
    }
    // Each stage from its own initial state: a later stage starts from another state, but
    // what bounds its step (or that nothing does) shows already.
    for (i, stage) in scene.stages.iter().enumerate() {
        dispatch(&stage.scene, Check).map_err(|e| match e {
            RunError::Refused { path, message } => RunError::Refused {
                path: format!("stages[{i}] ({}): {path}", stage.name),
                message,
            },
            other => other,
        })?;
    }
    Ok(())
}

/// Steps a scene would take at its initial state's time step, without running a step (see
/// [`Simulation::estimated_steps`]); job services bound a job's work with it.
pub fn estimated_steps(scene: &ValidatedScene) -> f64 {
    struct Steps;
    impl SimulationVisitor for Steps {
        type Output = f64;
        fn visit<const D: usize, K: Kernel>(self, mut sim: Simulation<D, K>) -> f64
        where
            dyn Material: DimensionDispatch<D>,
        {
            sim.estimated_steps()
        }
    }
    if scene.stages.is_empty() {
        return dispatch(scene, Steps);
    }
    estimated_stage_steps(scene, 0, |stage| dispatch(stage, Steps))
}

/// Steps a staged scene would take from its stage `first` on (a run started at that stage
/// from a stored state), each stage's share of its own estimate; a plain scene's whole
/// estimate.
pub fn estimated_steps_from(scene: &ValidatedScene, first: usize) -> f64 {
    if scene.stages.is_empty() || first == 0 {
        return estimated_steps(scene);
    }
    estimated_stage_steps(scene, first, estimated_steps)
}

/// The stages' shares from stage `first` on: `steps` estimates a stage's scene run from time
/// 0 to its end, of which the stage runs the part from the end of the stage before.
fn estimated_stage_steps(
    scene: &ValidatedScene,
    first: usize,
    steps: impl Fn(&ValidatedScene) -> f64,
) -> f64 {
    let mut total = 0.0;
    for (i, stage) in scene.stages.iter().enumerate().skip(first) {
        let start = match i {
            0 => 0.0,
            _ => scene.stages[i - 1].scene.scene.solver.end_time,
        };
        let end = stage.scene.scene.solver.end_time;
        total += steps(&stage.scene) * (end - start) / end;
    }
    total
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
