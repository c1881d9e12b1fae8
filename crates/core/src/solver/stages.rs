//! Running a staged scene: each stage is built from its own scene (solver mode, physics,
//! output of its own) and takes over the state the stage before left: the particles with
//! every field both stages have, the clock and the contact state (`Simulation::take_over`).
//! The hand-over goes through the same [`Checkpoint`] a resume uses, so a stage may even
//! change the kernel (the dimension and kernel are types: each stage is dispatched anew).

use super::simulation::Simulation;
use super::{DimensionDispatch, RunError, RunObserver, SimulationVisitor, dispatch};
use super::{conversion, hand_over};
use crate::checkpoint::Checkpoint;
use crate::damage_measures::DamageFigures;
use crate::fatigue_measures::{FatigueFigures, fatigue_figures};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::output::{Metrics, Outcome, OutputSink, StageInfo, StageSummary};
use crate::scene::ValidatedScene;
use crate::stress_measures::{averaged_peak_von_mises, peak_von_mises};
use std::collections::BTreeMap;

/// Where a staged run starts.
#[derive(Clone, Copy)]
pub(super) enum StagedStart<'a> {
    /// The first stage, from the scene's initial state.
    First,
    /// Within the stage a checkpoint of this run was written in (`mpm run --resume`).
    Resume(&'a Checkpoint),
    /// At stage `index`, from the state the stage before it ended with in another run of
    /// the same earlier stages (`mpm run SCENE --from STORE --stage NAME`).
    AtStage(usize, &'a Checkpoint),
}

/// Runs the stages of `scene` in order into `sink` from `start`; stops after a stage that
/// did not finish. Returns the whole run's metrics: the last stage's figures, wall time and
/// steps over all stages, and `stages` with each stage's summary. A stage with
/// `output.end_state` or `output.checkpoint` that finishes hands the sink its end state
/// (`write_stage_end`).
pub(super) fn run_stages(
    scene: &ValidatedScene,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
    start: StagedStart<'_>,
) -> Result<Metrics, RunError> {
    let resume = match start {
        StagedStart::Resume(c) => Some(c),
        _ => None,
    };
    struct Stage<'a> {
        sink: &'a mut dyn OutputSink,
        observer: &'a mut dyn RunObserver,
        handed_over: Option<&'a Checkpoint>,
        resume: bool,
        tag: serde_json::Value,
        averaging_radius: Option<f64>,
        fatigue_layer: Option<&'a crate::scene::FatigueLayer>,
        fatigue_before: BTreeMap<String, FatigueFigures>,
    }
    impl SimulationVisitor for Stage<'_> {
        type Output = Result<(Metrics, Checkpoint, StressFigures), RunError>;
        fn visit<const D: usize, K: Kernel>(self, mut sim: Simulation<D, K>) -> Self::Output
        where
            dyn Material: DimensionDispatch<D>,
        {
            sim.stage_tag = self.tag;
            let (metrics, end) =
                sim.run_stage(self.sink, self.observer, self.handed_over, self.resume)?;
            let figures = StressFigures {
                peak: peak_von_mises(&sim.particles),
                averaged: self
                    .averaging_radius
                    .map(|r| averaged_peak_von_mises(&sim.particles, r))
                    .unwrap_or_default(),
                damage: metrics.damage.clone(),
                fatigue: fatigue_figures(&sim.particles, &self.fatigue_before, self.fatigue_layer),
            };
            Ok((metrics, end, figures))
        }
    }
    let (first, mut summaries, mut handed_over) = match start {
        StagedStart::First => (0, Vec::new(), None),
        StagedStart::Resume(c) => {
            let (index, summaries) = resumed_stage(c, scene.stages.len())?;
            (index, summaries, Some(c.clone()))
        }
        StagedStart::AtStage(index, c) => {
            let summaries = stage_end_summaries(c, index, scene.stages.len())?;
            (index, summaries, Some(c.clone()))
        }
    };
    // Particles removed at hand-overs so far (original indices, sorted); a checkpoint of a
    // staged run, and a stage's end state, keep them in its stage tag.
    let mut removed: Vec<u32> = match start {
        StagedStart::Resume(c) | StagedStart::AtStage(_, c) => {
            serde_json::from_value(c.state("stage")["removed"].clone()).unwrap_or_default()
        }
        StagedStart::First => Vec::new(),
    };
    let mut last = Metrics::default();
    // The stage clock of every stage run by this process, summed.
    let mut stage_seconds: BTreeMap<String, f64> = BTreeMap::new();
    let mut steps_before = summaries
        .iter()
        .map(|s: &StageSummary| s.steps)
        .sum::<u64>();
    for (index, stage) in scene.stages.iter().enumerate().skip(first) {
        sink.begin_stage(&StageInfo {
            index,
            name: &stage.name,
            scene: &scene.json,
        })?;
        let start_time = match (index == first, resume) {
            (true, Some(c)) => c.state("stage")["start_time"].as_f64().unwrap_or(0.0),
            _ => handed_over
                .as_ref()
                .and_then(|c| c.state("time").as_f64())
                .unwrap_or(0.0),
        };
        let resumed_here = resume.is_some() && index == first;
        let removed_before = removed.len();
        // The particles' materials as the stage before left them (a conversion there
        // changed them).
        let before = match index {
            0 => scene,
            _ => &*scene.stages[index - 1].scene,
        };
        if let (Some(rule), Some(c), false) = (&stage.remove, &handed_over, resumed_here) {
            let path = format!("stages[{index}].remove");
            let after = hand_over::apply_rule(c, rule, &removed, before, &path)?;
            handed_over = Some(hand_over::remove_rows(c, before, &removed, &after)?);
            removed = after;
        }
        if let (false, Some(c), false) = (stage.convert.is_empty(), &handed_over, resumed_here) {
            handed_over = Some(conversion::convert_rows(c, before, &stage.scene, &removed)?);
        }
        let removed_here = match (resumed_here, resume) {
            (true, Some(c)) => c.state("stage")["removed_at_hand_over"]
                .as_u64()
                .unwrap_or(0) as usize,
            _ => removed.len() - removed_before,
        };
        let tag = serde_json::json!({
            "index": index,
            "start_time": start_time,
            "summaries": summaries,
            "removed": removed,
            "removed_at_hand_over": removed_here,
        });
        // The inelastic work the stage starts from: where the stage before left it.
        let fatigue_before = summaries
            .last()
            .map(|s| s.fatigue.clone())
            .unwrap_or_default();
        let filtered;
        let stage_scene = if removed.is_empty() {
            &*stage.scene
        } else {
            filtered = hand_over::without_particles(&stage.scene, &removed);
            &filtered
        };
        let (metrics, end, stress) = dispatch(
            stage_scene,
            Stage {
                sink: &mut *sink,
                observer: &mut *observer,
                handed_over: handed_over.as_ref(),
                resume: resumed_here,
                tag,
                averaging_radius: stage_scene.scene.output.stress_averaging_radius,
                fatigue_layer: stage_scene.scene.output.fatigue_layer.as_ref(),
                fatigue_before,
            },
        )?;
        summaries.push(StageSummary {
            name: stage.name.clone(),
            outcome: metrics.outcome,
            start_time,
            end_time: metrics.simulated_time,
            steps: metrics.steps - steps_before,
            wall_seconds: metrics.wall_seconds,
            error: metrics.error,
            energy_drift: metrics.energy_drift,
            particles: metrics.particles,
            removed_particles: removed_here,
            physics: metrics.physics.clone(),
            peak_von_mises: stress.peak,
            averaged_von_mises: stress.averaged,
            damage: stress.damage,
            fatigue: stress.fatigue,
        });
        steps_before = metrics.steps;
        for (stage, seconds) in &metrics.stage_seconds {
            *stage_seconds.entry(stage.clone()).or_insert(0.0) += seconds;
        }
        let finished = metrics.outcome == Some(Outcome::Finished);
        let mut end = end;
        let output = &stage_scene.scene.output;
        if finished && (output.end_state || output.checkpoint.is_some()) {
            // What a run starting at the next stage needs beside the particles: the stage
            // summaries so far and the particles removed so far.
            end.set_state(
                "stage",
                serde_json::json!({
                    "index": index,
                    "summaries": summaries,
                    "removed": removed,
                }),
            );
            sink.write_stage_end(&end)?;
        }
        last = metrics;
        handed_over = Some(end);
        if !finished {
            break;
        }
    }
    let wall: f64 = summaries.iter().map(|s| s.wall_seconds).sum();
    last.wall_seconds = wall;
    last.particle_steps_per_second = if wall > 0.0 {
        last.steps as f64 * last.particles as f64 / wall
    } else {
        0.0
    };
    last.stages = summaries;
    last.stage_seconds = stage_seconds;
    sink.finish_stages(&last)?;
    Ok(last)
}

