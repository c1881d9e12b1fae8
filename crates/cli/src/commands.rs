//! The subcommands of `mpm`.

use crate::exit_status::{ExitStatus, input_error};
use crate::progress::ProgressReporter;
use crate::scene_file::{load_scene, report_load_error};
use crate::stdout::{out, outln};
use anyhow::Context;
use clap::{Parser, Subcommand};
use mpm_core::output::{Metrics, Outcome};
use mpm_core::plugin::Registry;
use mpm_core::scene::ValidatedScene;
use mpm_core::solver::{RunError, run_scene};
use std::path::{Path, PathBuf};

/// Command-line interface of `mpm`.
#[derive(Debug, Parser)]
#[command(name = "mpm", version, about = "Material point method simulator")]
pub struct Cli {
    /// Worker threads (default: every core).
    #[arg(long, global = true, env = "MPM_THREADS")]
    pub threads: Option<usize>,
    /// Raise or lower a bound on a scene's work, `NAME=N` (repeatable): particles,
    /// grid_nodes, frames, store_bytes, file_bytes, steps, setup_tests.
    #[arg(long = "limit", global = true, value_name = "NAME=N")]
    pub limits: Vec<String>,
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run a scene locally and write DIR/<name>.zarr.
    Run {
        /// Scene file (JSON); not with --resume.
        #[arg(required_unless_present = "resume", conflicts_with = "resume")]
        scene: Option<PathBuf>,
        /// Continue the run whose result store this is from its latest checkpoint (the
        /// scene is the one stored; the store is written on in place). Relative particle
        /// files of the scene are looked up from the current folder.
        #[arg(long, value_name = "STORE", conflicts_with = "set")]
        resume: Option<PathBuf>,
        /// Start the scene where the run of this result store left its particles (its
        /// latest checkpoint; same dimension, domain, materials, bodies, contact and
        /// loads), as a stage takes over from the stage before; the scene's end time is
        /// absolute.
        #[arg(
            long,
            value_name = "STORE",
            requires = "scene",
            conflicts_with = "resume"
        )]
        from: Option<PathBuf>,
        /// With --from a staged run's store and a staged scene: start at this stage of the
        /// scene from the state the store's stage before it ended with (its stages before
        /// this one must be the stored run's; kept by a stage with `output.end_state` or
        /// `output.checkpoint`).
        #[arg(long, value_name = "NAME", requires = "from")]
        stage: Option<String>,
        /// Output folder.
        #[arg(long, default_value = "results")]
        out: PathBuf,
        /// Change a scene value first, e.g. `--set solver.end_time=0.1` (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Print the metrics as JSON on stdout instead of the summary.
        #[arg(long)]
        json: bool,
        /// No progress output.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Check a scene file without running it.
    Validate {
        /// Scene file (JSON).
        scene: PathBuf,
        /// Change a scene value first (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
    },
    /// Export a result store to VTK (.pvd + .vtu) for ParaView.
    Export {
        /// Result store (`results/<name>.zarr`).
        store: PathBuf,
        /// Folder for the VTK files.
        #[arg(long)]
        vtk: PathBuf,
        /// Stage of a staged run's store (its name; default: the last stage).
        #[arg(long)]
        stage: Option<String>,
    },
    /// Draw one frame of a result store as a PNG picture (for documentation).
    ///
    /// The particles are squares of their spacing, coloured by a field (viridis, NaN grey)
    /// with a colour bar, on equal axes in m, mm or µm; the title names the scene, the field
    /// and the time. A 3D store is seen along one axis (--plane), the nearest particles on
    /// top, whole or a slab of it (--slab). Particles an inlet has not let in yet, or that
    /// left through an open face (`injected` 0 or -1), are not drawn. With --voids, the voids
    /// listed in a table of the store's metrics (columns x, y, area in m² in 2D; x, y, z,
    /// volume in m³ in 3D, drawn as the circle of the sphere of that volume; optional id)
    /// are marked as red circles, only those open at the frame's time when the table has
    /// closed_time and filled_time: e.g. the fill pattern of an underfill between a chip
    /// and its substrate with the trapped air.
    Render {
        /// Result store (`results/<name>.zarr`) of a 2D or 3D run.
        store: PathBuf,
        /// Particle field to colour by: a scalar, or a vector or tensor with --component.
        #[arg(long)]
        field: String,
        /// Frame to draw; negative counts from the end (default: -1, the last).
        #[arg(long, allow_negative_numbers = true)]
        frame: Option<i64>,
        /// Component of a vector or tensor field, as a flat index (stress xy in 2D is 1).
        #[arg(long, default_value_t = 0)]
        component: usize,
        /// PNG file to write.
        #[arg(long)]
        out: PathBuf,
        /// Title (default: "<scene> — <field> at t = <time> s").
        #[arg(long)]
        title: Option<String>,
        /// Mark the voids of this table of the store's metrics (`metrics.tables.TABLE`).
        #[arg(long, value_name = "TABLE")]
        voids: Option<String>,
        /// Stage of a staged run's store (its name; default: the last stage).
        #[arg(long)]
        stage: Option<String>,
        /// The two axes a 3D store is drawn on: xy (seen along z, the default), xz or yz.
        #[arg(long)]
        plane: Option<String>,
        /// Draw only the particles of a 3D store whose third coordinate lies in LO:HI (m).
        #[arg(long, value_name = "LO:HI", allow_hyphen_values = true)]
        slab: Option<String>,
        /// Draw each particle as its square at the first frame's spacing deformed by F (the
        /// store must hold `F`): a body stretched to several times its length shows whole
        /// where it is whole, and torn where it tore.
        #[arg(long)]
        deformed: bool,
        /// Leave out the outlines of a refined run's grid levels (drawn by default: each
        /// finer level's region as the solver built it, level 1 white, 2 orange, 3 magenta).
        #[arg(long)]
        no_levels: bool,
    },
    /// Print the JSON Schema of scene files (as checked into api/scene.schema.json).
    Schema,
    /// List the registered plugins with their materials, physics sections and references,
    /// and the core's references (of a server with --server).
    Plugins {
        /// Print every section's JSON Schema too.
        #[arg(long)]
        schemas: bool,
        /// Ask this server instead of listing the local ones.
        #[arg(long, env = "MPM_SERVER")]
        server: Option<String>,
        /// Bearer token for the server.
        #[arg(long, env = "MPM_TOKEN")]
        token: Option<String>,
    },
    /// Run a scene over a sweep of settings; table (CSV, JSON) and plot (PNG, SVG) of error
    /// against wall time.
    Study {
        /// Scene file (JSON); it should carry a reference.
        scene: PathBuf,
        /// A swept setting, `KEY=V1,V2,...` (repeatable). KEY is any scene path
        /// (`solver.cfl`) or one of cell_size, kernel, transfer, scheme, cfl, mls, dt, ppc.
        #[arg(long = "vary", value_name = "KEY=V1,V2", required = true)]
        vary: Vec<String>,
        /// Output folder (default results/<scene>-study).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Local runs at a time (they then share the cores; 1 keeps wall times comparable).
        #[arg(long, default_value_t = 1)]
        parallel: usize,
        /// Submit the runs to this server as a group of jobs instead of running locally.
        #[arg(long, env = "MPM_SERVER")]
        server: Option<String>,
        /// Bearer token for the server.
        #[arg(long, env = "MPM_TOKEN")]
        token: Option<String>,
    },
    /// Run the stability suite (stiff and extreme cases) and print its table; with --map,
    /// the stability maps instead; with --long, the long runs.
    CheckStability {
        /// Only the cases whose name contains this.
        #[arg(long)]
        only: Option<String>,
        /// Also write the results as JSON to this file (with --map: one record per run).
        #[arg(long)]
        json: Option<PathBuf>,
        /// Stability maps: run the bar, the impact and the near-incompressible block at
        /// fixed steps of each CFL factor times the stable one, for every transfer × scheme
        /// × kernel and implicit dynamics; print a table per case and draw a PNG per case.
        /// Exits 0 whatever the runs do (a measurement), 1 when a run failed otherwise than
        /// by stopping itself or a picture cannot be written.
        #[arg(long, conflicts_with = "long")]
        map: bool,
        /// Long runs: the spinning disk and the vibrating bar for --steps fixed steps with
        /// each transfer; a table, the series in --json, a PNG per scene in --plot-dir.
        #[arg(long)]
        long: bool,
        /// Steps of each long run (default 100000).
        #[arg(long, requires = "long")]
        steps: Option<u64>,
        /// Folder for the long runs' pictures (`<scene>.png`).
        #[arg(long, default_value = "stability-long", requires = "long")]
        plot_dir: PathBuf,
        /// The CFL factors of the map's columns (default 0.1,0.25,0.5,0.75,1,1.25,1.5,2).
        #[arg(long, value_delimiter = ',', requires = "map")]
        cfl: Vec<f64>,
        /// Only the map's rows one of these comma-separated patterns names: whole
        /// `/`-separated parts of a label (`transfer/scheme/kernel`, `implicit/kernel`),
        /// e.g. `apic` (not `pic`), `usl/bspline2`, `implicit`.
        #[arg(long, requires = "map")]
        rows: Option<String>,
        /// Folder for the map's pictures (`<case>.png`).
        #[arg(long, default_value = "stability-map", requires = "map")]
        map_dir: PathBuf,
    },
    /// Run the built-in benchmark scenes (cube drop, Johnson–Cook impact, thermal) at a few
    /// grid sizes for a fixed number of steps; print particle-steps per second, bytes per
    /// particle and grid bytes (a table, or JSON). The global --threads sets the pool size.
    Bench(crate::bench::BenchArgs),
    /// Reduced-order models: train on full runs, run, measure the error, sweep.
    Rom {
        /// What to do.
        #[command(subcommand)]
        command: crate::rom::RomCommand,
    },
    /// Start the job service (HTTP API over a SQLite or PostgreSQL job queue, with workers).
    Serve(crate::service_cmd::ServeArgs),
    /// Run workers of the job service without the HTTP API (any number of machines sharing a
    /// PostgreSQL queue and a result folder).
    Worker(crate::service_cmd::WorkerArgs),
    /// Run one job of `mpm serve` in a process of its own (used by the service).
    #[command(hide = true)]
    RunJob(crate::job::RunJobArgs),
    /// Submit a scene to a server.
    Submit {
        /// Scene file (JSON).
        scene: PathBuf,
        /// Change a scene value first (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Wait for the job to end, with a progress bar, and print its metrics.
        #[arg(long)]
        wait: bool,
        /// Start from this job's stored state (its latest checkpoint, or with `--stage` the
        /// end of the stage before), as `mpm run --from STORE` does.
        #[arg(long, value_name = "JOB")]
        from: Option<String>,
        /// With `--from`: the stage of the staged scene to start at.
        #[arg(long, value_name = "NAME", requires = "from")]
        stage: Option<String>,
        #[command(flatten)]
        remote: RemoteArgs,
    },
    /// Show one job of a server.
    Status {
        /// Job id.
        id: String,
        #[command(flatten)]
        remote: RemoteArgs,
    },
    /// List the jobs of a server.
    List {
        /// Only jobs with this status.
        #[arg(long)]
        status: Option<String>,
        #[command(flatten)]
        remote: RemoteArgs,
    },
    /// Cancel a queued or running job.
    Cancel {
        /// Job id.
        id: String,
        #[command(flatten)]
        remote: RemoteArgs,
    },
    /// Download a job's result store into DIR/<name>.zarr.
    Fetch {
        /// Job id.
        id: String,
        /// Folder to download into.
        #[arg(long, default_value = "results")]
        out: PathBuf,
        #[command(flatten)]
        remote: RemoteArgs,
    },
}

