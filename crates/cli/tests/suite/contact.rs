//! Contact between bodies (multi-velocity-field MPM): the two disks touch when their
//! surfaces meet, not when their kernels overlap; a block on an inclined elastic slab
//! slides with a = g(sin θ − μ cos θ) above the friction angle and sticks below it; the
//! contact section is checked with JSON paths.

use crate::common;

use common::*;
use mpm_core::output::{Frame, Metrics, Outcome, OutputError, OutputSink, RunInfo};
use mpm_core::scene::ValidatedScene;
use mpm_core::solver::{Control, Progress, run_scene};
use serde_json::{Value, json};

/// Keeps the time and the particle velocities (output order) of every frame.
#[derive(Default)]
struct Frames {
    velocity: usize,
    times: Vec<f64>,
    kinetic: Vec<f64>,
    velocities: Vec<Vec<f64>>,
}

impl OutputSink for Frames {
    fn begin(&mut self, info: &RunInfo<'_>) -> Result<(), OutputError> {
        self.velocity = info
            .fields
            .iter()
            .position(|f| f.name == "v")
            .ok_or_else(|| OutputError("the scene must write v".into()))?;
        Ok(())
    }
    fn write_frame(&mut self, frame: &Frame<'_>) -> Result<(), OutputError> {
        self.times.push(frame.time);
        self.kinetic.push(frame.diagnostics[2]);
        self.velocities.push(frame.values[self.velocity].clone());
        Ok(())
    }
    fn finish(&mut self, _: &Metrics) -> Result<(), OutputError> {
        Ok(())
    }
}

fn run_frames(scene: &ValidatedScene) -> (Metrics, Frames) {
    let mut frames = Frames::default();
    let m = run_scene(scene, &mut frames, &mut |_: &Progress| Control::Continue).expect("run");
    (m, frames)
}

/// Particles of body `b`, as a range in output order.
fn body_range(scene: &ValidatedScene, b: usize) -> std::ops::Range<usize> {
    let start: usize = scene.bodies[..b].iter().map(|x| x.volumes.len()).sum();
    start..start + scene.bodies[b].volumes.len()
}

/// Mean velocity component `axis` of the particles in `range` (2D) in every frame.
fn mean_velocity(frames: &Frames, range: &std::ops::Range<usize>, axis: usize) -> Vec<f64> {
    frames
        .velocities
        .iter()
        .map(|v| range.clone().map(|p| v[2 * p + axis]).sum::<f64>() / range.len() as f64)
        .collect()
}

/// The time contact first acted (the first row of the `contact` table).
fn contact_start(m: &Metrics) -> f64 {
    m.tables.get("contact").expect("contact table").rows[0][0]
}

#[test]
fn disks_touch_when_their_surfaces_meet_and_rebound() {
    let scene = load_example("two-disks-contact.json", &[]);
    let (m, frames) = run_frames(&scene);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    // Centres 0.5·√2 apart, radii 0.2, closing speed 0.2·√2 m/s.
    let speed = 0.2 * 2f64.sqrt();
    let geometric = (0.5 * 2f64.sqrt() - 0.4) / speed;
    let start = contact_start(&m);
    let cell_time = 0.025 / speed;
    println!(
        "contact at {start:.4} s, geometric {geometric:.4} s, one cell = {cell_time:.4} s; table {:?}",
        m.tables["contact"].rows
    );
    // Within one cell of travel at the closing speed (the issue's tolerance).
    assert!(
        (start - geometric).abs() < cell_time,
        "contact at {start} s, geometric {geometric} s"
    );
    // Untouched before: every particle keeps its initial velocity until then.
    let lower = body_range(&scene, 0);
    let vx = mean_velocity(&frames, &lower, 0);
    for (t, v) in frames.times.iter().zip(&vx) {
        if *t < start {
            assert!((v - 0.1).abs() < 1e-9, "lower disk at {t} s: vx {v}");
        }
    }
    // Rebound: the lower disk moves back, momentum stays zero.
    let last = *vx.last().unwrap();
    assert!(last < -0.05, "lower disk after the rebound: vx {last}");
    assert!(m.max_momentum < 1e-9, "momentum {}", m.max_momentum);
    let kinetic = frames.kinetic.last().unwrap() / frames.kinetic[0];
    println!(
        "kinetic energy after the rebound / before: {kinetic:.3}; energy drift {:.3}",
        m.energy_drift
    );
    // Measured 0.77 (the shared-field run of two-disks.json loses 14.7% of its energy).
    assert!(kinetic > 0.7, "kinetic energy after the rebound {kinetic}");
}

