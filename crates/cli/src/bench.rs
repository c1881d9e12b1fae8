//! `mpm bench`: built-in benchmark scenes at a few grid sizes, each run for a fixed number
//! of steps, reporting particle-steps per second, bytes per particle and grid bytes.
//!
//! The scenes are generated here from the examples, with n cells along each axis:
//! - `cube-drop`: `examples/cube-drop.json` (fixed-corotated, APIC + MLS-MPM force,
//!   quadratic B-splines, dt = 1e-4 s, slip walls 3 cells thick); the cube holds
//!   ⌊0.8 n⌋ particles along each axis (2 per cell), so ⌊0.8 n⌋³ in all.
//! - `impact`: a Taylor-bar-like cylinder (radius 0.3 L, length 0.7 L, L = 32.4 mm) of the
//!   42CrMo4 Johnson–Cook steel of `examples/taylor-bar.json` hitting a slip wall at 287 m/s,
//!   quarter model with symmetry walls, 2 particles per cell along each axis.
//! - `thermal`: explicit heat conduction in a steel bar (0.1 × 0.025 × 0.025 m in a 0.1 m
//!   box) whose x- face is held at 400 K, mechanics off: the cost of the thermal
//!   plugin's transfers alone.
//!
//! Every scene takes a fixed step (a quarter of the elastic stable step for the impact, half
//! the conduction stable step for the thermal scene) and ends at `steps × dt`; the run is also
//! cancelled at step `steps`, so each case runs exactly `steps` steps unless it stops on a
//! check first. Results go to a null sink unless `--out DIR` is given.

use crate::exit_status::{ExitStatus, input_error};
use crate::stdout::{out, outln};
use mpm_core::output::{Metrics, NullSink, Outcome, OutputSink};
use mpm_core::plugin::Registry;
use mpm_core::scene::parse_scene_value;
use mpm_core::solver::{Control, Progress, RunError, run_scene};
use serde::Serialize;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// The benchmark scenes, in the order they run.
pub const SCENES: [&str; 3] = ["cube-drop", "impact", "thermal"];

/// Smallest size `--size` accepts (16 is for tests; the sizes are 32, 64, 128).
pub const MIN_SIZE: usize = 16;
/// Largest size `--size` accepts (the cube drop at 256³ has 8.4 million particles).
pub const MAX_SIZE: usize = 256;

/// Options of `mpm bench`.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    /// Cells along each axis, comma-separated (16 to 256; 128 is heavy: ~1M particles).
    #[arg(long, default_value = "32,64")]
    pub size: String,
    /// Scenes to run, comma-separated: cube-drop, impact, thermal (default: all).
    #[arg(long)]
    pub scene: Option<String>,
    /// Steps per case (each case runs exactly this many unless it stops on a check).
    #[arg(long, default_value_t = 50)]
    pub steps: u64,
    /// Print one JSON document (machine and cases) instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write each case's result store to DIR/bench-<scene>-<size>.zarr (default: nothing
    /// is written).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Run a peer implementation of the cube drop beside mpm's own, on the same machine and
    /// thread count, and print the ratio: `taichi` (crates/cli/src/bench_peer_taichi.py).
    #[arg(long, value_name = "PEER")]
    pub peer: Option<String>,
    /// The Python that runs the peer (`--peer taichi` needs the `taichi` package in it).
    #[arg(long, value_name = "PATH", default_value = "python3")]
    pub python: PathBuf,
}

/// One measured case.
#[derive(Debug, Serialize)]
pub struct BenchCase {
    /// Scene name (`cube-drop`, `impact`, `thermal`).
    pub scene: String,
    /// Cells along each axis.
    pub cells: usize,
    /// Particles.
    pub particles: usize,
    /// Steps taken.
    pub steps: u64,
    /// Wall seconds of the step loop (setup excluded).
    pub wall_seconds: f64,
    /// Particles × steps / wall seconds.
    pub particle_steps_per_second: f64,
    /// Bytes of particle storage per particle.
    pub bytes_per_particle: f64,
    /// Bytes of the grid.
    pub grid_bytes: usize,
    /// Wall seconds per stage of the step (`p2g`, `g2p`, `stress`, ...; the run's
    /// `metrics.stage_seconds`).
    pub stage_seconds: std::collections::BTreeMap<String, f64>,
    /// `finished` (ran its steps) or `stopped` (on a check; see `note`).
    pub outcome: String,
    /// The diagnostic of a stopped case.
    pub note: Option<String>,
}

