//! `mpm bench --peer taichi`: the cube drop run by mpm and by a Taichi program of the same
//! scene (crates/cli/src/bench_peer_taichi.py, built into the binary), one after the other
//! on the same machine with the same thread count; prints both speeds, their ratio, and how
//! far apart the two centre-of-mass trajectories are.
//!
//! The trajectories are the check that the peer computes the same thing: the same
//! particles, material, transfer, walls and step, so the same motion up to round-off.

use crate::bench::{BenchArgs, BenchCase, header, run_scene_case, scene, today};
use crate::exit_status::{ExitStatus, input_error};
use crate::stdout::{out, outln};
use anyhow::Context;
use mpm_core::output::{Frame, Metrics, OutputError, OutputSink, RunInfo};
use mpm_core::plugin::Registry;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::process::Command;

/// The Taichi program, written to a temporary file for each `mpm bench --peer taichi`.
const TAICHI_PROGRAM: &str = include_str!("bench_peer_taichi.py");

/// Frames at which both runs record their centre of mass (fewer when there are fewer steps).
const FRAMES: u64 = 10;

/// Largest difference between the two centre-of-mass trajectories accepted, in cells. Both
/// runs do the same arithmetic in f64 except for the order of the sums onto the grid and the
/// polar decomposition's algorithm, which differ at round-off; a peer that differs in the
/// scene (a wall a node off, a step, a constant) is off by far more (see the README).
const TOLERANCE_CELLS: f64 = 1e-6;

/// The centre of mass at one step.
#[derive(Clone, Debug, Deserialize, Serialize)]
struct Sample {
    step: u64,
    com: [f64; 3],
}

/// What the peer program prints.
#[derive(Debug, Deserialize, Serialize)]
struct PeerRun {
    taichi: String,
    particles: usize,
    steps: u64,
    wall_seconds: f64,
    particle_steps_per_second: f64,
    trajectory: Vec<Sample>,
}

/// One size compared.
#[derive(Debug, Serialize)]
struct PeerCase {
    cells: usize,
    mpm: BenchCase,
    peer: PeerRun,
    /// mpm's particle-steps per second over the peer's.
    ratio: f64,
    /// Largest distance between the two centres of mass at the same step, m.
    com_difference: f64,
    /// The accepted largest distance, m.
    com_tolerance: f64,
    /// Steps at which both recorded the centre of mass.
    com_samples: usize,
}

/// A result writer that keeps only the centre of mass of each frame (equal particle masses:
/// the mean position).
#[derive(Default)]
struct CentreOfMass {
    x_field: Option<usize>,
    dimension: usize,
    samples: Vec<Sample>,
}

impl OutputSink for CentreOfMass {
    fn begin(&mut self, info: &RunInfo<'_>) -> Result<(), OutputError> {
        self.dimension = info.dimension;
        self.x_field = info.fields.iter().position(|f| f.name == "x");
        if self.x_field.is_none() {
            return Err(OutputError("the bench scene writes no positions".into()));
        }
        Ok(())
    }

    fn write_frame(&mut self, frame: &Frame<'_>) -> Result<(), OutputError> {
        let (Some(field), d) = (self.x_field, self.dimension) else {
            return Ok(());
        };
        let x = &frame.values[field];
        let count = (x.len() / d.max(1)).max(1) as f64;
        let mut com = [0.0; 3];
        for p in x.chunks_exact(d) {
            for a in 0..d {
                com[a] += p[a];
            }
        }
        com.iter_mut().for_each(|c| *c /= count);
        self.samples.push(Sample {
            step: frame.diagnostics[0] as u64,
            com,
        });
        Ok(())
    }

    fn finish(&mut self, _: &Metrics) -> Result<(), OutputError> {
        Ok(())
    }
}

/// Runs the peer program for `n` cells and `steps` steps with `threads` threads.
fn run_taichi(
    python: &std::path::Path,
    program: &std::path::Path,
    n: usize,
    steps: u64,
    threads: usize,
) -> anyhow::Result<PeerRun> {
    let output = Command::new(python)
        .arg(program)
        .args(["--cells", &n.to_string(), "--steps", &steps.to_string()])
        .args(["--frames", &FRAMES.min(steps).to_string()])
        .args(["--threads", &threads.to_string()])
        .output()
        .with_context(|| format!("starting the peer with {}", python.display()))?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(5).collect();
        anyhow::bail!(
            "the Taichi peer failed ({}; does {} have the `taichi` package?): {}",
            output.status,
            python.display(),
            tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
        );
    }
    let stdout = String::from_utf8_lossy(&output.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .context("the Taichi peer printed no result")?;
    serde_json::from_str(line).context("reading the Taichi peer's result")
}

/// The largest distance between the centres of mass at the steps both recorded, and how
/// many steps that was.
fn trajectory_difference(ours: &[Sample], theirs: &[Sample]) -> (f64, usize) {
    let mut worst = 0.0f64;
    let mut matched = 0;
    for t in theirs {
        if let Some(o) = ours.iter().find(|o| o.step == t.step) {
            let d2: f64 = (0..3).map(|a| (o.com[a] - t.com[a]).powi(2)).sum();
            worst = worst.max(d2.sqrt());
            matched += 1;
        }
    }
    (worst, matched)
}

