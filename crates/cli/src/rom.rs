//! `mpm rom`: train a reduced-order model on full runs, run scenes with it, measure its
//! error against a full-order run, and sweep samples and latent sizes (error against wall
//! time per simulated second, with the full-order run as a line).

use crate::exit_status::ExitStatus;
use crate::progress::ProgressReporter;
use crate::scene_file::{load_scene, report_load_error};
use crate::stdout::outln;
use anyhow::{Context, anyhow};
use clap::{Subcommand, ValueEnum};
use mpm_core::output::{Metrics, Outcome};
use mpm_core::plugin::Registry;
use mpm_rom::compare::{PositionError, position_error};
use mpm_rom::model::TrainOptions;
use mpm_rom::neural::NeuralOptions;
use mpm_rom::reduced_run::{RunOptions, run_reduced};
use mpm_rom::{Model, ModelKind, RomError};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Kind of reduced map, as a command-line value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum KindArg {
    /// POD modes as B-spline fields of X.
    Linear,
    /// A small neural network g(X, q) (candle).
    Neural,
}

impl From<KindArg> for ModelKind {
    fn from(k: KindArg) -> Self {
        match k {
            KindArg::Linear => ModelKind::Linear,
            KindArg::Neural => ModelKind::Neural,
        }
    }
}

/// Settings of the network, for `--kind neural`.
#[derive(Clone, Debug, clap::Args)]
pub struct NeuralArgs {
    /// Neurons per hidden layer.
    #[arg(long, default_value_t = 64)]
    pub width: usize,
    /// Hidden layers.
    #[arg(long, default_value_t = 3)]
    pub layers: usize,
    /// Training epochs.
    #[arg(long, default_value_t = 300)]
    pub epochs: usize,
    /// Adam learning rate.
    #[arg(long, default_value_t = 2e-3)]
    pub learning_rate: f64,
    /// Points drawn per snapshot per batch.
    #[arg(long, default_value_t = 512)]
    pub batch_points: usize,
    /// Seed of the initial weights and the batches.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl NeuralArgs {
    fn options(&self) -> NeuralOptions {
        NeuralOptions {
            width: self.width,
            hidden_layers: self.layers,
            epochs: self.epochs,
            learning_rate: self.learning_rate,
            batch_points: self.batch_points,
            seed: self.seed,
        }
    }
}

/// Settings of a reduced run shared by `run` and `study`.
#[derive(Clone, Debug, clap::Args)]
pub struct StepArgs {
    /// Multiply the scene's time step by this (1: the full-order step).
    #[arg(long, default_value_t = 1.0)]
    pub dt_scale: f64,
    /// Extra reach, in cells, of the neighbourhood searched around each sample.
    #[arg(long, default_value_t = 1.0)]
    pub margin: f64,
    /// Let samples lie on the body's outermost cell layer too (by default they are drawn
    /// from particles at least a cell inside, whose grid nodes are full).
    #[arg(long)]
    pub surface_samples: bool,
    /// How samples are picked: `farthest` spreads them over the body (farthest-point
    /// sampling); `greedy` picks them from the modes, each making the projection's normal
    /// matrix best conditioned.
    #[arg(long, value_enum, default_value_t = SamplingArg::Farthest)]
    pub sampling: SamplingArg,
}

/// `--sampling` of a reduced run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SamplingArg {
    /// Farthest-point sampling over the body.
    Farthest,
    /// Greedy, from the map's modes (D-optimal design).
    Greedy,
}

impl StepArgs {
    fn options(&self, samples: usize) -> RunOptions {
        RunOptions {
            samples,
            time_step_scale: self.dt_scale,
            margin: self.margin,
            interior_samples: !self.surface_samples,
            sampling: match self.sampling {
                SamplingArg::Farthest => mpm_rom::reduced_run::Sampling::FarthestPoint,
                SamplingArg::Greedy => mpm_rom::reduced_run::Sampling::Greedy,
            },
            ..RunOptions::default()
        }
    }
}

