//! The time loop of a reduced run: step sizes, frame times, stops, cancellation and the
//! run's metrics.

use super::diagnostics::{diagnostic_at, diagnostic_plain};
use super::setup::Reduced;
use super::stage_clock::RomStage;
use crate::RomError;
use mpm_core::kernels::Kernel;
use mpm_core::material::Material;
use mpm_core::output::{Metrics, Outcome, OutputSink, RunInfo};
use mpm_core::scene::ValidatedScene;
use mpm_core::solver::{Control, DimensionDispatch, Progress, RunObserver, stable_time_step};
use std::time::Instant;

impl<const D: usize, K: Kernel> Reduced<'_, D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Runs the scene to its end time (or a stop), writing frames to `sink`.
    pub(super) fn run(
        &mut self,
        scene: &ValidatedScene,
        sink: &mut dyn OutputSink,
        observer: &mut dyn RunObserver,
    ) -> Result<Metrics, RomError> {
        let n = self.all.len();
        let start = Instant::now();
        self.initialise()?;
        sink.begin(&RunInfo {
            name: &scene.scene.name,
            dimension: D,
            particles: n,
            fields: &self.fields,
            scene: &scene.json,
        })?;
        let end_time = self.settings.end_time;
        let frame_dt = end_time / self.settings.frames as f64;
        let eps = 1e-9 * frame_dt;
        let lap = Instant::now();
        let first = self.write_frame(sink, 0, 0.0, 0.0, 0)?;
        self.clock.lap(RomStage::Frames, lap);
        let mut frame = 1usize;
        let (mut time, mut steps) = (0.0f64, 0u64);
        let mut min_det = first[7];
        let mut max_speed = first[6];
        let mut max_momentum = first[8];
        let mut outcome = Outcome::Finished;
        let mut diagnostic = None;
        let mut speed = first[6];
        while time < end_time - eps {
            let stable = stable_time_step(self.sim.grid.dx, speed, self.stats.max_wave_speed);
            let mut dt = self.settings.fixed_dt.unwrap_or(self.settings.cfl * stable);
            if dt < self.settings.min_dt || !dt.is_finite() {
                outcome = Outcome::Stopped;
                diagnostic = Some(diagnostic_at(
                    steps,
                    time,
                    diagnostic_plain("dt", dt, "the time step fell below stop.min_dt"),
                ));
                break;
            }
            let next_frame_time = (frame as f64 * frame_dt).min(end_time);
            if time + dt > next_frame_time - eps {
                dt = next_frame_time - time;
            }
            if let Some(d) = self.step(dt, time + dt)? {
                outcome = Outcome::Stopped;
                diagnostic = Some(diagnostic_at(steps, time, d));
                break;
            }
            time += dt;
            steps += 1;
            speed = self.stats.max_speed;
            min_det = min_det.min(self.stats.min_det_f);
            max_speed = max_speed.max(speed);
            if time >= next_frame_time - eps {
                let lap = Instant::now();
                let d = self.write_frame(sink, frame, time, dt, steps)?;
                self.clock.lap(RomStage::Frames, lap);
                max_momentum = max_momentum.max(d[8]);
                min_det = min_det.min(d[7]);
                frame += 1;
            }
            let progress = Progress {
                step: steps,
                time,
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
        let mut physics = std::collections::BTreeMap::new();
        physics.insert("rom.samples".to_string(), self.samples.len() as f64);
        physics.insert("rom.latent".to_string(), self.latent as f64);
        physics.insert("rom.candidates".to_string(), self.candidates.len() as f64);
        // An unseen coordinate makes it infinite; JSON has no infinity.
        let condition = self.sample_condition.min(1e300);
        physics.insert("rom.sample_condition".to_string(), condition);
        physics.insert(
            "rom.quadrature_points".to_string(),
            self.quadrature_total / steps.max(1) as f64,
        );
        physics.insert(
            "rom.max_quadrature_points".to_string(),
            self.quadrature_max as f64,
        );
        let metrics = Metrics {
            outcome: Some(outcome),
            wall_seconds: wall,
            steps,
            simulated_time: time,
            particles: n,
            particle_steps_per_second: if wall > 0.0 {
                steps as f64 * n as f64 / wall
            } else {
                0.0
            },
            min_det_f: min_det,
            max_speed,
            max_momentum,
            frames: frame,
            threads: rayon::current_num_threads(),
            diagnostic,
            physics,
            stage_seconds: self.clock.by_name(),
            ..Metrics::default()
        };
        sink.finish(&metrics)?;
        Ok(metrics)
    }
}
