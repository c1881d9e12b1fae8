//! End-to-end tests of `mpm rom`: training on real result stores, reduced runs written as
//! real Zarr stores, their error against full-order runs, and the refusals of bad models
//! and scenes. The case is `examples/rom-tower-2d.json`: an elastic wall clamped at its
//! foot and led sideways at its top at a velocity `obstacles[0].velocity`.

use crate::common;

use common::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

fn ok(args: &[&str], dir: &Path) -> String {
    let o = mpm(args, dir);
    let t = text(&o);
    assert!(o.status.success(), "mpm {args:?} failed: {t}");
    t
}

/// Training runs at top velocities 0.2, -0.1 and 0.05 m/s, the full-order runs at the
/// held-out 0.15 m/s (2 and 3 particles per cell per axis), and a linear model of 4 modes.
struct Fixture {
    dir: tempfile::TempDir,
    scene: PathBuf,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let scene = example("rom-tower-2d.json");
        let s = scene.to_str().unwrap();
        for (name, v) in [("a", "[0.2,0]"), ("b", "[-0.1,0]"), ("c", "[0.05,0]")] {
            ok(
                &[
                    "run",
                    s,
                    "--out",
                    "train",
                    "-q",
                    "--set",
                    &format!("name=wall-{name}"),
                    "--set",
                    &format!("obstacles[0].velocity={v}"),
                ],
                dir.path(),
            );
        }
        ok(&["run", s, "--out", "full", "-q"], dir.path());
        ok(
            &[
                "run",
                s,
                "--out",
                "full-fine",
                "-q",
                "--set",
                "bodies[0].particles_per_cell=3",
            ],
            dir.path(),
        );
        ok(
            &[
                "rom",
                "train",
                "--runs",
                "train",
                "--latent",
                "4",
                "--out",
                "model.safetensors",
            ],
            dir.path(),
        );
        Fixture { dir, scene }
    })
}

/// Runs the reduced model (samples anywhere in the body: this wall is only four cells
/// thick, and drawing samples from its two inner columns only, the default, gave 5-10 times
/// the error here) and returns (position error, error relative to displacement)
/// against `reference` as `mpm rom run --compare --json` reports them.
fn reduced(extra: &[&str], samples: &str, out: &str, reference: &str) -> (f64, f64) {
    let f = fixture();
    let s = f.scene.to_str().unwrap();
    let mut args = vec![
        "rom",
        "run",
        s,
        "--model",
        "model.safetensors",
        "--samples",
        samples,
        "--out",
        out,
        "--compare",
        reference,
        "--json",
        "-q",
        "--surface-samples",
    ];
    args.extend_from_slice(extra);
    let t = ok(&args, f.dir.path());
    let v: serde_json::Value = serde_json::from_str(&t).unwrap_or_else(|e| panic!("{e}: {t}"));
    assert_eq!(v["metrics"]["outcome"], "finished", "{t}");
    (
        v["error"]["relative"].as_f64().unwrap(),
        v["error"]["relative_to_displacement"].as_f64().unwrap(),
    )
}

#[test]
fn training_reports_the_pod_and_the_fit() {
    let f = fixture();
    let model = mpm_rom::Model::load(&f.dir.path().join("model.safetensors")).unwrap();
    let t = &model.info.training;
    assert_eq!(t.snapshots, 3 * 13, "3 runs of 13 frames");
    assert!(t.pod_captured > 0.999, "4 modes capture {}", t.pod_captured);
    // The B-spline mode fields reproduce the snapshots' projection to ~1% of the motion.
    assert!(t.fit_error < 0.02, "training misfit {}", t.fit_error);
}

#[test]
fn linear_model_reproduces_a_training_run() {
    // Every particle sampled: the reduced run differs from the training run only by the
    // 4-mode truncation and by F taken from the map. Measured 0.23% of the positions (3.0%
    // of the displacement); bound 0.5% and 6%.
    let (pos, disp) = reduced(
        &[
            "--set",
            "name=wall-a",
            "--set",
            "obstacles[0].velocity=[0.2,0]",
        ],
        "256",
        "reproduce",
        "train/wall-a.zarr",
    );
    assert!(
        pos < 5e-3 && disp < 0.06,
        "position {pos}, displacement {disp}"
    );
}

