//! Running a staged scene: each stage is built from its own scene (solver mode, physics,
//! output of its own) and takes over the state the stage before left: the particles with
//! every field both stages have, the clock and the contact state (`Simulation::take_over`).
//! The hand-over goes through the same [`Checkpoint`] a resume uses, so a stage may even
//! change the kernel (the dimension and kernel are types: each stage is dispatched anew).

use super::simulation::Simulation;
use super::{DimensionDispatch, RunError, RunObserver, SimulationVisitor, dispatch};
use crate::checkpoint::Checkpoint;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::output::{Metrics, Outcome, OutputSink, StageInfo, StageSummary};
use crate::scene::ValidatedScene;

/// Runs every stage of `scene` in order into `sink`; stops after a stage that did not
/// finish. Returns the whole run's metrics: the last stage's figures, wall time and
/// steps over all stages, and `stages` with each stage's summary.
pub(super) fn run_stages(
    scene: &ValidatedScene,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RunError> {
    struct Stage<'a> {
        sink: &'a mut dyn OutputSink,
        observer: &'a mut dyn RunObserver,
        handed_over: Option<&'a Checkpoint>,
    }
    impl SimulationVisitor for Stage<'_> {
        type Output = Result<(Metrics, Checkpoint), RunError>;
        fn visit<const D: usize, K: Kernel>(self, mut sim: Simulation<D, K>) -> Self::Output
        where
            dyn Material: DimensionDispatch<D>,
        {
            sim.run_stage(self.sink, self.observer, self.handed_over)
        }
    }
    let mut handed_over: Option<Checkpoint> = None;
    let mut summaries = Vec::new();
    let mut wall = 0.0;
    let mut last = Metrics::default();
    for (index, stage) in scene.stages.iter().enumerate() {
        sink.begin_stage(&StageInfo {
            index,
            name: &stage.name,
            scene: &scene.json,
        })?;
        let steps_before = last.steps;
        let start_time = handed_over
            .as_ref()
            .and_then(|c| c.state("time").as_f64())
            .unwrap_or(0.0);
        let (metrics, end) = dispatch(
            &stage.scene,
            Stage {
                sink: &mut *sink,
                observer: &mut *observer,
                handed_over: handed_over.as_ref(),
            },
        )?;
        wall += metrics.wall_seconds;
        summaries.push(StageSummary {
            name: stage.name.clone(),
            outcome: metrics.outcome,
            start_time,
            end_time: metrics.simulated_time,
            steps: metrics.steps - steps_before,
            wall_seconds: metrics.wall_seconds,
            error: metrics.error,
            energy_drift: metrics.energy_drift,
        });
        let finished = metrics.outcome == Some(Outcome::Finished);
        last = metrics;
        handed_over = Some(end);
        if !finished {
            break;
        }
    }
    last.wall_seconds = wall;
    last.particle_steps_per_second = if wall > 0.0 {
        last.steps as f64 * last.particles as f64 / wall
    } else {
        0.0
    };
    last.stages = summaries;
    sink.finish_stages(&last)?;
    Ok(last)
}
