//! What a run hands to a result writer: particle fields per frame, scalar diagnostics per
//! frame and the final metrics. The core knows no file format; `mpm-io` writes Zarr.

use crate::physics::Table;
use serde::Serialize;

/// A particle field written per frame; `shape` is the per-particle shape (`[]`, `[D]`,
/// `[D, D]`, ...).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct FieldInfo {
    /// Field name (`x`, `stress`, ...).
    pub name: String,
    /// Shape of one particle's value.
    pub shape: Vec<usize>,
}

impl FieldInfo {
    /// Numbers per particle.
    pub fn components(&self) -> usize {
        self.shape.iter().product()
    }
}

/// Scalar diagnostics stored once per frame, in this order.
pub const FRAME_DIAGNOSTICS: &[&str] = &[
    "step",
    "dt",
    "kinetic_energy",
    "strain_energy",
    "gravity_energy",
    "total_energy",
    "max_speed",
    "min_det_f",
    "momentum",
    "boundary_work",
    "dissipated_energy",
    "energy_error",
    "angular_momentum",
    "surface_energy",
];

/// Static facts about a run, given to the writer before the first frame.
pub struct RunInfo<'a> {
    /// Scene name.
    pub name: &'a str,
    /// 2 or 3.
    pub dimension: usize,
    /// Particle count (fixed for the run).
    pub particles: usize,
    /// The fields each frame carries, in order.
    pub fields: &'a [FieldInfo],
    /// The scene with defaults filled in.
    pub scene: &'a serde_json::Value,
}

/// A stage of a staged run, given to the writer before the stage begins.
pub struct StageInfo<'a> {
    /// Position of the stage, from 0.
    pub index: usize,
    /// Its name.
    pub name: &'a str,
    /// The whole staged scene (defaults filled in).
    pub scene: &'a serde_json::Value,
}

/// The figures of one stage of a staged run, in the run's metrics.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct StageSummary {
    /// The stage's name.
    pub name: String,
    /// How it ended.
    pub outcome: Option<Outcome>,
    /// Simulated time it started and ended at, s.
    pub start_time: f64,
    /// See `start_time`.
    pub end_time: f64,
    /// Time steps it took.
    pub steps: u64,
    /// Its wall-clock seconds.
    pub wall_seconds: f64,
    /// Its error against its reference, when it has one.
    pub error: Option<f64>,
    /// Its energy error (see `Metrics::energy_drift`).
    pub energy_drift: f64,
    /// Particles it ran with.
    #[serde(default)]
    pub particles: usize,
    /// Particles its `remove` rule took out when it took over (the voids a fill left).
    #[serde(default)]
    pub removed_particles: usize,
    /// Its physics operators' report (`underfill.fill_time`, solver counts, ...).
    #[serde(default)]
    pub physics: std::collections::BTreeMap<String, f64>,
    /// Largest von Mises stress of each material's particles at the stage's end, Pa (in
    /// 2D from the stored in-plane stress with σ_zz = 0).
    #[serde(default)]
    pub peak_von_mises: std::collections::BTreeMap<String, f64>,
    /// With `output.stress_averaging_radius`: the largest von Mises stress averaged over
    /// each material's particles within that radius of a particle, Pa (converges where the
    /// peak does not; `stress_measures.rs`).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub averaged_von_mises: std::collections::BTreeMap<String, f64>,
    /// Damage at the stage's end of each material whose law keeps damage
    /// (`damage_measures.rs`): the largest, the failed particles and their volume, the
    /// cracks and the longest one's length, and the stage's first failure.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub damage: std::collections::BTreeMap<String, crate::damage_measures::DamageFigures>,
    /// Inelastic work of each material whose law accumulates it (`fatigue_measures.rs`):
    /// the average at the stage's end, its increase over the stage, and the cycles to crack
    /// that increase per cycle gives under the law's fatigue law.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub fatigue: std::collections::BTreeMap<String, crate::fatigue_measures::FatigueFigures>,
}

/// One output frame. `values[i]` holds field `i` for every particle in output order,
/// flattened (particle-major).
pub struct Frame<'a> {
    /// Frame number, from 0.
    pub index: usize,
    /// Simulated time, seconds.
    pub time: f64,
    /// Field values, parallel to [`RunInfo::fields`].
    pub values: &'a [Vec<f64>],
    /// Values of [`FRAME_DIAGNOSTICS`], in order.
    pub diagnostics: &'a [f64],
}

