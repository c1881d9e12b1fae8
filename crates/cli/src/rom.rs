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
use plotters::prelude::*;
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
}

impl StepArgs {
    fn options(&self, samples: usize) -> RunOptions {
        RunOptions {
            samples,
            time_step_scale: self.dt_scale,
            margin: self.margin,
            interior_samples: !self.surface_samples,
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
    /// Scene file at the held-out parameters.
    scene: PathBuf,
    /// Full-order run of the same scene (the reference and the time to beat).
    #[arg(long)]
    full: PathBuf,
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
    /// `finished`, `stopped`, or the failure.
    pub outcome: String,
}

fn study(args: &StudyArgs, registry: &Registry) -> anyhow::Result<ExitStatus> {
    let validated = match load(&args.scene, &args.set, registry) {
        Ok(v) => v,
        Err(s) => return Ok(s),
    };
    let full = mpm_io::ResultStore::open(&args.full)
        .with_context(|| format!("opening the full-order run {}", args.full.display()))?;
    let full_metrics = full.attributes().get("metrics").ok_or_else(|| {
        anyhow!(
            "{} has no metrics (did the run finish?)",
            args.full.display()
        )
    })?;
    let full_wall = full_metrics["wall_seconds"].as_f64().unwrap_or(f64::NAN);
    let full_time = full_metrics["simulated_time"].as_f64().unwrap_or(f64::NAN);
    let full_rate = full_wall / full_time;
    let dir = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .scene
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".into());
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
            let store = dir.join(format!("latent{latent}-samples{samples}.zarr"));
            let row = match run_one(&validated, &model, &options, &store, true) {
                Ok(m) => {
                    let error = position_error(&store, &args.full).ok();
                    let rate = m.wall_seconds / m.simulated_time.max(1e-300);
                    RomRow {
                        latent,
                        samples,
                        wall_seconds: m.wall_seconds,
                        wall_per_simulated_second: rate,
                        speedup: full_rate / rate,
                        error: error.map(|e| e.relative),
                        error_to_displacement: error.map(|e| e.relative_to_displacement),
                        quadrature_points: m
                            .physics
                            .get("rom.quadrature_points")
                            .copied()
                            .unwrap_or(0.0),
                        outcome: format!("{:?}", m.outcome.unwrap_or(Outcome::Finished))
                            .to_lowercase(),
                    }
                }
                Err(e) => RomRow {
                    latent,
                    samples,
                    wall_seconds: f64::NAN,
                    wall_per_simulated_second: f64::NAN,
                    speedup: f64::NAN,
                    error: None,
                    error_to_displacement: None,
                    quadrature_points: 0.0,
                    outcome: format!("failed: {e}"),
                },
            };
            outln!(
                "latent {:>3}  samples {:>5}  {:>9.3} s/sim-s  speed-up {:>7.2}  error {:>10}  \
                 (to displacement {:>10})  {}",
                row.latent,
                row.samples,
                row.wall_per_simulated_second,
                row.speedup,
                fmt(row.error),
                fmt(row.error_to_displacement),
                row.outcome
            )?;
            rows.push(row);
        }
    }
    outln!("full-order run: {full_rate:.3} s per simulated second")?;
    write_study(&dir, &rows, full_rate)?;
    draw_study(
        &dir.join("rom-study.png"),
        &format!(
            "{}: reduced-order error against wall time",
            validated.scene.name
        ),
        &rows,
        full_rate,
    )?;
    outln!(
        "wrote {0}/rom-study.csv, {0}/rom-study.json, {0}/rom-study.png",
        dir.display()
    )?;
    Ok(ExitStatus::Success)
}

fn fmt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3e}"))
}

fn write_study(dir: &Path, rows: &[RomRow], full_rate: f64) -> anyhow::Result<()> {
    let mut csv = String::from(
        "latent,samples,wall_seconds,wall_per_simulated_second,speedup,error,\
         error_to_displacement,quadrature_points,outcome\n",
    );
    for r in rows {
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},{},{}\n",
            r.latent,
            r.samples,
            r.wall_seconds,
            r.wall_per_simulated_second,
            r.speedup,
            r.error.map_or(String::new(), |v| v.to_string()),
            r.error_to_displacement
                .map_or(String::new(), |v| v.to_string()),
            r.quadrature_points,
            r.outcome.replace(',', ";")
        ));
    }
    std::fs::write(dir.join("rom-study.csv"), csv)?;
    let json = serde_json::json!({
        "full_order_wall_per_simulated_second": full_rate,
        "rows": rows,
    });
    std::fs::write(
        dir.join("rom-study.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    Ok(())
}

fn err<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> anyhow::Error {
    anyhow!("{e}")
}

/// Error (log) against wall time per simulated second (log), one line per latent size, the
/// full-order run as a vertical line.
pub fn draw_study(png: &Path, title: &str, rows: &[RomRow], full_rate: f64) -> anyhow::Result<()> {
    crate::plot::register_font();
    let root = BitMapBackend::new(png, (1000, 650)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let points: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| Some((r.wall_per_simulated_second, r.error?)))
        .filter(|(w, e)| *w > 0.0 && *e > 0.0 && w.is_finite())
        .collect();
    let (mut xmin, mut xmax) = (full_rate, full_rate);
    let (mut ymin, mut ymax) = (f64::MAX, f64::MIN);
    for (x, y) in &points {
        xmin = xmin.min(*x);
        xmax = xmax.max(*x);
        ymin = ymin.min(*y);
        ymax = ymax.max(*y);
    }
    if points.is_empty() {
        ymin = 1e-3;
        ymax = 1e-1;
    }
    let mut chart = crate::plot::log_log_chart(
        &root,
        title,
        (xmin, xmax),
        (ymin, ymax),
        "wall time per simulated second, s",
        "relative L2 position error vs full order",
    )?;
    let mut latents: Vec<usize> = rows.iter().map(|r| r.latent).collect();
    latents.dedup();
    for (i, latent) in latents.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let mut pts: Vec<(f64, f64, usize)> = rows
            .iter()
            .filter(|r| r.latent == *latent)
            .filter_map(|r| Some((r.wall_per_simulated_second, r.error?, r.samples)))
            .filter(|(w, e, _)| *w > 0.0 && *e > 0.0 && w.is_finite())
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| (p.0, p.1)),
                color.stroke_width(2),
            ))
            .map_err(err)?
            .label(format!("reduced, latent {latent}"))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart
            .draw_series(
                pts.iter()
                    .map(|p| Circle::new((p.0, p.1), 4, color.filled())),
            )
            .map_err(err)?;
        chart
            .draw_series(pts.iter().map(|p| {
                Text::new(
                    format!("N={}", p.2),
                    (p.0, p.1),
                    ("sans-serif", 12).into_font(),
                )
            }))
            .map_err(err)?;
    }
    chart
        .draw_series(LineSeries::new(
            vec![(full_rate, ymin / 2.0), (full_rate, ymax * 2.0)],
            BLACK.stroke_width(2),
        ))
        .map_err(err)?
        .label(format!("full order: {full_rate:.3} s per simulated second"))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}
