//! Checkpoints and `mpm run --resume`: a run continued from its latest checkpoint writes
//! the same results, bit for bit, as the run never interrupted (frames, diagnostics, tables
//! and metrics but the wall-clock figures), for every solver mode and the state each
//! physics keeps: a reference's running error, Johnson–Cook's plastic state and damage,
//! temperatures and phase fractions, friction work, cohesive interface damage. One run is
//! killed (SIGKILL) in the middle and resumed.

use crate::common;

use common::{copy_dir, example, mpm, text};
use mpm_io::ResultStore;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Asserts that two stores hold the same numbers: every frame of every particle field, the
/// times, every diagnostic, every table and the metrics but wall-clock figures.
fn assert_same_results(a: &Path, b: &Path) {
    let (sa, sb) = (ResultStore::open(a).unwrap(), ResultStore::open(b).unwrap());
    let stages = sa.stages();
    assert_eq!(stages, sb.stages());
    for stage in &stages {
        assert_same_frames(
            &ResultStore::open_stage(a, Some(stage)).unwrap(),
            &ResultStore::open_stage(b, Some(stage)).unwrap(),
        );
    }
    if stages.is_empty() {
        assert_same_frames(&sa, &sb);
    }
    let metrics = |s: &ResultStore| {
        let mut m = s.attributes()["metrics"].clone();
        let object = m.as_object_mut().expect("metrics written");
        object.remove("wall_seconds");
        object.remove("particle_steps_per_second");
        object.remove("stage_seconds");
        object.remove("resumed_from_step");
        for stage in object
            .get_mut("stages")
            .and_then(|s| s.as_array_mut())
            .into_iter()
            .flatten()
        {
            stage.as_object_mut().unwrap().remove("wall_seconds");
        }
        m
    };
    assert_eq!(metrics(&sa), metrics(&sb), "metrics differ");
}

/// Asserts that two stores (or stages) hold the same frames, times and diagnostics.
fn assert_same_frames(sa: &ResultStore, sb: &ResultStore) {
    let (ta, tb) = (sa.times().unwrap(), sb.times().unwrap());
    assert_eq!(bits(&ta), bits(&tb), "output times differ");
    for name in mpm_core::output::FRAME_DIAGNOSTICS {
        let (x, y) = (sa.diagnostic(name).unwrap(), sb.diagnostic(name).unwrap());
        assert_eq!(bits(&x), bits(&y), "diagnostic {name} differs");
    }
    let fields = sa.fields().unwrap();
    assert_eq!(fields, sb.fields().unwrap());
    for field in &fields {
        for frame in 0..ta.len() as u64 {
            let (x, y) = (
                sa.frame(field, frame).unwrap().1,
                sb.frame(field, frame).unwrap().1,
            );
            assert!(
                bits(&x) == bits(&y),
                "{field} differs at frame {frame} (largest difference {:e})",
                x.iter()
                    .zip(&y)
                    .map(|(p, q)| (p - q).abs())
                    .fold(0.0, f64::max)
            );
        }
    }
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

/// The store's latest checkpoint attribute, if any (read from the file, as a watcher would).
fn checkpoint_of(store: &Path) -> Option<serde_json::Value> {
    let text = std::fs::read_to_string(store.join("zarr.json")).ok()?;
    let root: serde_json::Value = serde_json::from_str(&text).ok()?;
    root["attributes"].get("checkpoint").cloned()
}

/// Runs `example` with `overrides` and checkpoints every `every` steps to the end, resumes a
/// copy of its store from the latest checkpoint, and compares the two. Returns the
/// temporary folder and the uninterrupted store.
fn resumed_equals_uninterrupted(
    example_name: &str,
    overrides: &[&str],
    every: u64,
) -> (tempfile::TempDir, PathBuf) {
    let schedule = format!("output.checkpoint={{\"steps\":{every}}}");
    let mut all = vec![schedule.as_str()];
    all.extend_from_slice(overrides);
    resumed_with_checkpoints_equals_uninterrupted(example_name, &all)
}

/// As [`resumed_equals_uninterrupted`], with the checkpoint schedule among `overrides` (a
/// stage's own, say).
fn resumed_with_checkpoints_equals_uninterrupted(
    example_name: &str,
    overrides: &[&str],
) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let scene = example(example_name);
    let mut args = vec!["run", scene.to_str().unwrap(), "--out", "a", "-q"];
    for o in overrides {
        args.extend(["--set", o]);
    }
    let out = mpm(&args, dir.path());
    assert!(out.status.success(), "{}", text(&out));
    let name = example_name.trim_end_matches(".json");
    let a = dir.path().join("a").join(format!("{name}.zarr"));
    let pointer = checkpoint_of(&a).expect("a checkpoint was written");
    assert!(pointer["step"].as_u64().unwrap() > 0, "{pointer}");
    let b = dir.path().join("b.zarr");
    copy_dir(&a, &b);
    let out = mpm(&["run", "--resume", "b.zarr", "-q", "--json"], dir.path());
    assert!(out.status.success(), "{}", text(&out));
    let metrics: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(metrics["resumed_from_step"], pointer["step"]);
    assert_same_results(&a, &b);
    (dir, a)
}