/// A failure of the result writer.
#[derive(Debug, thiserror::Error)]
#[error("writing results: {0}")]
pub struct OutputError(pub String);

/// Receives a run's results.
pub trait OutputSink {
    /// Called once before the first frame.
    fn begin(&mut self, info: &RunInfo<'_>) -> Result<(), OutputError>;
    /// Called for every output frame, in order.
    fn write_frame(&mut self, frame: &Frame<'_>) -> Result<(), OutputError>;
    /// Called once at the end, also when the run stopped early.
    fn finish(&mut self, metrics: &Metrics) -> Result<(), OutputError>;
    /// In a staged run, called before each stage's `begin`: the stage's frames, tables
    /// and metrics go to a place of its own. A sink that does not separate stages ignores it.
    fn begin_stage(&mut self, _stage: &StageInfo<'_>) -> Result<(), OutputError> {
        Ok(())
    }
    /// In a staged run, called once after the last stage's `finish` with the whole run's
    /// metrics (its `stages` list every stage).
    fn finish_stages(&mut self, _metrics: &Metrics) -> Result<(), OutputError> {
        Ok(())
    }
    /// In a staged run with `output.end_state` or `output.checkpoint`, called after a stage finished, before the
    /// next stage's `begin_stage`, with the state it ended with, kept beside the stage's
    /// frames so a later run can start at the next stage. A sink that keeps no checkpoints
    /// ignores it.
    fn write_stage_end(
        &mut self,
        _state: &crate::checkpoint::Checkpoint,
    ) -> Result<(), OutputError> {
        Ok(())
    }
    /// Keeps a checkpoint of the run (replacing the previous one). A sink that keeps no
    /// checkpoints ignores it.
    fn write_checkpoint(
        &mut self,
        _checkpoint: &crate::checkpoint::Checkpoint,
    ) -> Result<(), OutputError> {
        Ok(())
    }
}

/// A sink that stores nothing (for tests and benchmarks).
#[derive(Default)]
pub struct NullSink;

impl OutputSink for NullSink {
    fn begin(&mut self, _: &RunInfo<'_>) -> Result<(), OutputError> {
        Ok(())
    }
    fn write_frame(&mut self, _: &Frame<'_>) -> Result<(), OutputError> {
        Ok(())
    }
    fn finish(&mut self, _: &Metrics) -> Result<(), OutputError> {
        Ok(())
    }
}

/// How a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Reached the end time.
    Finished,
    /// Stopped by a check (NaN, det F <= 0, speed, energy, time step); see the diagnostic.
    Stopped,
    /// Cancelled by the caller.
    Cancelled,
}

/// Where and why a run stopped.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diagnostic {
    /// Step at which the problem was seen.
    pub step: u64,
    /// Simulated time then.
    pub time: f64,
    /// Particle (in output order), when one particle is at fault.
    pub particle: Option<usize>,
    /// Field or quantity (`x`, `v`, `stress`, `det_f`, `energy`, `dt`, ...).
    pub field: String,
    /// The offending value.
    pub value: f64,
    /// A sentence for people.
    pub message: String,
}

/// One quantity of a run compared with its reference value.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Comparison {
    /// What is compared (`final_length`).
    pub quantity: String,
    /// Value from the run.
    pub measured: f64,
    /// Reference (published or closed-form) value.
    pub reference: f64,
    /// (measured − reference) / reference.
    pub relative_difference: f64,
}

/// What a run kept of mass and momentum: the largest change from the start over the output
/// frames, relative to the start's mass and to the largest Σ m|v| (Σ m|x − x̄||v| for angular
/// momentum). Momentum is kept only where nothing acts from outside.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Conservation {
    /// Gravity, walls, obstacles or damping act on the bodies (momentum need not be kept).
    pub external_forces: bool,
    /// Relative change of the total mass (0: particles carry their mass).
    pub mass_change: f64,
    /// Relative change of the linear momentum.
    pub momentum_change: f64,
    /// Relative change of the angular momentum (about the origin, with APIC's affine
    /// part): APIC keeps it, PIC loses it. Not measured for APIC with GIMP or linear shape
    /// functions (their affine inertia is per particle and not stored).
    pub angular_momentum_change: Option<f64>,
}