#[test]
fn held_out_velocity_stays_within_the_bound() {
    // 16 of 256 particles sampled at the held-out top velocity 0.15 m/s. Measured 0.30% of
    // the positions (5.3% of the displacement); bound 1% and 10%.
    let (pos, disp) = reduced(&[], "16", "held-out", "full/rom-tower-2d.zarr");
    assert!(
        pos < 1e-2 && disp < 0.10,
        "position {pos}, displacement {disp}"
    ); // The velocities written (∂g/∂q · q̇) follow the full run's: RMS over every frame within
    // 20% of the full run's (measured: 3.3% above).
    let rms = |store: &str| {
        let s = mpm_io::ResultStore::open(fixture().dir.path().join(store)).unwrap();
        let (mut sum, mut count) = (0.0, 0usize);
        for k in 1..s.frame_count().unwrap() {
            let (_, v) = s.frame("v", k).unwrap();
            sum += v.iter().map(|x| x * x).sum::<f64>();
            count += v.len();
        }
        (sum / count as f64).sqrt()
    };
    let reduced_v = rms("held-out/rom-tower-2d.zarr");
    let full_v = rms("full/rom-tower-2d.zarr");
    println!("RMS velocity: reduced {reduced_v}, full {full_v}");
    assert!(
        (reduced_v / full_v - 1.0).abs() < 0.2,
        "RMS velocity {reduced_v} against {full_v}"
    );
}

#[test]
fn super_resolution_runs_on_a_finer_particle_set() {
    // The model was trained at 2 particles per cell per axis; the map is continuous in X, so
    // the reduced run writes 3 per axis, compared with a full-order run at 3 per axis.
    // Measured 0.40% of the positions (6.9% of the displacement); bound 1% and 15%.
    let (pos, disp) = reduced(
        &["--set", "bodies[0].particles_per_cell=3"],
        "32",
        "fine",
        "full-fine/rom-tower-2d.zarr",
    );
    let store =
        mpm_io::ResultStore::open(fixture().dir.path().join("fine/rom-tower-2d.zarr")).unwrap();
    assert_eq!(store.attributes()["particles"], 4 * 16 * 9);
    assert!(
        pos < 1e-2 && disp < 0.15,
        "position {pos}, displacement {disp}"
    );
}

#[test]
fn bad_models_and_mismatched_scenes_are_refused() {
    let f = fixture();
    let d = f.dir.path();
    let s = f.scene.to_str().unwrap();
    let refused = |args: Vec<String>, expect: &str| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = mpm(&args, d);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {t}");
        assert!(t.contains(expect), "{args:?}: expected `{expect}` in: {t}");
    };
    std::fs::write(d.join("garbage.safetensors"), b"not a model").unwrap();
    let strs = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<String>>();
    let run = |model: &str, extra: &[&str]| {
        let mut v = vec!["rom", "run", s, "--model", model, "--out", "refused"];
        v.extend_from_slice(extra);
        strs(&v)
    };
    refused(run("garbage.safetensors", &[]), "not a safetensors file");
    refused(
        run("model.safetensors", &["--set", "domain.cell_size=0.04"]),
        "domain.cell_size",
    );
    refused(
        run("model.safetensors", &["--set", "solver.kernel=linear"]),
        "solver.kernel",
    );
    refused(run("model.safetensors", &["--samples", "1"]), "--samples 1");
    refused(
        run(
            "model.safetensors",
            &["--set", "bodies[0].shape.box.max=[0.5,0.8]"],
        ),
        "outside the region the model was trained on",
    );
    // A material with per-particle history (Johnson-Cook plasticity, from the Taylor bar).
    let taylor: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(example("taylor-bar.json")).unwrap())
            .unwrap();
    let plastic = format!("materials.rubber={}", taylor["materials"]["steel"]);
    refused(
        run("model.safetensors", &["--set", &plastic]),
        "materials.rubber",
    );
    // A 3D scene against the 2D model.
    let cube = example("cube-drop.json");
    refused(
        strs(&[
            "rom",
            "run",
            cube.to_str().unwrap(),
            "--model",
            "model.safetensors",
            "--out",
            "refused",
        ]),
        "dimension",
    );
    // Training on runs of different particles.
    refused(
        strs(&[
            "rom",
            "train",
            "--runs",
            "train",
            "full-fine",
            "--latent",
            "2",
            "--out",
            "x.safetensors",
        ]),
        "every run must use the same particles",
    );
    refused(
        strs(&[
            "rom",
            "train",
            "--runs",
            "train",
            "--latent",
            "500",
            "--out",
            "x.safetensors",
        ]),
        "--latent 500",
    );
    assert!(
        !d.join("refused").exists(),
        "nothing may be written for a refused run"
    );
    assert!(!d.join("x.safetensors").exists());
}