#[test]
fn explicit_run_with_a_reference_resumes_bit_for_bit() {
    // The vibrating bar: the reference's error accumulates over frames, so the resumed run
    // must carry it over; checkpoints must not change the run either.
    let (dir, with_checkpoints) = resumed_equals_uninterrupted("vibrating-bar.json", &[], 100);
    let plain = mpm(
        &[
            "run",
            example("vibrating-bar.json").to_str().unwrap(),
            "--out",
            "plain",
            "-q",
        ],
        dir.path(),
    );
    assert!(plain.status.success(), "{}", text(&plain));
    assert_same_results(
        &dir.path().join("plain/vibrating-bar.zarr"),
        &with_checkpoints,
    );
}

#[test]
fn johnson_cook_state_and_damage_resume_bit_for_bit() {
    resumed_equals_uninterrupted("taylor-bar.json", &["solver.end_time=1e-5"], 40);
}

#[test]
fn heat_and_phase_change_resume_bit_for_bit() {
    resumed_equals_uninterrupted("stefan-two-phase.json", &[], 50);
}

#[test]
fn thermal_expansion_with_cohesive_interfaces_resumes_bit_for_bit() {
    // Free strain (the stress update's last applied free strain is solver state), contact
    // fields and bonded interfaces, particles reordered every few steps.
    resumed_equals_uninterrupted(
        "underfill-delamination.json",
        &["solver.end_time=5e-6", "output.frames=5"],
        250,
    );
}

#[test]
fn quasi_static_cure_resumes_bit_for_bit() {
    resumed_equals_uninterrupted("underfill-cure.json", &["solver.end_time=300"], 4);
}

#[test]
fn friction_contact_resumes_bit_for_bit() {
    resumed_equals_uninterrupted("two-disks-contact.json", &[], 100);
}

#[test]
fn implicit_static_steps_resume_bit_for_bit() {
    resumed_equals_uninterrupted("cantilever-static.json", &[], 7);
}

#[test]
fn incompressible_liquid_resumes_bit_for_bit() {
    resumed_equals_uninterrupted("dam-break.json", &[], 40);
}

#[test]
fn a_pressure_inlet_resumes_bit_for_bit() {
    // The particles a pressure inlet has let in come back from the checkpoint; the run goes
    // on letting them in strip by strip (0.06 s of the channel: 480 steps, about a dozen
    // particles in, before and after the checkpoint at step 400).
    resumed_equals_uninterrupted(
        "pressure-inlet-channel.json",
        &[
            "solver.end_time=0.06",
            r#"solver.mechanics={"incompressible":{"outflow":true}}"#,
        ],
        400,
    );
}

#[test]
fn liquid_entering_and_leaving_resumes_bit_for_bit() {
    // Resumed while the inlet still lets liquid in and the open right face lets it out.
    // Until stop 85 this splashing run (0.3 s, frames every 25 ms) stopped at the
    // example's cfl 0.5 and at 0.45, and ran at 0.4: G2P counted the particles that had
    // left, which have no mass (`liquid_inflow::particles_gone_through_an_open_face_or_
    // waiting_at_an_inlet_stop_nothing`). It now runs at the example's step.
    resumed_equals_uninterrupted(
        "liquid-inflow-tank.json",
        &[
            "solver.end_time=0.3",
            r#"domain.walls=[{"sides":["x-","y-"],"condition":"slip"}]"#,
            r#"solver.mechanics={"incompressible":{"outflow":true}}"#,
        ],
        50,
    );
}

