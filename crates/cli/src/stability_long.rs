//! `mpm check-stability --long`: long runs. The spinning disk of the suite (coarser) and the
//! vibrating bar run a fixed number of steps at a fixed time step with each transfer (PIC,
//! FLIP, APIC, MLS); the total mechanical energy and, for the free disk, the angular
//! momentum are recorded at every output frame relative to their start. A measurement, not
//! a pass/fail suite: `stability_long_plot` draws each scene as a picture.

use crate::exit_status::{ExitStatus, input_error};
use crate::stability::{bar_time_step, diagnostic_note, outcome_name, spinning_disk};
use anyhow::Context;
use mpm_core::output::{FRAME_DIAGNOSTICS, Frame, Metrics, OutputError, OutputSink, RunInfo};
use mpm_core::plugin::Registry;
use mpm_core::solver::{Control, Progress, RunError, preflight, run_scene};
use serde::Serialize;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Steps of a default long run.
pub const DEFAULT_STEPS: u64 = 100_000;
/// The most steps `--steps` accepts.
pub const MAX_STEPS: u64 = 100_000_000;
/// The most output frames (samples of the series) of a run.
pub const MAX_SAMPLES: u64 = 500;
/// The transfers each scene runs with: `mls` is APIC with the MLS-MPM force.
pub const TRANSFERS: [&str; 4] = ["pic", "flip", "apic", "mls"];

/// One scene of the long runs.
pub struct LongCase {
    /// Short name (the picture is `<name>.png`).
    pub name: &'static str,
    /// What it is, with its size and time step.
    pub what: &'static str,
    /// The scene, with its fixed `solver.dt`; the end time is set per run.
    pub scene: Value,
    /// Whether nothing acts from outside, so that angular momentum is recorded.
    pub free: bool,
}

/// The long runs' scenes: the suite's spinning disk with a cell of 0.04 m (the suite's is
/// 0.02 m) and the vibrating bar at half its stable step.
pub fn cases() -> Vec<LongCase> {
    let mut disk = spinning_disk();
    disk["domain"]["cell_size"] = json!(0.04);
    // The stable step dx / (c + max |v|) is 0.04 / (11.6 + 0.6) s = 3.3e-3 s; 0.3 of it.
    disk["solver"]["dt"] = json!(1e-3);
    if let Some(solver) = disk["solver"].as_object_mut() {
        solver.remove("cfl");
    }
    let bar = bar_time_step(0.5, 1.0);
    vec![
        LongCase {
            name: "disk",
            what: "free elastic disk spinning at 2 rad/s (radius 0.3 m, cell 0.04 m, dt 1e-3 s)",
            scene: disk,
            free: true,
        },
        LongCase {
            name: "bar",
            what: "vibrating bar (examples/vibrating-bar.json, period 0.4 s, dt 2.495e-3 s)",
            scene: bar,
            free: false,
        },
    ]
}

/// One long run: a scene with one transfer, and its series.
#[derive(Clone, Debug, Serialize)]
pub struct LongRun {
    /// The scene's name.
    pub case: String,
    /// `pic`, `flip` (blend 0.99), `apic` or `mls`.
    pub transfer: String,
    /// The fixed time step, s.
    pub dt: f64,
    /// Steps taken.
    pub steps: u64,
    /// Particles.
    pub particles: usize,
    /// `finished`, `stopped`, `cancelled`, `refused`, `invalid` or `error`.
    pub outcome: String,
    /// The diagnostic or refusal, if any.
    pub note: String,
    /// Wall seconds of the run (setup excluded).
    pub wall_seconds: f64,
    /// The total mechanical energy (kinetic + strain) at the start, J/m.
    pub energy0: f64,
    /// The angular momentum at the start (about the origin; the disk's linear momentum is
    /// zero, so also about its centre), where recorded.
    pub angular_momentum0: Option<f64>,
    /// Simulated time of each sample, s.
    pub time: Vec<f64>,
    /// (E(t) − E(0)) / E(0) at each sample.
    pub energy_change: Vec<f64>,
    /// (L(t) − L(0)) / L(0) at each sample, where recorded (the free disk).
    pub angular_momentum_change: Option<Vec<f64>>,
}

impl LongRun {
    /// The last relative energy change (NaN without samples).
    pub fn final_energy_change(&self) -> f64 {
        self.energy_change.last().copied().unwrap_or(f64::NAN)
    }

    /// The last relative angular momentum change, where recorded.
    pub fn final_angular_momentum_change(&self) -> Option<f64> {
        self.angular_momentum_change
            .as_ref()
            .map(|l| l.last().copied().unwrap_or(f64::NAN))
    }
}