/// The stress, damage and fatigue figures of a stage's end, per material
/// (`stress_measures`, `damage_measures`, `fatigue_measures`).
struct StressFigures {
    peak: BTreeMap<String, f64>,
    averaged: BTreeMap<String, f64>,
    damage: BTreeMap<String, DamageFigures>,
    fatigue: BTreeMap<String, FatigueFigures>,
}

/// The stage a checkpoint of a staged run was written in, and the summaries of the stages
/// before it.
fn resumed_stage(c: &Checkpoint, stages: usize) -> Result<(usize, Vec<StageSummary>), RunError> {
    let refuse = |message: String| RunError::Refused {
        path: "checkpoint".into(),
        message,
    };
    let tag = c.state("stage");
    let index = tag["index"]
        .as_u64()
        .map(|i| i as usize)
        .filter(|&i| i < stages)
        .ok_or_else(|| {
            refuse(format!(
                "the checkpoint names no stage of this scene ({tag})"
            ))
        })?;
    let summaries: Vec<StageSummary> = serde_json::from_value(tag["summaries"].clone())
        .map_err(|e| refuse(format!("the checkpoint's stage summaries: {e}")))?;
    if summaries.len() != index {
        return Err(refuse(format!(
            "the checkpoint has {} stage summaries before stage {index}",
            summaries.len()
        )));
    }
    Ok((index, summaries))
}

/// The summaries of the stages before `index` that a stage's end state keeps (written at
/// the end of stage `index - 1`), checked against the scene's `stages` stages.
fn stage_end_summaries(
    c: &Checkpoint,
    index: usize,
    stages: usize,
) -> Result<Vec<StageSummary>, RunError> {
    let refuse = |message: String| RunError::Refused {
        path: "stages".into(),
        message,
    };
    if index == 0 || index >= stages {
        return Err(refuse(format!(
            "a run starts from another run's stage at stage 1 to {} of this scene, not {index}",
            stages.saturating_sub(1)
        )));
    }
    let tag = c.state("stage");
    if tag["index"].as_u64() != Some(index as u64 - 1) {
        return Err(refuse(format!(
            "the state handed over is not the end of stage {} ({tag})",
            index - 1
        )));
    }
    let summaries: Vec<StageSummary> = serde_json::from_value(tag["summaries"].clone())
        .map_err(|e| refuse(format!("the end state's stage summaries: {e}")))?;
    if summaries.len() != index {
        return Err(refuse(format!(
            "the end state has {} stage summaries, not the {index} before stage {index}",
            summaries.len()
        )));
    }
    Ok(summaries)
}