/// Parses a comma-separated list of sizes.
pub fn parse_sizes(text: &str) -> anyhow::Result<Vec<usize>> {
    let sizes = text
        .split(',')
        .map(|s| match s.trim().parse::<usize>() {
            Ok(n) if (MIN_SIZE..=MAX_SIZE).contains(&n) => Ok(n),
            _ => Err(input_error!(
                "--size {text}: `{}` is not a number of cells from {MIN_SIZE} to {MAX_SIZE}",
                s.trim()
            )),
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(sizes)
}

/// Parses a comma-separated list of scene names (`None`: all of them).
pub fn parse_scenes(text: Option<&str>) -> anyhow::Result<Vec<&'static str>> {
    let Some(text) = text else {
        return Ok(SCENES.to_vec());
    };
    text.split(',')
        .map(|s| {
            SCENES
                .iter()
                .copied()
                .find(|n| *n == s.trim())
                .ok_or_else(|| {
                    input_error!(
                        "--scene {text}: no benchmark scene `{}`; the scenes are {}",
                        s.trim(),
                        SCENES.join(", ")
                    )
                })
        })
        .collect()
}

/// The scene `name` with `n` cells along each axis, ending after `steps` fixed steps.
pub fn scene(name: &str, n: usize, steps: u64) -> Value {
    let nf = n as f64;
    let end = |dt: f64| steps as f64 * dt;
    match name {
        "cube-drop" => {
            let dx = 1.0 / nf;
            let side = (0.8 * nf).floor() * dx / 2.0;
            let dt = 1e-4;
            json!({
                "name": format!("bench-cube-drop-{n}"), "dimension": 3,
                "domain": {"min": [0, 0, 0], "max": [1, 1, 1], "cell_size": dx,
                    "walls": [{"sides": ["x-", "x+", "y-", "y+", "z-", "z+"],
                               "condition": "slip", "thickness": 3}]},
                "solver": {"end_time": end(dt), "kernel": "bspline2", "transfer": "apic",
                    "mls": true, "scheme": "usl", "dt": dt, "gravity": [0, -9.81, 0]},
                "materials": {"jelly": {"type": "fixed_corotated", "density": 1000.0,
                    "youngs_modulus": 1e5, "poisson_ratio": 0.3}},
                "bodies": [{"name": "cube", "material": "jelly",
                    "shape": {"box": {"min": [0.3, 0.3, 0.3],
                                      "max": [0.3 + side, 0.3 + side, 0.3 + side]}},
                    "particles_per_cell": 2, "velocity": {"uniform": [0, -1, 0]}}],
                "output": {"frames": 1, "fields": ["x", "v"]}
            })
        }
        "impact" => {
            let (l, rho, e, nu, speed): (f64, f64, f64, f64, f64) =
                (0.0324, 7830.0, 206.9e9, 0.3, 287.0);
            let dx = l / nf;
            let wave = (e * (1.0 - nu) / (rho * (1.0 + nu) * (1.0 - 2.0 * nu))).sqrt();
            let dt = 0.25 * dx / (wave + speed);
            let (radius, length) = (0.3 * l, 0.7 * l);
            json!({
                "name": format!("bench-impact-{n}"), "dimension": 3,
                "domain": {"min": [0, 0, 0], "max": [l, l, l], "cell_size": dx,
                    "walls": [{"sides": ["x-", "z-"], "condition": "symmetry"},
                              {"sides": ["y-"], "condition": "slip"}]},
                "solver": {"end_time": end(dt), "kernel": "bspline2", "transfer": "apic",
                    "scheme": "usl", "dt": dt},
                "materials": {"steel": {"type": "johnson_cook", "density": rho,
                    "youngs_modulus": e, "poisson_ratio": nu, "specific_heat": 460.0,
                    "taylor_quinney": 0.9,
                    "flow_stress": {"yield_stress": 806e6, "hardening_modulus": 614e6,
                        "hardening_exponent": 0.168, "strain_rate_sensitivity": 0.0089,
                        "thermal_softening_exponent": 1.1, "reference_strain_rate": 1.0,
                        "room_temperature": 293.15, "melt_temperature": 1813.15}}},
                "bodies": [{"name": "bar", "material": "steel",
                    "shape": {"cylinder": {"center": [0, length / 2.0, 0], "radius": radius,
                                           "axis": [0, 1, 0], "length": length}},
                    "clip_to_domain": true, "particles_per_cell": 2,
                    "velocity": {"uniform": [0, -speed, 0]}}],
                "output": {"frames": 1, "fields": ["x", "v", "plastic_strain", "temperature"]}
            })
        }
        _ => {
            let (l, rho, c, k) = (0.1, 7800.0, 500.0, 50.0);
            let dx = l / nf;
            let dt = 0.5 * rho * c * dx * dx / (2.0 * 3.0 * k);
            json!({
                "name": format!("bench-thermal-{n}"), "dimension": 3,
                "domain": {"min": [0, 0, 0], "max": [l, l, l], "cell_size": dx},
                "solver": {"end_time": end(dt), "kernel": "linear", "mechanics": "off",
                    "dt": dt},
                "materials": {"steel": {"type": "linear_elastic", "density": rho,
                    "youngs_modulus": 200e9, "poisson_ratio": 0.3}},
                "physics": {"thermal": {"integrator": "explicit",
                    "materials": {"steel": {"conductivity": k, "specific_heat": c,
                                            "initial_temperature": 300.0}},
                    "boundaries": [{"sides": ["x-"], "temperature": 400.0}]}},
                "bodies": [{"name": "bar", "material": "steel",
                    "shape": {"box": {"min": [0, 0, 0], "max": [l, l / 4.0, l / 4.0]}},
                    "particles_per_cell": 2}],
                "output": {"frames": 1, "fields": ["x", "temperature"]}
            })
        }
    }
}

/// Runs one case: scene `name` at `n` cells for `steps` steps, into `out` when given.
pub fn run_case(
    name: &str,
    n: usize,
    steps: u64,
    registry: &Registry,
    out: Option<&Path>,
) -> anyhow::Result<BenchCase> {
    let mut null = NullSink;
    let mut zarr;
    let sink: &mut dyn OutputSink = match out {
        Some(dir) => {
            zarr = mpm_io::ZarrSink::new(dir.join(format!("bench-{name}-{n}.zarr")));
            &mut zarr
        }
        None => &mut null,
    };
    run_scene_case(scene(name, n, steps), name, n, steps, registry, sink)
}

/// Runs one case of the scene document `doc` (a [`scene`], possibly changed) into `sink`.
pub(crate) fn run_scene_case(
    doc: Value,
    name: &str,
    n: usize,
    steps: u64,
    registry: &Registry,
    sink: &mut dyn OutputSink,
) -> anyhow::Result<BenchCase> {
    let validated = parse_scene_value(doc, registry, Path::new("."))
        .map_err(|e| input_error!("bench scene {name} at {n}³ cells: {e}"))?;
    let mut stop_at = |p: &Progress| {
        if p.step >= steps {
            Control::Cancel
        } else {
            Control::Continue
        }
    };
    let m: Metrics = match run_scene(&validated, sink, &mut stop_at) {
        Ok(m) => m,
        Err(RunError::Refused { path, message }) => {
            return Err(input_error!(
                "bench scene {name} at {n}³ cells: {path}: {message}"
            ));
        }
        Err(e) => return Err(e.into()),
    };
    let stopped = m.outcome == Some(Outcome::Stopped);
    Ok(BenchCase {
        scene: name.to_string(),
        cells: n,
        particles: m.particles,
        steps: m.steps,
        wall_seconds: m.wall_seconds,
        particle_steps_per_second: m.particle_steps_per_second,
        bytes_per_particle: m.bytes_per_particle,
        grid_bytes: m.grid_bytes,
        stage_seconds: m.stage_seconds,
        outcome: if stopped { "stopped" } else { "finished" }.into(),
        note: m.diagnostic.map(|d| {
            format!(
                "step {}: {} = {:.3e}: {}",
                d.step, d.field, d.value, d.message
            )
        }),
    })
}

/// The table of the human output (Markdown, so it can be pasted into the README).
pub fn table(cases: &[BenchCase]) -> String {
    let mut s = String::from(
        "| scene | cells | particles | steps | wall s | M particle-steps/s | bytes/particle | grid MB |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    for c in cases {
        let note = c
            .note
            .as_deref()
            .map(|n| format!(" (stopped: {n})"))
            .unwrap_or_default();
        s += &format!(
            "| {}{note} | {}³ | {} | {} | {:.2} | {:.2} | {:.0} | {:.1} |\n",
            c.scene,
            c.cells,
            c.particles,
            c.steps,
            c.wall_seconds,
            c.particle_steps_per_second / 1e6,
            c.bytes_per_particle,
            c.grid_bytes as f64 / 1e6
        );
    }
    s
}

/// Where each case's loop time went, in percent per stage (Markdown).
pub fn breakdown(cases: &[BenchCase]) -> String {
    let shown: Vec<&str> = mpm_core::solver::STEP_STAGES
        .into_iter()
        .filter(|s| cases.iter().any(|c| c.stage_seconds.contains_key(*s)))
        .collect();
    let mut s = format!("| scene | cells | {} | other |\n", shown.join(" | "));
    s += &format!("|---|---|{}---|\n", "---|".repeat(shown.len()));
    for c in cases {
        let share = |t: f64| 100.0 * t / c.wall_seconds.max(f64::MIN_POSITIVE);
        let mut row = format!("| {} | {}³ |", c.scene, c.cells);
        let mut timed = 0.0;
        for stage in &shown {
            let t = c.stage_seconds.get(*stage).copied().unwrap_or(0.0);
            timed += t;
            row += &format!(" {:.1}% |", share(t));
        }
        row += &format!(" {:.1}% |\n", share((c.wall_seconds - timed).max(0.0)));
        s += &row;
    }
    s
}

/// The head of a `--json` document: the machine, date, commit, build and steps per case.
pub(crate) fn header(threads: usize, steps: u64) -> Value {
    json!({
        "machine": {
            "cores": std::thread::available_parallelism().map_or(0, |n| n.get()),
            "threads": threads,
            "os": std::env::consts::OS,
            "arch": std::env::consts::ARCH,
        },
        "date": today(),
        "commit": commit(),
        "version": env!("CARGO_PKG_VERSION"),
        "debug_assertions": cfg!(debug_assertions),
        "steps": steps,
    })
}

/// Today's date (UTC) as `YYYY-MM-DD`, from the system clock.
pub(crate) fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    // Days since 1970-01-01 to a civil date (H. Hinnant's algorithm).
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}