#[test]
fn a_sealed_air_pocket_resumes_bit_for_bit() {
    // The U-tube with its sealed pocket: a checkpoint forgets the pocket's history in the
    // run that writes it as in the resumed one (both start the pocket again from the
    // ambient pressure and its measured volume).
    resumed_equals_uninterrupted("enclosed-air-u-tube.json", &["solver.end_time=0.15"], 150);
}

#[test]
fn a_staged_run_resumes_in_its_stage_bit_for_bit() {
    // The cure/cool/cycles chain with a checkpoint every 50 steps: the latest is in the
    // `cycles` stage; the resumed run writes that stage on and keeps the earlier stages'
    // summaries.
    let (_dir, store) = resumed_equals_uninterrupted(
        "underfill-cure-cycles.json",
        &["stages[2].changes.solver.end_time=6600"],
        50,
    );
    let pointer = checkpoint_of(&store).unwrap();
    assert!(pointer["step"].as_u64().unwrap() > 100, "{pointer}");
}

#[test]
fn a_crack_onset_before_the_checkpoint_is_kept_by_the_resumed_run() {
    // The chain with a brittle underfill whose damage is averaged over 50 µm: its first
    // particle fails at 5,700 s (step 145, in `cycles`), before the checkpoint at step 200,
    // so the resumed run reports the onset its checkpoint carried (`failure_watch.rs`)
    // and the averaged damage goes on as it would have.
    let plasticity = r#"materials.underfill.solid.plasticity={"flow_stress":{"yield_stress":7e7,"hardening_modulus":5e7,"hardening_exponent":0.3,"strain_rate_sensitivity":0,"thermal_softening_exponent":1,"room_temperature":298,"melt_temperature":473},"damage":{"d1":5e-5,"d2":1e-4,"d3":-2,"averaging_radius":5e-5},"failure_time":600}"#;
    let (_dir, store) =
        resumed_equals_uninterrupted("underfill-cure-cycles.json", &[plasticity], 200);
    let metrics = ResultStore::open(&store).unwrap().attributes()["metrics"].clone();
    let onset = &metrics["stages"][2]["damage"]["underfill"]["onset"];
    assert!(onset["time"].as_f64().unwrap() > 3000.0, "{onset}");
    assert_eq!(checkpoint_of(&store).unwrap()["step"], 200);
}