#[test]
fn rom_error_compares_stores_and_refuses_different_ones() {
    let f = fixture();
    let d = f.dir.path();
    let t = ok(
        &[
            "rom",
            "error",
            "train/wall-a.zarr",
            "train/wall-a.zarr",
            "--json",
        ],
        d,
    );
    let v: serde_json::Value = serde_json::from_str(&t).unwrap();
    assert_eq!(v["relative"], 0.0);
    let o = mpm(
        &[
            "rom",
            "error",
            "train/wall-a.zarr",
            "full-fine/rom-tower-2d.zarr",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("particles"), "{}", text(&o));
}

#[test]
fn neural_model_trains_and_runs() {
    // A small network (2 hidden layers of 32, 300 epochs) on the same runs. Its training
    // misfit is reported; the reduced run must finish and write every particle. The error
    // bound is loose (the network fits the snapshots far less closely than the POD modes;
    // see the README): below 10% of the positions.
    let f = fixture();
    let d = f.dir.path();
    let t = ok(
        &[
            "rom",
            "train",
            "--runs",
            "train",
            "--latent",
            "4",
            "--kind",
            "neural",
            "--epochs",
            "300",
            "--width",
            "32",
            "--layers",
            "2",
            "--out",
            "neural.safetensors",
        ],
        d,
    );
    assert!(t.contains("Neural, latent 4"), "{t}");
    let model = mpm_rom::Model::load(&d.join("neural.safetensors")).unwrap();
    assert_eq!(model.info.kind, mpm_rom::ModelKind::Neural);
    assert!(model.info.training.fit_error.is_finite());
    let s = f.scene.to_str().unwrap();
    let t = ok(
        &[
            "rom",
            "run",
            s,
            "--model",
            "neural.safetensors",
            "--samples",
            "16",
            "--out",
            "neural",
            "--compare",
            "full/rom-tower-2d.zarr",
            "--json",
            "-q",
            "--surface-samples",
        ],
        d,
    );
    let v: serde_json::Value = serde_json::from_str(&t).unwrap();
    assert_eq!(v["metrics"]["outcome"], "finished", "{t}");
    assert_eq!(v["metrics"]["particles"], 256);
    let error = v["error"]["relative"].as_f64().unwrap();
    assert!(error < 0.1, "neural reduced run: position error {error}");
}

#[test]
fn study_tabulates_and_plots_error_against_wall_time() {
    let f = fixture();
    let d = f.dir.path();
    let s = f.scene.to_str().unwrap();
    let t = ok(
        &[
            "rom",
            "study",
            s,
            "--full",
            "full/rom-tower-2d.zarr",
            "--runs",
            "train",
            "--latent",
            "2,4",
            "--samples",
            "8,16",
            "--out",
            "study",
            "--surface-samples",
        ],
        d,
    );
    assert!(t.contains("full-order run:"), "{t}");
    let csv = std::fs::read_to_string(d.join("study/rom-study.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4, "{csv}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("study/rom-study.json")).unwrap())
            .unwrap();
    assert!(
        json["full_order_wall_per_simulated_second"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    for row in json["rows"].as_array().unwrap() {
        assert_eq!(row["outcome"], "finished", "{row}");
        assert!(row["error"].as_f64().unwrap() < 0.05, "{row}");
    }
    let png = std::fs::read(d.join("study/rom-study.png")).unwrap();
    assert_eq!(&png[..4], b"\x89PNG");
}