/// The commit: `MPM_COMMIT` from the environment, else `git rev-parse` here, else none.
pub(crate) fn commit() -> Option<String> {
    if let Ok(c) = std::env::var("MPM_COMMIT") {
        return Some(c);
    }
    let out = std::process::Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .stderr(std::process::Stdio::null())
        .output()
        .ok()?;
    let text = String::from_utf8(out.stdout).ok()?;
    (out.status.success() && !text.trim().is_empty()).then(|| text.trim().to_string())
}

/// Runs `mpm bench`.
pub fn run(args: BenchArgs, registry: &Registry) -> anyhow::Result<ExitStatus> {
    let sizes = parse_sizes(&args.size)?;
    let scenes = parse_scenes(args.scene.as_deref())?;
    if args.steps == 0 || args.steps > 1_000_000 {
        return Err(input_error!(
            "--steps {}: give a number of steps from 1 to 1000000",
            args.steps
        ));
    }
    if let Some(peer) = &args.peer {
        return crate::bench_peer::run(&args, peer, &sizes, &scenes, registry);
    }
    let mut cases = Vec::new();
    for name in &scenes {
        for &n in &sizes {
            eprintln!("bench: {name} at {n}³ cells, {} steps", args.steps);
            cases.push(run_case(
                name,
                n,
                args.steps,
                registry,
                args.out.as_deref(),
            )?);
        }
    }
    let threads = rayon::current_num_threads();
    if args.json {
        let mut doc = header(threads, args.steps);
        doc["cases"] = json!(cases);
        outln!("{}", serde_json::to_string_pretty(&doc)?)?;
    } else {
        out!("{}", table(&cases))?;
        outln!("\nWhere the loop's wall time goes (metrics.stage_seconds):\n")?;
        out!("{}", breakdown(&cases))?;
        outln!(
            "{threads} threads, {} steps per case, {}",
            args.steps,
            today()
        )?;
    }
    Ok(if cases.iter().any(|c| c.outcome == "stopped") {
        ExitStatus::Stopped
    } else {
        ExitStatus::Success
    })
}
