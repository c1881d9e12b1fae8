//! The hyper-reduced time stepper. Each step it
//! 1. evaluates the map g(X, q) at the sampled particles and at the particles whose kernel
//!    stencils overlap theirs (the quadrature neighbourhood),
//! 2. does the ordinary MPM update for those particles only: stress from the scene's
//!    material plugins with F = ∂g/∂X, P2G, the core's grid update with the scene's walls
//!    and obstacles, and G2P to the sampled particles,
//! 3. projects the sampled particles' new positions and velocities back onto the map by
//!    least squares through the Jacobian ∂g/∂q (Gauss–Newton for the neural map), giving q
//!    and q̇.
//!
//! Frames evaluate the map at every particle of the scene, whatever its resolution, and
//! go to the same result layout as a full run.

mod diagnostics;
mod frame;
mod options;
mod projection;
mod sampling;
mod sampling_greedy;
mod setup;
mod stage_clock;
mod step;
mod stress;
mod time_loop;

pub use options::{REDUCED_FIELDS, RunOptions, Sampling};
pub use sampling::{farthest_point_samples, interior_particles};
pub use sampling_greedy::{greedy_samples, sample_condition};
pub use stage_clock::ROM_STAGES;

use crate::{Model, RomError};
use mpm_core::kernels::Kernel;
use mpm_core::material::Material;
use mpm_core::output::{Metrics, OutputSink};
use mpm_core::scene::ValidatedScene;
use mpm_core::solver::{DimensionDispatch, RunObserver, Simulation, SimulationVisitor, dispatch};
use setup::Reduced;

/// Runs `scene` with `model` and writes its frames to `sink`. The metrics carry
/// `rom.samples`, `rom.latent`, `rom.candidates`, `rom.quadrature_points` (mean per step)
/// and `rom.sample_condition` (of the projection's normal matrix at the start) under
/// `physics`.
pub fn run_reduced(
    scene: &ValidatedScene,
    model: &Model,
    options: &RunOptions,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RomError> {
    model.check_scene(scene)?;
    let dim = model.info.dimension;
    if options.samples == 0 || options.samples * dim < model.info.latent {
        return Err(RomError::Option(format!(
            "--samples {} gives {} equations for {} coordinates; use at least {}",
            options.samples,
            options.samples * dim,
            model.info.latent,
            model.info.latent.div_ceil(dim)
        )));
    }
    if options.samples > scene.particle_count() {
        return Err(RomError::Option(format!(
            "--samples {} exceeds the scene's {} particles",
            options.samples,
            scene.particle_count()
        )));
    }
    if !(options.time_step_scale > 0.0 && options.time_step_scale <= 100.0) {
        return Err(RomError::Option(format!(
            "--dt-scale must be in (0, 100], got {}",
            options.time_step_scale
        )));
    }
    if !(options.margin >= 0.0 && options.margin <= 10.0) {
        return Err(RomError::Option(format!(
            "--margin must be in [0, 10] cells, got {}",
            options.margin
        )));
    }
    for (i, name) in scene.scene.output.fields.iter().enumerate() {
        if !REDUCED_FIELDS.contains(&name.as_str()) {
            return Err(RomError::Mismatch {
                path: format!("output.fields[{i}]"),
                message: format!(
                    "field `{name}` is not available from a reduced run (available: {})",
                    REDUCED_FIELDS.join(", ")
                ),
            });
        }
    }
    struct Visit<'a> {
        scene: &'a ValidatedScene,
        model: &'a Model,
        options: &'a RunOptions,
        sink: &'a mut dyn OutputSink,
        observer: &'a mut dyn RunObserver,
    }
    impl SimulationVisitor for Visit<'_> {
        type Output = Result<Metrics, RomError>;
        fn visit<const D: usize, K: Kernel>(self, sim: Simulation<D, K>) -> Self::Output
        where
            dyn Material: DimensionDispatch<D>,
        {
            let mut run = Reduced::<D, K>::new(sim, self.scene, self.model, self.options)?;
            run.run(self.scene, self.sink, self.observer)
        }
    }
    dispatch(
        scene,
        Visit {
            scene,
            model,
            options,
            sink,
            observer,
        },
    )
}