#[test]
fn every_kernel_and_transfer_and_each_law_keeps_the_disks_apart_until_they_touch() {
    let speed = 0.2 * 2f64.sqrt();
    let geometric = (0.5 * 2f64.sqrt() - 0.4) / speed;
    let cell_time = 0.025 / speed;
    let mut cases: Vec<Vec<String>> = Vec::new();
    // Not the linear kernel: the two disks invert particles with it (det F <= 0 by 1.6 s)
    // with or without contact, from its cell-crossing error.
    for kernel in ["gimp", "bspline2", "bspline3"] {
        for transfer in ["pic", "flip", "apic"] {
            cases.push(vec![
                format!("solver.kernel={kernel}"),
                format!("solver.transfer={transfer}"),
            ]);
        }
    }
    cases.push(vec!["solver.mls=true".into()]);
    cases.push(vec!["contact.pairs[0].law=no_slip".into()]);
    cases.push(vec![
        "contact.pairs[0].law={\"friction\": {\"coefficient\": 0.5}}".into(),
    ]);
    for sets in cases {
        let mut o = sets.clone();
        o.push("solver.end_time=1.6".into());
        let m = run(&load(&example("two-disks-contact.json"), &o));
        assert_eq!(
            m.outcome,
            Some(Outcome::Finished),
            "{sets:?}: {:?}",
            m.diagnostic
        );
        let start = contact_start(&m);
        println!("{sets:?}: contact at {start:.4} s (geometric {geometric:.4} s)");
        // One cell of travel at the closing speed.
        assert!(
            (start - geometric).abs() < cell_time,
            "{sets:?}: contact at {start} s"
        );
        assert!(
            m.max_momentum < 1e-9,
            "{sets:?}: momentum {}",
            m.max_momentum
        );
    }
}

#[test]
fn three_dimensional_spheres_touch_when_their_surfaces_meet() {
    let scene = json!({
        "name": "spheres", "dimension": 3,
        "domain": {"min": [0, 0, 0], "max": [1, 0.5, 0.5], "cell_size": 0.05},
        "solver": {"end_time": 0.5},
        "materials": {"rubber": {"type": "neo_hookean", "density": 1000.0,
                                 "youngs_modulus": 1e5, "poisson_ratio": 0.3}},
        "bodies": [
            {"name": "a", "material": "rubber",
             "shape": {"sphere": {"center": [0.3, 0.25, 0.25], "radius": 0.15}},
             "velocity": {"uniform": [1.0, 0, 0]}},
            {"name": "b", "material": "rubber",
             "shape": {"sphere": {"center": [0.7, 0.25, 0.25], "radius": 0.15}},
             "velocity": {"uniform": [-1.0, 0, 0]}}],
        "contact": {"pairs": [{"bodies": ["a", "b"], "law": "frictionless"}]},
        "output": {"frames": 5, "fields": ["x"]}
    });
    let dir = tempfile::tempdir().unwrap();
    let m = run(&load(&write_scene(dir.path(), "spheres.json", &scene), &[]));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    // Gap 0.1 m closed at 2 m/s: 0.05 s; one cell of travel is 0.025 s.
    let start = contact_start(&m);
    println!("3D: contact at {start:.4} s (geometric 0.05 s)");
    assert!((start - 0.05).abs() < 0.025, "contact at {start} s");
    assert!(m.max_momentum < 1e-9, "momentum {}", m.max_momentum);
}

#[test]
fn shared_field_disks_interact_before_their_surfaces_meet() {
    // The same disks without contact: one shared field couples them early (the problem
    // the contact section solves). The lower disk slows before the geometric time.
    let scene = load_example("two-disks.json", &[]);
    let (_, frames) = run_frames(&scene);
    let speed = 0.2 * 2f64.sqrt();
    let geometric = (0.5 * 2f64.sqrt() - 0.4) / speed;
    let vx = mean_velocity(&frames, &body_range(&scene, 0), 0);
    let early = frames
        .times
        .iter()
        .zip(&vx)
        .find(|(_, v)| (*v - 0.1).abs() > 1e-6)
        .map(|(t, _)| *t)
        .unwrap();
    println!("shared field: lower disk slows at {early} s, geometric {geometric} s");
    assert!(early < geometric);
}

/// A block on an elastic slab held at its base, gravity tilted by `angle` degrees, Coulomb
/// friction `mu` between them.
fn incline(angle: f64, mu: f64) -> Value {
    incline_scene(angle, json!({"friction": {"coefficient": mu}}), &["v"])
}