/// A sink keeping, per frame, the time, the total energy and the angular momentum.
#[derive(Default)]
struct SeriesSink {
    samples: Vec<[f64; 3]>,
}

fn diagnostic_index(name: &str) -> usize {
    FRAME_DIAGNOSTICS
        .iter()
        .position(|d| *d == name)
        .expect("a frame diagnostic")
}

impl OutputSink for SeriesSink {
    fn begin(&mut self, _: &RunInfo<'_>) -> Result<(), OutputError> {
        Ok(())
    }
    fn write_frame(&mut self, frame: &Frame<'_>) -> Result<(), OutputError> {
        let d = frame.diagnostics;
        self.samples.push([
            frame.time,
            d[diagnostic_index("total_energy")],
            d[diagnostic_index("angular_momentum")],
        ]);
        Ok(())
    }
    fn finish(&mut self, _: &Metrics) -> Result<(), OutputError> {
        Ok(())
    }
}

/// The number of output frames of a run of `steps` steps: the largest divisor of `steps`
/// up to [`MAX_SAMPLES`], so that every frame falls on a step and the run takes exactly
/// `steps` steps.
pub fn frames_for(steps: u64) -> u64 {
    (1..=MAX_SAMPLES.min(steps))
        .rev()
        .find(|d| steps.is_multiple_of(*d))
        .unwrap_or(1)
}

/// `scene` with `transfer` (`mls`: APIC with the MLS-MPM force), `steps` fixed steps and
/// a frame every `steps / frames_for(steps)` steps.
fn long_scene(case: &LongCase, transfer: &str, steps: u64) -> Value {
    let mut s = case.scene.clone();
    let dt = s["solver"]["dt"].as_f64().expect("a fixed dt");
    let solver = &mut s["solver"];
    if transfer == "mls" {
        solver["transfer"] = json!("apic");
        solver["mls"] = json!(true);
    } else {
        solver["transfer"] = json!(transfer);
    }
    solver["end_time"] = json!(steps as f64 * dt);
    s["output"] = json!({"frames": frames_for(steps), "fields": ["x"]});
    s
}

/// Runs `case` with `transfer` for `steps` steps and keeps its series.
pub fn run_long(case: &LongCase, transfer: &str, steps: u64, registry: &Registry) -> LongRun {
    let scene = long_scene(case, transfer, steps);
    let mut run = LongRun {
        case: case.name.into(),
        transfer: transfer.into(),
        dt: scene["solver"]["dt"].as_f64().unwrap_or(f64::NAN),
        steps: 0,
        particles: 0,
        outcome: String::new(),
        note: String::new(),
        wall_seconds: 0.0,
        energy0: f64::NAN,
        angular_momentum0: None,
        time: Vec::new(),
        energy_change: Vec::new(),
        angular_momentum_change: None,
    };
    let scene = match mpm_core::scene::parse_scene_value(scene, registry, Path::new(".")) {
        Ok(s) => s,
        Err(e) => {
            run.outcome = "invalid".into();
            run.note = e.to_string();
            return run;
        }
    };
    if let Err(RunError::Refused { path, message }) = preflight(&scene) {
        run.outcome = "refused".into();
        run.note = format!("{path}: {message}");
        return run;
    }
    let mut sink = SeriesSink::default();
    let start = Instant::now();
    let metrics = match run_scene(&scene, &mut sink, &mut |_: &Progress| Control::Continue) {
        Ok(m) => m,
        Err(e) => {
            run.outcome = "error".into();
            run.note = e.to_string();
            return run;
        }
    };
    run.wall_seconds = start.elapsed().as_secs_f64();
    run.steps = metrics.steps;
    run.particles = metrics.particles;
    run.outcome = outcome_name(&metrics).into();
    run.note = diagnostic_note(&metrics);
    let Some(&[_, e0, l0]) = sink.samples.first() else {
        return run;
    };
    run.energy0 = e0;
    run.time = sink.samples.iter().map(|s| s[0]).collect();
    run.energy_change = sink.samples.iter().map(|s| (s[1] - e0) / e0).collect();
    if case.free {
        run.angular_momentum0 = Some(l0);
        run.angular_momentum_change = Some(sink.samples.iter().map(|s| (s[2] - l0) / l0).collect());
    }
    run
}