/// Runs `mpm bench --peer PEER`.
pub fn run(
    args: &BenchArgs,
    peer: &str,
    sizes: &[usize],
    scenes: &[&str],
    registry: &Registry,
) -> anyhow::Result<ExitStatus> {
    if peer != "taichi" {
        return Err(input_error!("--peer {peer}: the peer is `taichi`"));
    }
    if args.scene.is_some() && scenes != ["cube-drop"] {
        return Err(input_error!(
            "--peer taichi runs the cube-drop scene only; leave out --scene or give cube-drop"
        ));
    }
    if args.out.is_some() {
        return Err(input_error!(
            "--peer writes no result stores; leave out --out"
        ));
    }
    let threads = rayon::current_num_threads();
    let program = std::env::temp_dir().join(format!("mpm-bench-peer-{}.py", std::process::id()));
    std::fs::write(&program, TAICHI_PROGRAM)
        .with_context(|| format!("writing {}", program.display()))?;
    let result = compare(args, sizes, threads, &program, registry);
    std::fs::remove_file(&program).ok();
    let cases = result?;
    if args.json {
        let mut doc = header(threads, args.steps);
        doc["peer"] = json!("taichi");
        doc["cases"] = json!(cases);
        outln!("{}", serde_json::to_string_pretty(&doc)?)?;
    } else {
        out!("{}", table(&cases, threads))?;
        outln!(
            "{threads} threads, {} steps per case, {}",
            args.steps,
            today()
        )?;
    }
    if let Some(c) = cases.iter().find(|c| c.com_difference > c.com_tolerance) {
        anyhow::bail!(
            "at {}³ cells the peer's centre of mass is {:.3e} m from mpm's (more than {:.1e} m): \
             the two programs do not compute the same scene",
            c.cells,
            c.com_difference,
            c.com_tolerance
        );
    }
    Ok(if cases.iter().any(|c| c.mpm.outcome == "stopped") {
        ExitStatus::Stopped
    } else {
        ExitStatus::Success
    })
}

/// Both runs at every size, mpm's first.
fn compare(
    args: &BenchArgs,
    sizes: &[usize],
    threads: usize,
    program: &std::path::Path,
    registry: &Registry,
) -> anyhow::Result<Vec<PeerCase>> {
    let mut cases = Vec::new();
    for &n in sizes {
        eprintln!("bench: cube-drop at {n}³ cells, {} steps: mpm", args.steps);
        let mut doc = scene("cube-drop", n, args.steps);
        doc["output"]["frames"] = json!(FRAMES.min(args.steps));
        let mut sink = CentreOfMass::default();
        let mpm = run_scene_case(doc, "cube-drop", n, args.steps, registry, &mut sink)?;
        eprintln!(
            "bench: cube-drop at {n}³ cells, {} steps: taichi",
            args.steps
        );
        let peer = run_taichi(&args.python, program, n, args.steps, threads)?;
        if peer.particles != mpm.particles {
            anyhow::bail!(
                "the Taichi peer has {} particles at {n}³ cells, mpm {}",
                peer.particles,
                mpm.particles
            );
        }
        let (com_difference, com_samples) = trajectory_difference(&sink.samples, &peer.trajectory);
        if com_samples == 0 {
            anyhow::bail!("mpm and the Taichi peer recorded no centre of mass at the same step");
        }
        cases.push(PeerCase {
            cells: n,
            ratio: mpm.particle_steps_per_second / peer.particle_steps_per_second,
            com_tolerance: TOLERANCE_CELLS / n as f64,
            mpm,
            peer,
            com_difference,
            com_samples,
        });
    }
    Ok(cases)
}

/// The human output: one row per implementation and size, then the ratios.
fn table(cases: &[PeerCase], threads: usize) -> String {
    let mut s = String::from(
        "| implementation | cells | particles | steps | threads | wall s | M particle-steps/s |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for c in cases {
        for (name, particles, steps, wall, rate) in [
            (
                "mpm".to_string(),
                c.mpm.particles,
                c.mpm.steps,
                c.mpm.wall_seconds,
                c.mpm.particle_steps_per_second,
            ),
            (
                format!("taichi {}", c.peer.taichi),
                c.peer.particles,
                c.peer.steps,
                c.peer.wall_seconds,
                c.peer.particle_steps_per_second,
            ),
        ] {
            s += &format!(
                "| {name} | {}³ | {particles} | {steps} | {threads} | {wall:.2} | {:.2} |\n",
                c.cells,
                rate / 1e6
            );
        }
    }
    for c in cases {
        s += &format!(
            "{}³: mpm / taichi = {:.2}×; centre of mass apart by at most {:.2e} m over {} \
             frames (accepted: {:.1e} m)\n",
            c.cells, c.ratio, c.com_difference, c.com_samples, c.com_tolerance
        );
    }
    s
}