/// Where the job service is.
#[derive(Debug, clap::Args)]
pub struct RemoteArgs {
    /// Server URL.
    #[arg(long, default_value = "http://127.0.0.1:8080", env = "MPM_SERVER")]
    pub server: String,
    /// Bearer token for the server.
    #[arg(long, env = "MPM_TOKEN")]
    pub token: Option<String>,
}

impl RemoteArgs {
    fn remote(&self) -> crate::client::Remote {
        crate::client::Remote {
            server: self.server.clone(),
            token: self.token.clone(),
        }
    }
}

/// Runs a parsed command line.
pub fn run_cli(cli: Cli, registry: Registry) -> anyhow::Result<ExitStatus> {
    let registry = std::sync::Arc::new(registry);
    match crate::job::limits_from(&cli.limits) {
        Ok(limits) => {
            mpm_core::scene::Limits::set_current(limits);
        }
        Err(e) => {
            eprintln!("error: --limit {e}");
            return Ok(ExitStatus::InvalidInput);
        }
    }
    if let Some(threads) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global()
            .context("setting the thread count")?;
    }
    match cli.command {
        Command::Validate { scene, set } => match load_scene(&scene, &set, &registry) {
            Ok(v) => {
                if let Err(e) = mpm_core::solver::preflight(&v) {
                    eprintln!("error: {}: {e}", scene.display());
                    return Ok(ExitStatus::InvalidInput);
                }
                let stages = if v.stages.is_empty() {
                    String::new()
                } else {
                    let names: Vec<&str> = v.stages.iter().map(|s| s.name.as_str()).collect();
                    format!(", stages {}", names.join(" → "))
                };
                outln!(
                    "{}: valid ({}D, {} particles in {} bodies, {} material(s){stages})",
                    scene.display(),
                    v.scene.dimension,
                    v.particle_count(),
                    v.scene.bodies.len(),
                    v.materials.len()
                )?;
                Ok(ExitStatus::Success)
            }
            Err(e) => Ok(report_load_error(&scene, e)),
        },
        Command::Run {
            scene,
            resume,
            from,
            stage,
            out,
            set,
            json,
            quiet,
        } => {
            let mut handed_over = None;
            let mut stage_start = None;
            let (validated, store, scene, checkpoint) = match (scene, resume) {
                (Some(scene), _) => {
                    let validated = match load_scene(&scene, &set, &registry) {
                        Ok(v) => v,
                        Err(e) => return Ok(report_load_error(&scene, e)),
                    };
                    let store = out.join(format!("{}.zarr", validated.scene.name));
                    if let Some(from) = &from {
                        let same = |a: &std::path::Path, b: &std::path::Path| {
                            a.canonicalize()
                                .ok()
                                .is_some_and(|a| b.canonicalize().ok() == Some(a))
                        };
                        if same(from, &store) {
                            eprintln!(
                                "error: {}: the run would write over the store it starts from; \
                                 give another --out or scene name",
                                store.display()
                            );
                            return Ok(ExitStatus::InvalidInput);
                        }
                        let loaded = match &stage {
                            Some(name) => {
                                crate::from_store::load_stage(from, &validated, name, &registry)
                                    .map(|start| stage_start = Some(start))
                            }
                            None => crate::from_store::load(from, &validated)
                                .map(|c| handed_over = Some(c)),
                        };
                        if let Err(status) = loaded {
                            return Ok(status);
                        }
                    }
                    (validated, store, scene, None)
                }
                (None, Some(store)) => match crate::resume::load(&store, &registry) {
                    Ok((validated, checkpoint)) => {
                        (validated, store.clone(), store, Some(checkpoint))
                    }
                    Err(status) => return Ok(status),
                },
                (None, None) => anyhow::bail!("give a scene file or --resume STORE"),
            };
            let mut progress = ProgressReporter::new(quiet || json);
            let result = match (&checkpoint, &handed_over, &stage_start) {
                (None, None, Some((index, state))) => mpm_core::solver::run_scene_from_stage(
                    &validated,
                    *index,
                    state,
                    &mut mpm_io::ZarrSink::new(&store),
                    &mut progress,
                ),
                (None, Some(c), _) => mpm_core::solver::run_scene_from(
                    &validated,
                    c,
                    &mut mpm_io::ZarrSink::new(&store),
                    &mut progress,
                ),
                (None, None, None) => run_scene(
                    &validated,
                    &mut mpm_io::ZarrSink::new(&store),
                    &mut progress,
                ),
                (Some(c), _, _) => {
                    let frames = c.state("frames").as_u64().unwrap_or(0) as usize;
                    let mut sink = mpm_io::ZarrSink::resume(&store, frames);
                    mpm_core::solver::resume_scene(&validated, c, &mut sink, &mut progress)
                }
            };
            progress.finish();
            let metrics = match result {
                Ok(m) => m,
                Err(RunError::Refused { path, message }) => {
                    eprintln!("error: {}: {path}: {message}", scene.display());
                    return Ok(ExitStatus::InvalidInput);
                }
                Err(e) => return Err(e.into()),
            };
            if json {
                outln!("{}", serde_json::to_string_pretty(&metrics)?)?;
            } else {
                print_summary(&validated, &metrics, &store)?;
            }
            Ok(match metrics.outcome {
                Some(Outcome::Finished) => ExitStatus::Success,
                _ => ExitStatus::Stopped,
            })
        }
        Command::Rom { command } => crate::rom::run(command, &registry),
        Command::Bench(args) => crate::bench::run(args, &registry),
        Command::RunJob(args) => Ok(crate::job::run(&args, &registry)),
        Command::Export { store, vtk, stage } => {
            let pvd = mpm_io::export_vtk(&store, &vtk, stage.as_deref())?;
            outln!("wrote {}", pvd.display())?;
            Ok(ExitStatus::Success)
        }
        Command::Render {
            store,
            field,
            frame,
            component,
            out,
            title,
            voids,
            stage,
            plane,
            slab,
            deformed,
            no_levels,
        } => {
            let r = crate::render::render(&crate::render::RenderArgs {
                store,
                field,
                frame,
                component,
                out: out.clone(),
                title,
                voids,
                stage,
                plane,
                slab,
                deformed,
                hide_levels: no_levels,
            })?;
            let voids = r
                .voids
                .map(|n| format!(", {n} void{} marked", if n == 1 { "" } else { "s" }))
                .unwrap_or_default();
            let levels = r
                .levels
                .map(|n| format!(", {n} refined level(s) outlined"))
                .unwrap_or_default();
            outln!(
                "wrote {} (frame {}, t = {} s, {} particles, {} from {} to {}{voids}{levels})",
                out.display(),
                r.frame,
                crate::render::short(r.time),
                r.particles,
                r.label,
                crate::render::short(r.range.0),
                crate::render::short(r.range.1),
            )?;
            Ok(ExitStatus::Success)
        }
        Command::Schema => {
            outln!(
                "{}",
                serde_json::to_string_pretty(&crate::schema::scene_schema(&registry))?
            )?;
            Ok(ExitStatus::Success)
        }
        Command::Plugins {
            schemas,
            server,
            token,
        } => {
            let catalogue = match server {
                Some(server) => crate::client::plugins(&crate::client::Remote { server, token })?,
                None => registry.catalogue(),
            };
            print_catalogue(&catalogue, schemas)?;
            Ok(ExitStatus::Success)
        }
        Command::Serve(args) => crate::service_cmd::serve(args, registry.clone()),
        Command::Worker(args) => crate::service_cmd::worker(args, registry.clone()),
        Command::CheckStability {
            only,
            json,
            map: true,
            cfl,
            rows,
            map_dir,
            ..
        } => check_stability_map(only, json, cfl, rows, map_dir, &registry),
        Command::CheckStability {
            only,
            json,
            long: true,
            steps,
            plot_dir,
            ..
        } => crate::stability_long::check_stability_long(only, json, steps, plot_dir, &registry),
        Command::CheckStability { only, json, .. } => {
            let all = crate::stability::cases();
            let chosen = crate::stability::choose_cases(
                &all,
                |c| c.name,
                only.as_deref(),
                "stability case",
            )?;
            let mut results = Vec::new();
            for case in chosen {
                eprintln!("{}: {}", case.name, case.what);
                results.push(crate::stability::run_case(case, &registry));
            }
            out!("{}", crate::stability::table(&results))?;
            if let Some(path) = json {
                std::fs::write(&path, serde_json::to_string_pretty(&results)?)
                    .with_context(|| format!("cannot write `{}`", path.display()))?;
            }
            let failed = results.iter().filter(|r| !r.pass).count();
            outln!("{} passed, {failed} failed", results.len() - failed)?;
            Ok(if failed == 0 {
                ExitStatus::Success
            } else {
                ExitStatus::Failure
            })
        }
        Command::Study {
            scene,
            vary,
            out,
            parallel,
            server,
            token,
        } => {
            let text = std::fs::read_to_string(&scene)
                .with_context(|| format!("cannot read scene file `{}`", scene.display()))?;
            let value: serde_json::Value = serde_json::from_str(&text)
                .map_err(|e| input_error!("{}: $: not valid JSON: {e}", scene.display()))?;
            let bodies = value["bodies"].as_array().map_or(0, |b| b.len());
            let vars = vary
                .iter()
                .map(|v| crate::study::parse_variation(v, bodies))
                .collect::<anyhow::Result<Vec<_>>>()?;
            let report = |i: usize, n: usize, labels: &[(String, String)]| {
                let text: Vec<String> = labels.iter().map(|(k, v)| format!("{k}={v}")).collect();
                eprintln!("run {}/{n}: {}", i + 1, text.join(" "));
            };
            let rows = match server {
                Some(server) => {
                    let remote = crate::client::Remote { server, token };
                    crate::study::run_remote(&scene, &vars, &remote, report)?
                }
                None => crate::study::run_local(&scene, &vars, &registry, parallel, report),
            };
            if rows.iter().all(|r| r.outcome == "invalid") {
                // Nothing ran: the scene is invalid under every setting. Say why, write nothing.
                let mut messages: Vec<&str> =
                    rows.iter().filter_map(|r| r.message.as_deref()).collect();
                messages.dedup();
                for m in messages {
                    eprintln!("error: {}: {m}", scene.display());
                }
                return Ok(ExitStatus::InvalidInput);
            }
            let dir = out.unwrap_or_else(|| crate::study::default_dir(&scene));
            crate::study::write_tables(&dir, &vars, &rows)?;
            let title = format!(
                "{}: error against wall time",
                value["name"].as_str().unwrap_or("study")
            );
            crate::plot::draw(&dir, &title, &rows)?;
            out!("{}", crate::study::table(&vars, &rows))?;
            for (name, group) in crate::study::series(&rows) {
                if let Some(order) = crate::study::observed_order(&group) {
                    outln!("observed order {order:.2}: {name}")?;
                }
            }
            outln!("wrote {}/study.{{csv,json,png,svg}}", dir.display())?;
            Ok(ExitStatus::Success)
        }
        Command::Submit {
            scene,
            set,
            wait,
            from,
            stage,
            remote,
        } => {
            let remote = remote.remote();
            let start = crate::client::StartFrom { job: from, stage };
            let job = crate::client::submit_from(&remote, &scene, &set, &start)?;
            let id = job["id"].as_str().unwrap_or("?").to_string();
            outln!("submitted job {id}")?;
            if !wait {
                return Ok(ExitStatus::Success);
            }
            let job = crate::client::wait(&remote, &id, false)?;
            outln!("status {}", job["status"].as_str().unwrap_or("?"))?;
            outln!("{}", serde_json::to_string_pretty(&job["metrics"])?)?;
            for line in crate::process_report::job_report(&job["metrics"]) {
                outln!("report         {line}")?;
            }
            if !job["failure"].is_null() {
                outln!("failure {}", job["failure"])?;
            }
            Ok(match job["status"].as_str() {
                Some("succeeded") => ExitStatus::Success,
                _ if job["metrics"]["outcome"] == "stopped" => ExitStatus::Stopped,
                // Cancelled, or failed for a reason of the server's (the scene was validated
                // when it was submitted).
                _ => ExitStatus::Failure,
            })
        }
        Command::Status { id, remote } => {
            let job = crate::client::status(&remote.remote(), &id)?;
            outln!("{}", serde_json::to_string_pretty(&job)?)?;
            Ok(ExitStatus::Success)
        }
        Command::List { status, remote } => {
            let answer = crate::client::list(&remote.remote(), status.as_deref())?;
            for job in answer["jobs"].as_array().into_iter().flatten() {
                outln!("{}", crate::client::job_line(job))?;
            }
            Ok(ExitStatus::Success)
        }
        Command::Cancel { id, remote } => {
            let job = crate::client::cancel(&remote.remote(), &id)?;
            outln!("job {} is {}", id, job["status"].as_str().unwrap_or("?"))?;
            Ok(ExitStatus::Success)
        }
        Command::Fetch { id, out, remote } => {
            let path = crate::client::fetch(&remote.remote(), &id, &out)?;
            outln!("fetched {}", path.display())?;
            Ok(ExitStatus::Success)
        }
    }
}