#[test]
fn a_creeping_solder_joint_and_its_fatigue_figures_resume_bit_for_bit() {
    // The process example (the fill cannot be checkpointed, so the checkpoints start in
    // `cycle-2`): the latest is in `cycle-3`; the bump's Anand state resumes, and so do
    // the work each stage began from and the life it gives.
    let (_dir, store) = resumed_with_checkpoints_equals_uninterrupted(
        "underfill-process-2d.json",
        &[r#"stages[4].changes.output.checkpoint={"steps":50}"#],
    );
    let pointer = checkpoint_of(&store).unwrap();
    assert_eq!(pointer["step"], 500, "the latest checkpoint is in cycle-3");
    let metrics = ResultStore::open(&store).unwrap().attributes()["metrics"].clone();
    let solder = &metrics["stages"][5]["fatigue"]["solder"];
    assert!(
        solder["cycles_to_crack"].as_f64().unwrap() > 0.0,
        "{solder}"
    );
}

#[test]
fn a_total_lagrangian_run_resumes_bit_for_bit() {
    // The reference configuration and its F come from the checkpoint; the stencils are
    // rebuilt from them.
    resumed_equals_uninterrupted("stretched-bar.json", &[], 100);
    resumed_equals_uninterrupted(
        "stretched-bar.json",
        &["solver.transfer=\"apic\"", "solver.scheme=\"usl\""],
        100,
    );
}

#[test]
fn a_cpdi_run_resumes_bit_for_bit() {
    // CPDI keeps nothing between steps but the particles: its stencils come from their
    // positions, F and half widths every step.
    let cpdi = ["solver.mechanics=\"dynamic\"", "solver.kernel=\"cpdi2\""];
    resumed_equals_uninterrupted("stretched-bar.json", &cpdi, 100);
    let apic = [
        cpdi[0],
        cpdi[1],
        "solver.transfer=\"apic\"",
        "solver.scheme=\"usl\"",
    ];
    resumed_equals_uninterrupted("stretched-bar.json", &apic, 100);
}

#[test]
fn a_loaded_run_resumes_bit_for_bit() {
    // The tip load's share per particle comes back from the checkpoint with the particles'
    // order; the peak reference's state too.
    let short = ["solver.end_time=0.4"];
    resumed_equals_uninterrupted("cantilever-tip-load.json", &short, 60);
    let updated = [short[0], "solver.mechanics=\"dynamic\""];
    resumed_equals_uninterrupted("cantilever-tip-load.json", &updated, 60);
}

#[test]
fn a_killed_run_resumes_bit_for_bit() {
    // The double cantilever beam: contact fields and cohesive interface nodes whose damage
    // grows. The run is killed as soon as its first checkpoint is on disk, while it goes on
    // writing frames; the resume drops the frames after the checkpoint and writes them again.
    let dir = tempfile::tempdir().unwrap();
    let scene = example("dcb.json");
    let args = |out: &str| {
        vec![
            "run".to_string(),
            scene.to_str().unwrap().to_string(),
            "--out".into(),
            out.into(),
            "-q".into(),
            "--set".into(),
            "solver.end_time=0.012".into(),
            "--set".into(),
            "output.checkpoint={\"steps\":300}".into(),
        ]
    };
    let whole = mpm(
        &args("whole").iter().map(String::as_str).collect::<Vec<_>>(),
        dir.path(),
    );
    assert!(whole.status.success(), "{}", text(&whole));
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_mpm"))
        .args(args("killed"))
        .current_dir(dir.path())
        .spawn()
        .unwrap();
    let store = dir.path().join("killed/dcb.zarr");
    let start = Instant::now();
    let mut killed_running = false;
    loop {
        if checkpoint_of(&store).is_some() {
            killed_running = child.try_wait().unwrap().is_none();
            child.kill().unwrap();
            break;
        }
        if child.try_wait().unwrap().is_some() || start.elapsed() > Duration::from_secs(120) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let status = child.wait().unwrap();
    assert!(
        killed_running,
        "the run ended before it could be killed ({status}); lengthen it"
    );
    let written = ResultStore::open(&store).unwrap().frame_count().unwrap();
    let at = checkpoint_of(&store).unwrap()["frames"].as_u64().unwrap();
    assert!(written >= at, "{written} frames, checkpoint after {at}");
    let out = mpm(&["run", "--resume", "killed/dcb.zarr", "-q"], dir.path());
    assert!(out.status.success(), "{}", text(&out));
    assert_same_results(&dir.path().join("whole/dcb.zarr"), &store);
}

#[test]
fn resume_refuses_what_it_cannot_continue() {
    let dir = tempfile::tempdir().unwrap();
    // A store without checkpoints.
    let out = mpm(
        &[
            "run",
            example("heat-slab.json").to_str().unwrap(),
            "--out",
            "r",
            "-q",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    let out = mpm(&["run", "--resume", "r/heat-slab.zarr"], dir.path());
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("no checkpoint"), "{}", text(&out));
    // Not a store at all.
    let out = mpm(&["run", "--resume", "nowhere.zarr"], dir.path());
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    // A scene and --resume together.
    let out = mpm(
        &["run", "x.json", "--resume", "r/heat-slab.zarr"],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    // The gap-averaged underfill keeps cell state a checkpoint does not hold: refused with
    // the path before anything runs.
    let out = mpm(
        &[
            "validate",
            example("capillary-gap.json").to_str().unwrap(),
            "--set",
            "output.checkpoint={\"steps\":10}",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(
        text(&out).contains("output.checkpoint") && text(&out).contains("underfill"),
        "{}",
        text(&out)
    );
    let out = mpm(
        &[
            "validate",
            example("heat-slab.json").to_str().unwrap(),
            "--set",
            "output.checkpoint={}",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("output.checkpoint"), "{}", text(&out));
}