/// Subcommands of `mpm rom`.
#[derive(Debug, Subcommand)]
pub enum RomCommand {
    /// Fit a reduced map x = g(X, q) to the frames of full-order runs (result stores or
    /// folders of them, e.g. an `mpm study` folder): one scene at several parameters.
    Train {
        /// Training stores, or folders holding `*.zarr` stores.
        #[arg(long, required = true, num_args = 1..)]
        runs: Vec<PathBuf>,
        /// Number of generalised coordinates q.
        #[arg(long)]
        latent: usize,
        /// Linear (POD) or neural map.
        #[arg(long, value_enum, default_value_t = KindArg::Linear)]
        kind: KindArg,
        /// Model file to write (safetensors).
        #[arg(long)]
        out: PathBuf,
        /// Spacing of the linear map's B-spline grid, m (default: half a cell).
        #[arg(long)]
        mode_spacing: Option<f64>,
        #[command(flatten)]
        neural: NeuralArgs,
    },
    /// Run a scene with a reduced model: MPM at N sampled particles, output at every
    /// particle of the scene (of any resolution) in the usual result layout.
    Run {
        /// Scene file (JSON): the training scene, at any parameters and particle density.
        scene: PathBuf,
        /// Model file from `mpm rom train`.
        #[arg(long)]
        model: PathBuf,
        /// Sampled particles N.
        #[arg(long, default_value_t = 32)]
        samples: usize,
        /// Output folder.
        #[arg(long, default_value = "results")]
        out: PathBuf,
        /// Change a scene value first (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Also report the position error against this full-order store.
        #[arg(long)]
        compare: Option<PathBuf>,
        #[command(flatten)]
        step: StepArgs,
        /// Print the metrics as JSON.
        #[arg(long)]
        json: bool,
        /// No progress output.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Relative L2 position error of a run against a reference run (same particles, same
    /// output times), over all particles and frames.
    Error {
        /// The run (e.g. a reduced run's store).
        run: PathBuf,
        /// The reference (the full-order run at the same parameters).
        reference: PathBuf,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Train one model per latent size, run the scene with each at each sample count, and
    /// tabulate and plot position error against wall time per simulated second, with the
    /// full-order run's time as a line.
    Study(StudyArgs),
    /// Draw a parametric training set by Latin hypercubes: training and held-out points
    /// over the ranges of `--vary`, written as scenes (and run with --run) for `mpm rom
    /// train --runs DIR/train` and `mpm rom study --full DIR/test`.
    Design(crate::rom_design::DesignArgs),
}

/// Exit status of a reduced-model failure: bad input for models, scenes and options.
fn report(e: RomError) -> anyhow::Result<ExitStatus> {
    eprintln!("error: {e}");
    Ok(match e {
        RomError::Store(_) | RomError::File { .. } | RomError::Output(_) | RomError::Network(_) => {
            ExitStatus::Failure
        }
        RomError::Training(_)
        | RomError::BadModel { .. }
        | RomError::Mismatch { .. }
        | RomError::Option(_) => ExitStatus::InvalidInput,
    })
}

fn load(
    scene: &Path,
    set: &[String],
    registry: &Registry,
) -> Result<mpm_core::scene::ValidatedScene, ExitStatus> {
    load_scene(scene, set, registry).map_err(|e| report_load_error(scene, e))
}

/// Runs `mpm rom ...`.
pub fn run(command: RomCommand, registry: &Registry) -> anyhow::Result<ExitStatus> {
    match command {
        RomCommand::Train {
            runs,
            latent,
            kind,
            out,
            mode_spacing,
            neural,
        } => {
            let options = TrainOptions {
                kind: kind.into(),
                latent,
                mode_spacing,
                neural: neural.options(),
            };
            let model = match Model::train(&runs, &options, &mut |line| eprintln!("{line}")) {
                Ok(m) => m,
                Err(e) => return report(e),
            };
            if let Err(e) = model.save(&out) {
                return report(e);
            }
            let t = &model.info.training;
            outln!(
                "wrote {} ({:?}, latent {}, {} snapshots of {} particles; POD captures {:.6}; \
                 training misfit {:.3e} of the RMS displacement; {:.1} s)",
                out.display(),
                model.info.kind,
                model.info.latent,
                t.snapshots,
                t.particles,
                t.pod_captured,
                t.fit_error,
                t.seconds
            )?;
            Ok(ExitStatus::Success)
        }
        RomCommand::Run {
            scene,
            model,
            samples,
            out,
            set,
            compare,
            step,
            json,
            quiet,
        } => {
            let validated = match load(&scene, &set, registry) {
                Ok(v) => v,
                Err(s) => return Ok(s),
            };
            let model = match Model::load(&model) {
                Ok(m) => m,
                Err(e) => return report(e),
            };
            let options = step.options(samples);
            let store = out.join(format!("{}.zarr", validated.scene.name));
            let metrics = match run_one(&validated, &model, &options, &store, quiet || json) {
                Ok(m) => m,
                Err(e) => return report(e),
            };
            let error = match &compare {
                Some(reference) => match position_error(&store, reference) {
                    Ok(e) => Some(e),
                    Err(e) => return report(e),
                },
                None => None,
            };
            warn_on_sample_condition(&metrics);
            if json {
                outln!(
                    "{}",
                    serde_json::to_string_pretty(&serde_json::json!({
                        "metrics": metrics,
                        "error": error,
                    }))?
                )?;
            } else {
                print_run(&metrics, &store, error.as_ref())?;
            }
            Ok(match metrics.outcome {
                Some(Outcome::Finished) => ExitStatus::Success,
                _ => ExitStatus::Stopped,
            })
        }
        RomCommand::Error {
            run,
            reference,
            json,
        } => {
            let e = match position_error(&run, &reference) {
                Ok(e) => e,
                Err(e) => return report(e),
            };
            if json {
                outln!("{}", serde_json::to_string_pretty(&e)?)?;
            } else {
                outln!(
                    "relative position error {:.4e} (relative to the displacement {:.4e}; \
                     largest particle distance {:.3e} m) over {} frames × {} particles",
                    e.relative,
                    e.relative_to_displacement,
                    e.max_distance,
                    e.frames,
                    e.particles
                )?;
            }
            Ok(ExitStatus::Success)
        }
        RomCommand::Study(args) => study(&args, registry),
        RomCommand::Design(args) => crate::rom_design::design(&args, registry),
    }
}

fn run_one(
    scene: &mpm_core::scene::ValidatedScene,
    model: &Model,
    options: &RunOptions,
    store: &Path,
    quiet: bool,
) -> Result<Metrics, RomError> {
    let mut sink = mpm_io::ZarrSink::new(store);
    let mut progress = ProgressReporter::new(quiet);
    let result = run_reduced(scene, model, options, &mut sink, &mut progress);
    progress.finish();
    result
}

/// Above this condition number of the samples' normal matrix a reduced run warns: a misfit
/// can grow a hundredfold into one coordinate.
const SAMPLE_CONDITION_WARNING: f64 = 1e4;

/// Warns on stderr when the samples' normal matrix is worse conditioned than
/// [`SAMPLE_CONDITION_WARNING`].
fn warn_on_sample_condition(m: &Metrics) {
    let condition = m
        .physics
        .get("rom.sample_condition")
        .copied()
        .unwrap_or(0.0);
    if condition > SAMPLE_CONDITION_WARNING {
        eprintln!(
            "warning: the samples barely see a coordinate (condition number {condition:.1e} > \
             {SAMPLE_CONDITION_WARNING:.0e}): the projection can blow a misfit up into it; use \
             more samples, a smaller latent size, or --sampling greedy"
        );
    }
}

fn print_run(m: &Metrics, store: &Path, error: Option<&PositionError>) -> anyhow::Result<()> {
    let get = |k: &str| m.physics.get(k).copied().unwrap_or(f64::NAN);
    outln!(
        "{:?}: {} steps to t = {} s in {:.3} s ({:.3} s per simulated second); {} particles \
         written; {} samples, latent {}, {:.0} quadrature particles per step (of {} candidates)",
        m.outcome.unwrap_or(Outcome::Finished),
        m.steps,
        m.simulated_time,
        m.wall_seconds,
        m.wall_seconds / m.simulated_time.max(1e-300),
        m.particles,
        get("rom.samples"),
        get("rom.latent"),
        get("rom.quadrature_points"),
        get("rom.candidates"),
    )?;
    let parts: Vec<String> = mpm_rom::reduced_run::ROM_STAGES
        .iter()
        .filter_map(|&name| m.stage_seconds.get(name).map(|s| (name, s)))
        .map(|(name, s)| {
            let share = 100.0 * s / m.wall_seconds.max(1e-300);
            format!("{name} {s:.2} s ({share:.0}%)")
        })
        .collect();
    if !parts.is_empty() {
        outln!("where the time went: {}", parts.join(", "))?;
    }
    let condition = get("rom.sample_condition");
    if condition.is_finite() {
        outln!("samples' condition number (normal matrix of the projection): {condition:.3e}")?;
    }

    if let Some(d) = &m.diagnostic {
        outln!(
            "stopped at step {} (t = {} s): {}",
            d.step,
            d.time,
            d.message
        )?;
    }
    if let Some(e) = error {
        outln!(
            "position error against the full-order run: {:.4e} (relative to the displacement \
             {:.4e})",
            e.relative,
            e.relative_to_displacement
        )?;
    }
    outln!("wrote {}", store.display())?;
    Ok(())
}

/// Settings of `mpm rom study`.
#[derive(Debug, clap::Args)]
pub struct StudyArgs {
    /// Scene file at the held-out parameters, with one `--full`; without it, each held-out
    /// reduced run runs the scene its full-order store holds (with `--set`).
    scene: Option<PathBuf>,
    /// Full-order runs at held-out parameters (stores, or folders of them, e.g. `mpm rom
    /// design`'s `test`): the references and the time to beat. Errors and times are summed
    /// over them.
    #[arg(long, required = true, num_args = 1..)]
    full: Vec<PathBuf>,
    /// Training stores or folders of them (not including `--full`).
    #[arg(long, required = true, num_args = 1..)]
    runs: Vec<PathBuf>,
    /// Latent sizes, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "4,8")]
    latent: Vec<usize>,
    /// Sample counts, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "8,16,32,64")]
    samples: Vec<usize>,
    /// Linear or neural maps.
    #[arg(long, value_enum, default_value_t = KindArg::Linear)]
    kind: KindArg,
    /// Change a scene value first (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    set: Vec<String>,
    /// Output folder (default results/<scene>-rom-study).
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    step: StepArgs,
    #[command(flatten)]
    neural: NeuralArgs,
}

/// One row of a reduced-order study.
#[derive(Clone, Debug, Serialize)]
pub struct RomRow {
    /// Generalised coordinates.
    pub latent: usize,
    /// Sampled particles.
    pub samples: usize,
    /// Wall seconds of the run.
    pub wall_seconds: f64,
    /// Wall seconds per simulated second.
    pub wall_per_simulated_second: f64,
    /// Speed-up over the full-order run (its wall time per simulated second over this one's).
    pub speedup: f64,
    /// Relative position error (the paper's measure).
    pub error: Option<f64>,
    /// Error relative to the displacement.
    pub error_to_displacement: Option<f64>,
    /// Mean quadrature particles per step.
    pub quadrature_points: f64,
    /// The largest condition number of the projection's normal matrix at the samples over
    /// the held-out runs (`rom.sample_condition`): large when the samples barely see a
    /// coordinate.
    pub sample_condition: f64,
    /// `finished`, `stopped`, or the failure.
    pub outcome: String,
}

/// A held-out run of a study: the full-order store and the scene its reduced runs run.
struct HeldOut {
    store: PathBuf,
    scene: mpm_core::scene::ValidatedScene,
}

/// The held-out runs of `mpm rom study`, each with its scene; on failure the exit status.
fn held_out_runs(args: &StudyArgs, registry: &Registry) -> Result<Vec<HeldOut>, ExitStatus> {
    // The scene first: a missing or invalid scene file is named before the stores.
    let scene = match &args.scene {
        Some(path) => Some((path, load(path, &args.set, registry)?)),
        None => None,
    };
    // A missing store exits 1 (a missing file), a folder without stores 2.
    let stores = mpm_rom::snapshots::find_stores(&args.full)
        .map_err(|e| report(e).unwrap_or(ExitStatus::Failure))?;
    if let Some((path, scene)) = scene {
        if stores.len() > 1 {
            eprintln!(
                "error: {}: give the scene with one --full only; with {} held-out runs each \
                 reduced run runs the scene its store holds (leave the scene out)",
                path.display(),
                stores.len()
            );
            return Err(ExitStatus::InvalidInput);
        }
        return Ok(vec![HeldOut {
            store: stores[0].clone(),
            scene,
        }]);
    }
    let mut out = Vec::new();
    for store in stores {
        let fail = |message: String| {
            eprintln!("error: {}: {message}", store.display());
            ExitStatus::InvalidInput
        };
        let opened = mpm_io::ResultStore::open(&store).map_err(|e| fail(e.to_string()))?;
        let mut json = opened
            .attributes()
            .get("scene")
            .cloned()
            .ok_or_else(|| fail("the store holds no scene".into()))?;
        for o in &args.set {
            crate::overrides::apply_override(&mut json, o)
                .map_err(|e| fail(format!("--set: {e:#}")))?;
        }
        let scene = mpm_core::scene::parse_scene_value(json, registry, Path::new("."))
            .map_err(|e| fail(format!("its scene: {e}")))?;
        out.push(HeldOut { store, scene });
    }
    Ok(out)
}

fn study(args: &StudyArgs, registry: &Registry) -> anyhow::Result<ExitStatus> {
    let held_out = match held_out_runs(args, registry) {
        Ok(h) => h,
        Err(s) => return Ok(s),
    };
    let (mut full_wall, mut full_time) = (0.0, 0.0);
    for h in &held_out {
        let full = mpm_io::ResultStore::open(&h.store)
            .with_context(|| format!("opening the full-order run {}", h.store.display()))?;
        let metrics = full
            .attributes()
            .get("metrics")
            .ok_or_else(|| anyhow!("{} has no metrics (did the run finish?)", h.store.display()))?;
        full_wall += metrics["wall_seconds"].as_f64().unwrap_or(f64::NAN);
        full_time += metrics["simulated_time"].as_f64().unwrap_or(f64::NAN);
    }
    let full_rate = full_wall / full_time;
    // The name the held-out scenes share (`mpm rom design` names them <scene>-test-<k>).
    let names: Vec<&str> = held_out
        .iter()
        .map(|h| h.scene.scene.name.as_str())
        .collect();
    let common = names.iter().skip(1).fold(names[0].len(), |n, other| {
        names[0]
            .bytes()
            .zip(other.bytes())
            .take(n)
            .take_while(|(a, b)| a == b)
            .count()
    });
    let title_name = match names[0][..common].trim_end_matches(['-', '_']) {
        "" => names[0].to_string(),
        shared => shared.to_string(),
    };
    let dir = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .scene
            .as_ref()
            .and_then(|s| s.file_stem())
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| title_name.clone());
        PathBuf::from("results").join(format!("{stem}-rom-study"))
    });
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut rows = Vec::new();
    for &latent in &args.latent {
        let options = TrainOptions {
            kind: args.kind.into(),
            latent,
            mode_spacing: None,
            neural: args.neural.options(),
        };
        let model = match Model::train(&args.runs, &options, &mut |line| eprintln!("{line}")) {
            Ok(m) => m,
            Err(e) => return report(e),
        };
        let path = dir.join(format!("model-latent{latent}.safetensors"));
        if let Err(e) = model.save(&path) {
            return report(e);
        }
        for &samples in &args.samples {
            let options = args.step.options(samples);
            let row = study_row(
                &held_out,
                &model,
                &options,
                &dir,
                (latent, samples),
                full_rate,
            );
            outln!(
                "latent {:>3}  samples {:>5}  {:>9.3} s/sim-s  speed-up {:>7.2}  error {:>10}  \
                 (to displacement {:>10})  condition {:>9.2e}  {}",
                row.latent,
                row.samples,
                row.wall_per_simulated_second,
                row.speedup,
                fmt(row.error),
                fmt(row.error_to_displacement),
                row.sample_condition,
                row.outcome
            )?;
            rows.push(row);
        }
    }
    outln!(
        "full-order run{}: {full_rate:.3} s per simulated second",
        if held_out.len() > 1 {
            format!("s ({} held out, errors summed over them)", held_out.len())
        } else {
            String::new()
        }
    )?;
    write_study(&dir, &rows, full_rate, held_out.len())?;
    crate::rom_study_plot::draw_study(
        &dir.join("rom-study.png"),
        &format!("{title_name}: reduced-order error against wall time"),
        &rows,
        full_rate,
    )?;
    outln!(
        "wrote {0}/rom-study.csv, {0}/rom-study.json, {0}/rom-study.png",
        dir.display()
    )?;
    Ok(ExitStatus::Success)
}