/// Least-squares slope of `y` against `t` over `t ≥ from`.
fn slope(t: &[f64], y: &[f64], from: f64) -> f64 {
    let pts: Vec<(f64, f64)> = t
        .iter()
        .zip(y)
        .filter(|(t, _)| **t >= from)
        .map(|(a, b)| (*a, *b))
        .collect();
    let n = pts.len() as f64;
    let (mt, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let cov: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - my)).sum();
    let var: f64 = pts.iter().map(|p| (p.0 - mt) * (p.0 - mt)).sum();
    cov / var
}

fn block_acceleration(angle: f64, mu: f64) -> (f64, Vec<f64>) {
    let (a, vx, _, _) = block_run(angle, mu);
    (a, vx)
}

/// The block's acceleration and velocities, the metrics and the frame times.
fn block_run(angle: f64, mu: f64) -> (f64, Vec<f64>, Metrics, Vec<f64>) {
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "incline.json", &incline(angle, mu));
    let scene = load(&path, &[]);
    let (m, frames) = run_frames(&scene);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let vx = mean_velocity(&frames, &body_range(&scene, 1), 0);
    (slope(&frames.times, &vx, 0.1), vx, m, frames.times)
}

#[test]
fn block_slides_down_the_incline_with_coulomb_friction() {
    let (angle, mu) = (30.0f64, 0.3);
    let expected = 9.81 * (angle.to_radians().sin() - mu * angle.to_radians().cos());
    let (a, vx, m, times) = block_run(angle, mu);
    println!("sliding: a = {a:.4} m/s², g(sin θ − μ cos θ) = {expected:.4} m/s²; v {vx:?}");
    // Friction work: μ m g cos θ times the distance slid (trapezoid rule over the frames);
    // the block is 0.2 × 0.08 m² of 1000 kg/m³ per metre of thickness.
    let distance: f64 = times
        .windows(2)
        .zip(vx.windows(2))
        .map(|(t, v)| 0.5 * (v[0] + v[1]) * (t[1] - t[0]))
        .sum();
    let expected_work = mu * 16.0 * 9.81 * angle.to_radians().cos() * distance;
    let work = m.physics["contact.friction_work"];
    println!(
        "friction work {work:.4} J, μ m g cos θ · distance = {expected_work:.4} J; energy drift {:.2e}",
        m.energy_drift
    );
    // 2% (measured 0.4%); with the friction work counted as work done on the block the
    // energy balance closes to 1% (measured 0.14%).
    assert!(
        (work - expected_work).abs() < 0.02 * expected_work,
        "friction work {work} J, expected {expected_work} J"
    );
    assert!(
        m.energy_drift.abs() < 0.01,
        "energy drift {}",
        m.energy_drift
    );
    // 2% of the expected acceleration (measured: 0.03%).
    assert!(
        (a - expected).abs() < 0.02 * expected,
        "a = {a}, expected {expected}"
    );
}

#[test]
fn block_slides_freely_without_friction() {
    let angle = 30.0f64;
    let expected = 9.81 * angle.to_radians().sin();
    let (a, _) = block_acceleration(angle, 0.0);
    println!("frictionless: a = {a:.4} m/s², g sin θ = {expected:.4} m/s²");
    // 2% of g sin θ (measured: 0.05%).
    assert!(
        (a - expected).abs() < 0.02 * expected,
        "a = {a}, expected {expected}"
    );
}

#[test]
fn block_sticks_below_the_friction_angle() {
    let (angle, mu) = (30.0f64, 0.8);
    let (a, vx) = block_acceleration(angle, mu);
    let free = 9.81 * angle.to_radians().sin();
    println!("sticking: a = {a:.5} m/s² (free sliding would be {free:.3}); v {vx:?}");
    // Stuck: below 1% of the frictionless acceleration. The block creeps at up to about
    // 0.03 m/s in the first 0.03 s while the normal contact builds up, then rests.
    assert!(a.abs() < 0.01 * free, "a = {a}");
    assert!(vx.iter().all(|v| v.abs() < 0.05), "block velocity {vx:?}");
    assert!(
        vx[5..].iter().all(|v| v.abs() < 0.01),
        "block velocity {vx:?}"
    );
}

#[test]
fn contact_section_problems_name_their_paths() {
    let issues = invalid_example(
        "two-disks-contact.json",
        &["contact.pairs[0].bodies[1]=\"x\"", "solver.scheme=musl"],
    );
    let joined = issues.join("\n");
    assert!(
        joined.contains("contact.pairs[0].bodies[1]: no body named \"x\""),
        "{joined}"
    );
    assert!(
        joined.contains("solver.scheme: contact between bodies needs"),
        "{joined}"
    );
    let issues = invalid_example(
        "two-disks-contact.json",
        &["contact.pairs[0].law={\"friction\": {\"coefficient\": -1}}"],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("contact.pairs[0].law.friction.coefficient:")),
        "{issues:?}"
    );
}