/// The runs as a Markdown table.
pub fn table(runs: &[LongRun]) -> String {
    let mut out = String::from(
        "| scene | transfer | outcome | steps | dt s | particles | wall s | energy change | angular momentum change | note |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in runs {
        out += &format!(
            "| {} | {} | {} | {} | {:.4e} | {} | {:.1} | {:+.3e} | {} | {} |\n",
            r.case,
            r.transfer,
            r.outcome,
            r.steps,
            r.dt,
            r.particles,
            r.wall_seconds,
            r.final_energy_change(),
            r.final_angular_momentum_change()
                .map_or("—".into(), |c| format!("{c:+.3e}")),
            r.note.chars().take(90).collect::<String>()
        );
    }
    out
}

/// Checks `--steps`: at least 1, at most [`MAX_STEPS`].
pub fn check_steps(steps: u64) -> Result<(), String> {
    if (1..=MAX_STEPS).contains(&steps) {
        Ok(())
    } else {
        Err(format!(
            "--steps {steps}: give a number of steps from 1 to {MAX_STEPS}"
        ))
    }
}

/// `mpm check-stability --long`: runs every long case (those whose name contains `only`)
/// with every transfer for `steps` steps, prints the table, writes `<plot_dir>/<case>.png`
/// and, with `json`, every run with its series. Bad options are invalid input (2); a run
/// that failed otherwise than by stopping itself, or a file that cannot be written, is a
/// failure (1); else success, whatever the runs did.
pub(crate) fn check_stability_long(
    only: Option<String>,
    json: Option<PathBuf>,
    steps: Option<u64>,
    plot_dir: PathBuf,
    registry: &Registry,
) -> anyhow::Result<ExitStatus> {
    let steps = steps.unwrap_or(DEFAULT_STEPS);
    check_steps(steps).map_err(|e| input_error!("{e}"))?;
    let all = cases();
    let chosen = crate::stability::choose_cases(&all, |c| c.name, only.as_deref(), "long case")?;
    std::fs::create_dir_all(&plot_dir)
        .with_context(|| format!("cannot create `{}`", plot_dir.display()))?;
    let mut runs = Vec::new();
    for case in chosen {
        eprintln!("{}: {}, {steps} steps", case.name, case.what);
        let first = runs.len();
        for transfer in TRANSFERS {
            let run = run_long(case, transfer, steps, registry);
            eprintln!(
                "  {transfer}: {} after {} steps, {:.1} s, energy {:+.3e}{}",
                run.outcome,
                run.steps,
                run.wall_seconds,
                run.final_energy_change(),
                run.final_angular_momentum_change()
                    .map_or(String::new(), |l| format!(", angular momentum {l:+.3e}"))
            );
            runs.push(run);
        }
        let png = plot_dir.join(format!("{}.png", case.name));
        crate::stability_long_plot::draw(&png, case, &runs[first..])?;
        crate::stdout::write(format_args!("picture: {}\n", png.display()))?;
    }
    crate::stdout::write(format_args!("{}", table(&runs)))?;
    if let Some(path) = json {
        std::fs::write(&path, serde_json::to_string_pretty(&runs)?)
            .with_context(|| format!("cannot write `{}`", path.display()))?;
    }
    let errors: Vec<&LongRun> = runs
        .iter()
        .filter(|r| matches!(r.outcome.as_str(), "error" | "invalid" | "cancelled"))
        .collect();
    for r in &errors {
        eprintln!("{} {}: {}: {}", r.case, r.transfer, r.outcome, r.note);
    }
    Ok(if errors.is_empty() {
        ExitStatus::Success
    } else {
        ExitStatus::Failure
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_divide_the_steps() {
        assert_eq!(frames_for(100_000), 500);
        assert_eq!(frames_for(2000), 500);
        assert_eq!(frames_for(300), 300);
        assert_eq!(frames_for(1009), 1);
        assert_eq!(frames_for(1), 1);
    }

    #[test]
    fn bad_steps_are_refused() {
        assert!(check_steps(1).is_ok());
        assert!(check_steps(0).unwrap_err().contains("--steps 0"));
        assert!(check_steps(MAX_STEPS + 1).is_err());
    }

    #[test]
    fn a_long_scene_has_the_transfer_and_exactly_the_steps() {
        let case = &cases()[0];
        let s = long_scene(case, "mls", 2000);
        assert_eq!(s["solver"]["transfer"], "apic");
        assert_eq!(s["solver"]["mls"], true);
        let dt = s["solver"]["dt"].as_f64().unwrap();
        assert!((s["solver"]["end_time"].as_f64().unwrap() - 2000.0 * dt).abs() < 1e-12);
        assert_eq!(s["output"]["frames"], 500);
    }
}
