//! The run loop every mode shares: the time step choice (adaptive or fixed, landing on
//! output times), output frames, the reference, the energy balance and the stop checks.

use super::conservation::{Totals, Tracker, totals};
use super::failure_watch::FailureWatch;
use super::multi_field::MultiField;
use super::output_staging::fill_staging;
use super::simulation::Simulation;
use super::stage_clock::StepStage;
use super::state_averaging::StateAveraging;
use super::stats::ParticleFault;
use super::volume_averaging::VolumeAverage;
use super::{Control, DimensionDispatch, Progress, RunError, RunObserver};
use crate::checkpoint::{CHECKPOINT_FORMAT, Checkpoint, CheckpointError, Scalars};
use crate::damage_measures::damage_figures;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::output::{
    Diagnostic, FRAME_DIAGNOSTICS, Frame, Metrics, Outcome, OutputError, OutputSink, RunInfo,
};
use crate::reference::Frame as ReferenceFrame;
use crate::scene::Transfer;
use std::time::Instant;

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// The first failed check after a step, as a diagnostic.
    pub(super) fn check(&self, energy_growth: f64) -> Option<Diagnostic> {
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
            let message = if f.field == "wall" {
                "a particle passed through a wall: in total Lagrangian mechanics a wall holds \
                 only the material that starts at it, and a body moving onto one goes through \
                 (use `dynamic` mechanics)"
            } else {
                "a particle left the grid (add walls or enlarge the domain)"
            };
            return Some(make(f, message));
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
        if self.settings.mechanics.is_explicit_dynamics()
            && energy_growth > self.settings.max_energy_growth
        {
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

    /// APIC's inertia D = coef·dx² where the affine part's angular momentum is counted
    /// (B-spline kernels with APIC), for the conservation totals.
    fn affine_inertia(&self) -> Option<f64> {
        K::APIC_INERTIA
            .filter(|_| self.settings.transfer == Transfer::Apic)
            .map(|coef| coef * self.grid.dx * self.grid.dx)
    }

    /// Writes output frame `index` and returns the conservation totals of this instant.
    pub(super) fn write_frame(
        &mut self,
        sink: &mut dyn OutputSink,
        index: usize,
        dt: f64,
    ) -> Result<Totals, OutputError> {
        let now = totals(&self.particles, self.affine_inertia());
        self.gather_interface_damage();
        fill_staging(&self.particles, &self.fields, &mut self.staging);
        let k = &self.kinematics;
        let strain = self.stresses.batch.strain_energy;
        let diagnostics = [
            self.steps as f64,
            dt,
            k.kinetic_energy,
            strain,
            k.gravity_energy,
            self.total_energy(),
            k.max_speed,
            k.min_det_f,
            k.momentum.norm(),
            self.ledger.boundaries + self.ledger.free_strain,
            self.ledger.dissipated(),
            self.total_energy() - self.ledger.net_input() - self.energy0,
            now.angular_momentum(),
            self.surface_energy,
        ];
        debug_assert_eq!(diagnostics.len(), FRAME_DIAGNOSTICS.len());
        sink.write_frame(&Frame {
            index,
            time: self.time,
            values: &self.staging,
            diagnostics: &diagnostics,
        })?;
        Ok(now)
    }

    /// Shows the reference (if any) the current state as an output frame.
    pub(super) fn observe_reference(&mut self, last: bool) {
        if let Some(r) = &mut self.reference {
            let frame = ReferenceFrame {
                particles: &self.particles,
                time: self.time,
                last,
            };
            <dyn Material as DimensionDispatch<D>>::observe_reference(r.as_mut(), frame);
        }
    }

    /// Steps the run would take at the initial state's step (the fixed one, or the CFL
    /// number times the stable one): `end_time / dt`. An estimate for bounding a job's work
    /// before it runs; the step may shrink later, as particles speed up.
    pub fn estimated_steps(&mut self) -> f64 {
        self.initialise();
        let dt = self
            .settings
            .fixed_dt
            .unwrap_or(self.settings.cfl * self.stable_dt());
        if dt > 0.0 {
            (self.settings.end_time / dt).ceil()
        } else {
            f64::INFINITY
        }
    }

    /// Computes the initial stress and refuses a fixed time step above the stable one.
    pub fn preflight(&mut self) -> Result<(), RunError> {
        self.initialise();
        self.check_fixed_dt()
    }

    /// Refuses a fixed time step above the stable one, or no step where nothing bounds it.
    fn check_fixed_dt(&self) -> Result<(), RunError> {
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
        self.run_from(sink, observer, Start::Fresh)
    }

    /// Continues a run from `checkpoint` (written by this scene's run) to the end time;
    /// `sink` must continue the store after the checkpoint's frames.
    pub fn resume(
        &mut self,
        sink: &mut dyn OutputSink,
        observer: &mut dyn RunObserver,
        checkpoint: &Checkpoint,
    ) -> Result<Metrics, RunError> {
        self.run_from(sink, observer, Start::Resume(checkpoint))
    }

    /// Runs a stage of a staged scene from the state the stage before left (`handed_over`,
    /// saved at its end; with `resume`, a checkpoint of this stage) to this stage's end
    /// time; returns its metrics and the state it leaves for the next stage.
    pub fn run_stage(
        &mut self,
        sink: &mut dyn OutputSink,
        observer: &mut dyn RunObserver,
        handed_over: Option<&Checkpoint>,
        resume: bool,
    ) -> Result<(Metrics, Checkpoint), RunError> {
        let start = match (handed_over, resume) {
            (Some(c), true) => Start::Resume(c),
            (Some(c), false) => Start::HandOver(c),
            (None, _) => Start::Fresh,
        };
        let metrics = self.run_from(sink, observer, start)?;
        let mut end = Checkpoint::default();
        self.save_state(&mut end);
        Ok((metrics, end))
    }

    fn run_from(
        &mut self,
        sink: &mut dyn OutputSink,
        observer: &mut dyn RunObserver,
        from: Start<'_>,
    ) -> Result<Metrics, RunError> {
        let resumed_from_step = match from {
            Start::Resume(c) => Some(c.state("step").as_u64().unwrap_or(0)),
            _ => None,
        };
        let mut run = match from {
            Start::Fresh => {
                self.preflight()?;
                None
            }
            Start::Resume(c) => {
                self.restore_state(c).map_err(resume_error)?;
                Some(LoopState::load(c).map_err(resume_error)?)
            }
            Start::HandOver(c) => {
                self.take_over(c).map_err(|e| RunError::Refused {
                    path: "stages".into(),
                    message: format!("the hand-over between stages failed: {e}"),
                })?;
                self.check_fixed_dt()?;
                None
            }
        };
        let mut averaging = StateAveraging::for_particles(&self.particles);
        let mut failures = match from {
            Start::Resume(c) => FailureWatch::load(&self.particles, c),
            _ => FailureWatch::start(&self.particles),
        };
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
        let mut dt;
        let affine_inertia = self.affine_inertia();
        let mut run = match run.take() {
            Some(run) => run,
            None => {
                let start_totals = self.write_frame(sink, 0, 0.0)?;
                self.observe_reference(false);
                LoopState {
                    start_time: self.time,
                    frame: 1,
                    conservation: Tracker::new(start_totals),
                    mechanical_max: self.kinematics.kinetic_energy
                        + self.stresses.batch.strain_energy,
                    drift: 0.0,
                    max_drift: 0.0,
                    min_det: self.kinematics.min_det_f,
                    max_speed: self.kinematics.max_speed,
                    max_momentum: self.kinematics.momentum.norm(),
                    wall_before: 0.0,
                    checkpoint_slot: 0,
                }
            }
        };
        let energy0 = self.energy0;
        let frame_dt = (end_time - run.start_time) / self.settings.frames as f64;
        let mut outcome = Outcome::Finished;
        let mut diagnostic = None;
        let eps = 1e-9 * frame_dt;
        // `solver.end_when`: the figure that ends the run once the physics first report it
        // in this run (a figure an earlier stage left in the report does not count).
        let end_when = self
            .settings
            .end_when
            .clone()
            .filter(|name| !self.report.maxima.iter().any(|(n, _)| n == name));
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
            self.chosen_dt = dt;
            let next_frame_time = (run.start_time + run.frame as f64 * frame_dt).min(end_time);
            if self.time + dt > next_frame_time - eps {
                dt = next_frame_time - self.time;
            }
            self.step(dt);
            if let Some(averaging) = averaging.as_mut() {
                let start = Instant::now();
                averaging.apply(&mut self.particles);
                self.clock.add(StepStage::StateAverage, start);
            }
            failures.observe(&self.particles, self.time);
            let k = &self.kinematics;
            let mechanical =
                k.kinetic_energy + self.stresses.batch.strain_energy + self.surface_energy.abs();
            run.mechanical_max = run.mechanical_max.max(mechanical);
            // Energy balance: what the bodies gained beyond the work done on them from outside
            // and the energy physical causes dissipated (the ledger): the method's error.
            let energy = self.total_energy() - self.ledger.net_input();
            run.drift = if run.mechanical_max > 0.0 {
                (energy - energy0) / run.mechanical_max
            } else {
                0.0
            };
            if run.drift.is_finite() {
                run.max_drift = run.max_drift.max(run.drift.abs());
            }
            run.min_det = run.min_det.min(k.min_det_f);
            run.max_speed = run.max_speed.max(k.max_speed);
            run.max_momentum = run.max_momentum.max(k.momentum.norm());
            let drift = run.drift;
            if let Some(d) = self.check(if drift.is_nan() { f64::INFINITY } else { drift }) {
                outcome = Outcome::Stopped;
                diagnostic = Some(d);
                break;
            }
            let reached = end_when
                .as_ref()
                .is_some_and(|name| self.report.maxima.iter().any(|(n, _)| n == name));
            if self.time >= next_frame_time - eps || reached {
                let last = self.time >= end_time - eps || reached;
                let now = self.write_frame(sink, run.frame, dt)?;
                self.observe_reference(last);
                run.conservation.observe(now);
                run.frame += 1;
            }
            if self.checkpoint_due(&mut run) {
                let mut c = Checkpoint::default();
                let wall = run.wall_before + start.elapsed().as_secs_f64();
                run.save(&mut c, wall);
                self.save_state(&mut c);
                failures.save(&mut c);
                if !self.stage_tag.is_null() {
                    c.set_state("stage", self.stage_tag.clone());
                }
                sink.write_checkpoint(&c)?;
            }
            let progress = Progress {
                step: self.steps,
                time: self.time,
                end_time,
                dt,
                wall_seconds: run.wall_before + start.elapsed().as_secs_f64(),
            };
            if observer.progress(&progress) == Control::Cancel {
                outcome = Outcome::Cancelled;
                break;
            }
            if reached {
                break;
            }
        }
        let LoopState {
            frame,
            conservation,
            drift,
            max_drift,
            min_det,
            max_speed,
            max_momentum,
            wall_before,
            ..
        } = run;
        let wall = wall_before + start.elapsed().as_secs_f64();
        let mut damage = damage_figures(&self.particles);
        for (name, onset) in failures.onsets() {
            if let Some(figures) = damage.get_mut(name) {
                figures.onset = Some(*onset);
            }
        }
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
            stage_seconds: self.clock.figures(),
            grid_bytes: self.grid.bytes()
                + self.volume_average.as_ref().map_or(0, VolumeAverage::bytes)
                + self
                    .physics
                    .iter()
                    .flat_map(|slot| &slot.scratch)
                    .map(|a| a.len() * 8)
                    .sum::<usize>()
                + self.interpolation.numbering_bytes()
                + self.contact.as_ref().map_or(0, MultiField::bytes),
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
            boundary_work: self.ledger.boundaries + self.ledger.free_strain,
            energy_ledger: self.ledger,
            conservation: conservation.report(
                self.settings.gravity.norm() > 0.0
                    || !self.boundaries.is_empty()
                    || self.settings.damping > 0.0
                    || !self.settings.mechanics.is_explicit_dynamics(),
                // APIC's affine part is counted with a B-spline's constant inertia; with
                // GIMP or linear shape functions it is not stored, so not measured.
                self.settings.transfer != Transfer::Apic || affine_inertia.is_some(),
            ),
            frames: frame,
            resumed_from_step,
            stages: Vec::new(),
            threads: rayon::current_num_threads(),
            diagnostic,
            physics: self.report.maxima.iter().cloned().collect(),
            tables: self.report.tables.iter().cloned().collect(),
            damage,
        };
        sink.finish(&metrics)?;
        Ok(metrics)
    }
}