/// `mpm check-stability --map`: runs the chosen map cases over the chosen rows and CFL
/// factors, prints a table per case, writes `<map_dir>/<case>.png` and, with `json`, every
/// run as one record. Bad options are invalid input (2); a run that failed otherwise than
/// by stopping itself, or a file that cannot be written, is a failure (1); else success,
/// whatever the runs did.
fn check_stability_map(
    only: Option<String>,
    json: Option<PathBuf>,
    cfl: Vec<f64>,
    rows: Option<String>,
    map_dir: PathBuf,
    registry: &Registry,
) -> anyhow::Result<ExitStatus> {
    use crate::stability_map as map;
    let factors = if cfl.is_empty() {
        map::DEFAULT_FACTORS.to_vec()
    } else {
        cfl
    };
    map::check_factors(&factors).map_err(|e| input_error!("{e}"))?;
    let rows = map::select_rows(rows.as_deref()).map_err(|e| input_error!("{e}"))?;
    let all = map::cases();
    let chosen = crate::stability::choose_cases(&all, |c| c.name, only.as_deref(), "map case")?;
    std::fs::create_dir_all(&map_dir)
        .with_context(|| format!("cannot create `{}`", map_dir.display()))?;
    let mut cells = Vec::new();
    for case in chosen {
        eprintln!(
            "{}: {} ({} rows × {} CFL factors)",
            case.name,
            case.what,
            rows.len(),
            factors.len()
        );
        let done = map::run_map(case, &rows, &factors, registry, |row, cells| {
            let line: Vec<String> = cells.iter().map(map::cell_text).collect();
            eprintln!("  {}: {}", row.label, line.join(", "));
        })
        .map_err(|e| anyhow::anyhow!("{e}"))?;
        out!("{}\n", map::table(&done))?;
        let png = map_dir.join(format!("{}.png", done.case));
        crate::stability_map_plot::draw(&png, &done)?;
        outln!("picture: {}\n", png.display())?;
        cells.extend(done.cells);
    }
    outln!("{}", map::summary(&cells))?;
    if let Some(path) = json {
        std::fs::write(&path, serde_json::to_string_pretty(&cells)?)
            .with_context(|| format!("cannot write `{}`", path.display()))?;
    }
    let errors: Vec<&map::MapCell> = cells
        .iter()
        .filter(|c| c.outcome == map::MapOutcome::Error)
        .collect();
    for c in &errors {
        eprintln!("{} {} at CFL {}: {}", c.case, c.row, c.cfl, c.note);
    }
    Ok(if errors.is_empty() {
        ExitStatus::Success
    } else {
        ExitStatus::Failure
    })
}