/// Runs the model at every held-out run's parameters and sums the errors and times.
fn study_row(
    held_out: &[HeldOut],
    model: &Model,
    options: &RunOptions,
    dir: &Path,
    (latent, samples): (usize, usize),
    full_rate: f64,
) -> RomRow {
    let (mut wall, mut simulated, mut quadrature) = (0.0, 0.0, 0.0);
    let mut condition = 0.0f64;
    let mut errors = Vec::new();
    let mut outcome = String::from("finished");
    for h in held_out {
        let store = match held_out.len() {
            1 => dir.join(format!("latent{latent}-samples{samples}.zarr")),
            _ => dir.join(format!(
                "latent{latent}-samples{samples}-{}.zarr",
                h.scene.scene.name
            )),
        };
        match run_one(&h.scene, model, options, &store, true) {
            Ok(m) => {
                wall += m.wall_seconds;
                simulated += m.simulated_time;
                quadrature += m
                    .physics
                    .get("rom.quadrature_points")
                    .copied()
                    .unwrap_or(0.0)
                    / held_out.len() as f64;
                let c = m.physics.get("rom.sample_condition").copied();
                condition = condition.max(c.unwrap_or(f64::NAN));
                if m.outcome != Some(Outcome::Finished) {
                    outcome =
                        format!("{:?}", m.outcome.unwrap_or(Outcome::Finished)).to_lowercase();
                }
                match position_error(&store, &h.store) {
                    Ok(e) => errors.push(e),
                    Err(e) => outcome = format!("failed: {e}"),
                }
            }
            Err(e) => {
                outcome = format!("failed: {e}");
                break;
            }
        }
    }
    let complete = errors.len() == held_out.len();
    let error = complete.then(|| PositionError::summed(&errors));
    let rate = if outcome.starts_with("failed") {
        f64::NAN
    } else {
        wall / simulated.max(1e-300)
    };
    RomRow {
        latent,
        samples,
        wall_seconds: if rate.is_nan() { f64::NAN } else { wall },
        wall_per_simulated_second: rate,
        speedup: full_rate / rate,
        error: error.map(|e| e.relative),
        error_to_displacement: error.map(|e| e.relative_to_displacement),
        quadrature_points: quadrature,
        sample_condition: condition,
        outcome,
    }
}

fn fmt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3e}"))
}

fn write_study(dir: &Path, rows: &[RomRow], full_rate: f64, held_out: usize) -> anyhow::Result<()> {
    let mut csv = String::from(
        "latent,samples,wall_seconds,wall_per_simulated_second,speedup,error,\
         error_to_displacement,quadrature_points,sample_condition,outcome\n",
    );
    for r in rows {
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{}\n",
            r.latent,
            r.samples,
            r.wall_seconds,
            r.wall_per_simulated_second,
            r.speedup,
            r.error.map_or(String::new(), |v| v.to_string()),
            r.error_to_displacement
                .map_or(String::new(), |v| v.to_string()),
            r.quadrature_points,
            r.sample_condition,
            r.outcome.replace(',', ";")
        ));
    }
    std::fs::write(dir.join("rom-study.csv"), csv)?;
    let json = serde_json::json!({
        "full_order_wall_per_simulated_second": full_rate,
        "held_out_runs": held_out,
        "rows": rows,
    });
    std::fs::write(
        dir.join("rom-study.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    Ok(())
}