/// Where a run starts.
#[derive(Clone, Copy)]
enum Start<'a> {
    /// From the scene's initial state.
    Fresh,
    /// From a checkpoint of this same run.
    Resume(&'a Checkpoint),
    /// From the state the stage before left.
    HandOver(&'a Checkpoint),
}

/// The run loop's running figures, kept in checkpoints.
struct LoopState {
    /// Simulated time the run (stage) started at; frames are spaced from it.
    start_time: f64,
    /// The next output frame's index.
    frame: usize,
    conservation: Tracker,
    mechanical_max: f64,
    drift: f64,
    max_drift: f64,
    min_det: f64,
    max_speed: f64,
    max_momentum: f64,
    /// Wall seconds spent before this process took the run up.
    wall_before: f64,
    /// The last `time / output.checkpoint.time` interval a checkpoint was written in.
    checkpoint_slot: u64,
}

impl LoopState {
    fn save(&self, c: &mut Checkpoint, wall: f64) {
        let mut s = Scalars::new();
        s.push(&[self.start_time, self.frame as f64]);
        self.conservation.save(&mut s);
        s.push(&[
            self.mechanical_max,
            self.drift,
            self.max_drift,
            self.min_det,
            self.max_speed,
            self.max_momentum,
            wall,
            self.checkpoint_slot as f64,
        ]);
        c.put("run.scalars", s.into_vec());
        c.set_state("format", CHECKPOINT_FORMAT.into());
        c.set_state("frames", self.frame.into());
    }

    fn load(c: &Checkpoint) -> Result<Self, CheckpointError> {
        if c.state("format").as_u64() != Some(CHECKPOINT_FORMAT as u64) {
            return Err(CheckpointError::Invalid(format!(
                "written in checkpoint format {}, this version reads {CHECKPOINT_FORMAT}",
                c.state("format")
            )));
        }
        let mut s = c.scalars("run.scalars")?;
        let start_time = s.take()?;
        let frame = s.take()? as usize;
        let conservation = Tracker::load(&mut s)?;
        let [
            mechanical_max,
            drift,
            max_drift,
            min_det,
            max_speed,
            max_momentum,
            wall_before,
            slot,
        ] = s.take_n()?;
        Ok(Self {
            start_time,
            frame,
            conservation,
            mechanical_max,
            drift,
            max_drift,
            min_det,
            max_speed,
            max_momentum,
            wall_before,
            checkpoint_slot: slot as u64,
        })
    }
}

fn resume_error(e: CheckpointError) -> RunError {
    RunError::Refused {
        path: "checkpoint".into(),
        message: e.to_string(),
    }
}

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Whether the scene's checkpoint schedule asks for one after this step.
    fn checkpoint_due(&self, run: &mut LoopState) -> bool {
        let Some(schedule) = self.settings.checkpoint else {
            return false;
        };
        let by_steps = schedule
            .steps
            .is_some_and(|n| n > 0 && self.steps.is_multiple_of(n));
        let mut by_time = false;
        if let Some(t) = schedule.time.filter(|t| *t > 0.0) {
            let slot = (self.time / t * (1.0 + 1e-12)).floor() as u64;
            if slot > run.checkpoint_slot {
                run.checkpoint_slot = slot;
                by_time = true;
            }
        }
        by_steps || by_time
    }
}