/// Prints a plugin catalogue (see `Registry::catalogue`): each plugin with its materials,
/// physics sections and references, then the core's references; `schemas`: with each
/// section's JSON Schema.
fn print_catalogue(catalogue: &serde_json::Value, schemas: bool) -> anyhow::Result<()> {
    let print_sections = |owner: &serde_json::Value| -> anyhow::Result<()> {
        for (kind, key) in [
            ("material", "materials"),
            ("physics", "physics"),
            ("reference", "references"),
        ] {
            for (name, schema) in owner[key].as_object().into_iter().flatten() {
                outln!("  {kind} `{name}`")?;
                if schemas {
                    outln!("{}", serde_json::to_string_pretty(schema)?)?;
                }
            }
        }
        Ok(())
    };
    for p in catalogue["plugins"].as_array().into_iter().flatten() {
        outln!(
            "{}: {}",
            p["name"].as_str().unwrap_or("?"),
            p["description"].as_str().unwrap_or("")
        )?;
        print_sections(p)?;
    }
    if catalogue["core"]["references"]
        .as_object()
        .is_some_and(|r| !r.is_empty())
    {
        outln!("core: the mechanics references of the solver itself")?;
        print_sections(&catalogue["core"])?;
    }
    Ok(())
}

fn print_summary(v: &ValidatedScene, m: &Metrics, store: &Path) -> anyhow::Result<()> {
    let s = &v.scene;
    outln!(
        "scene          {} ({}D, {:?} kernel, {:?}{}, {:?})",
        s.name,
        s.dimension,
        s.solver.kernel,
        s.solver.transfer,
        if s.solver.mls { " + MLS" } else { "" },
        s.solver.scheme
    )?;
    outln!("outcome        {:?}", m.outcome.unwrap_or(Outcome::Stopped))?;
    if let Some(d) = &m.diagnostic {
        let particle = d
            .particle
            .map(|p| format!(", particle {p}"))
            .unwrap_or_default();
        outln!(
            "diagnostic     step {}, t = {:.6e} s{particle}, {} = {:.6e}: {}",
            d.step,
            d.time,
            d.field,
            d.value,
            d.message
        )?;
    }
    outln!("particles      {}", m.particles)?;
    for stage in &m.stages {
        let error = stage
            .error
            .map(|e| format!(", error {e:.4e}"))
            .unwrap_or_default();
        outln!(
            "stage          {}: {:?}, t = {:.6e} to {:.6e} s, {} steps, {:.3} s{error}",
            stage.name,
            stage.outcome.unwrap_or(Outcome::Stopped),
            stage.start_time,
            stage.end_time,
            stage.steps,
            stage.wall_seconds
        )?;
    }
    for line in crate::process_report::process_report(m) {
        outln!("report         {line}")?;
    }
    if m.stages.is_empty() {
        for (material, d) in &m.damage {
            outln!(
                "damage         {}",
                crate::process_report::damage_line(material, d)
            )?;
        }
    }
    outln!(
        "steps          {} to t = {:.6e} s",
        m.steps,
        m.simulated_time
    )?;
    outln!(
        "wall time      {:.3} s on {} threads",
        m.wall_seconds,
        m.threads
    )?;
    outln!(
        "speed          {:.3e} particle-steps/s",
        m.particle_steps_per_second
    )?;
    outln!(
        "memory         {:.0} bytes/particle, grid {:.1} MB",
        m.bytes_per_particle,
        m.grid_bytes as f64 / 1e6
    )?;
    outln!(
        "energy drift   {:+.3e} (max |drift| {:.3e})",
        m.energy_drift,
        m.max_energy_drift
    )?;
    outln!("min det F      {:.6}", m.min_det_f)?;
    if let Some(e) = m.error {
        outln!(
            "error          {e:.4e}  ({})",
            m.error_kind.as_deref().unwrap_or("")
        )?;
        if let (Some(r), Some(x)) = (m.reference_value, m.measured_value) {
            outln!("               reference {r:.6e}, measured {x:.6e}")?;
        }
    }
    outln!("results        {} ({} frames)", store.display(), m.frames)?;
    Ok(())
}