/// Figures of a finished (or stopped) run; stored as the result store's `metrics` attribute.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Metrics {
    /// `finished`, `stopped` or `cancelled`.
    pub outcome: Option<Outcome>,
    /// Wall-clock seconds of the step loop and output.
    pub wall_seconds: f64,
    /// Time steps taken.
    pub steps: u64,
    /// Simulated time reached, seconds.
    pub simulated_time: f64,
    /// Particle count.
    pub particles: usize,
    /// Particle steps per wall second.
    pub particle_steps_per_second: f64,
    /// Particle storage actually allocated, bytes per particle.
    pub bytes_per_particle: f64,
    /// Grid storage, bytes: the grid's arrays (a sparse grid's: the most blocks in use at
    /// once), contact fields', F-bar's and the physics operators' node arrays (at the end:
    /// one row per node the particles' stencils reach, and the rows' numbering).
    pub grid_bytes: usize,
    /// Wall seconds spent in each stage of the step (`sort`, `bin`, `p2g`, `grid_update`,
    /// `g2p`, `volume_average`, `physics`, `stress`, `state_average`, and `solve`: the rest of
    /// the mode's step, such as the implicit Newton–Krylov solve): where the time goes. The
    /// rest of the loop (output, checks, the time step) is not broken down. After a resume,
    /// only this process's part of the run.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub stage_seconds: std::collections::BTreeMap<String, f64>,
    /// The method's energy error at the end: the change of the total (kinetic + strain +
    /// gravity + a liquid's surface) energy less what the `energy_ledger` explains (work
    /// done on the bodies, liquid through openings, damping, plastic, friction, cohesive
    /// and viscous dissipation; not the volume source's work), relative to the largest mechanical (kinetic + strain +
    /// |surface|) energy seen; negative: the method lost energy
    /// (numerical dissipation, impacts against fixed surfaces, wall friction).
    pub energy_drift: f64,
    /// Work done on the body by moving obstacles and by changing free strains (thermal
    /// expansion, shrinkage) (J; J/m in 2D): `energy_ledger.boundaries + free_strain`.
    pub boundary_work: f64,
    /// Work and dissipation by cause over the run.
    pub energy_ledger: crate::energy_ledger::EnergyLedger,
    /// Mass and momentum kept over the run.
    pub conservation: Conservation,
    /// Largest |energy drift| over the run.
    pub max_energy_drift: f64,
    /// Error against the scene's reference, when it has one.
    pub error: Option<f64>,
    /// What `error` measures.
    pub error_kind: Option<String>,
    /// Reference and measured values where the error compares two numbers.
    pub reference_value: Option<f64>,
    /// See `reference_value`.
    pub measured_value: Option<f64>,
    /// Further quantities compared with the reference (Taylor bar: length, diameter,
    /// peak plastic strain).
    pub comparisons: Vec<Comparison>,
    /// Smallest det F seen.
    pub min_det_f: f64,
    /// Largest particle speed seen, m/s.
    pub max_speed: f64,
    /// Largest magnitude of the total particle momentum seen (after any step).
    pub max_momentum: f64,
    /// Output frames written.
    pub frames: usize,
    /// The stages of a staged run, in order (the other figures are the last stage's, with
    /// wall time and steps over the whole run).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub stages: Vec<StageSummary>,
    /// The step of the checkpoint this run was resumed from, when it was (`mpm run
    /// --resume`, or a job whose worker died); everything else is as if it never stopped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resumed_from_step: Option<u64>,
    /// Worker threads used.
    pub threads: usize,
    /// Why the run stopped, when it did.
    pub diagnostic: Option<Diagnostic>,
    /// Largest value over the run of figures the physics operators report (solver
    /// iterations, say) and of the quasi-static relaxation iterations.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub physics: std::collections::BTreeMap<String, f64>,
    /// Tables the physics operators kept over the run (voids, fill history) by name; the
    /// result store also holds each as the array `tables/<name>`.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub tables: std::collections::BTreeMap<String, Table>,
    /// Damage at the end of each material whose law keeps damage (`damage_measures.rs`):
    /// the largest, the failed particles, their cracks, and the first failure's time and
    /// place (a particle failed when the run or stage began does not count).
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub damage: std::collections::BTreeMap<String, crate::damage_measures::DamageFigures>,
}
