//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod jobs;
pub mod moto;
pub mod postgres;

use mpm_core::output::{Frame, Metrics, NullSink, OutputError, OutputSink, RunInfo};
use mpm_core::scene::ValidatedScene;
use mpm_core::solver::{Control, Progress, run_scene};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

/// Path of a file in the repository's `examples/`.
pub fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name)
}

/// Loads a scene with `--set` style overrides.
pub fn load(path: &Path, overrides: &[String]) -> ValidatedScene {
    mpm_cli::load_scene(path, overrides, &mpm_cli::default_registry()).expect("valid scene")
}

/// Loads an example with overrides given as `&str`.
pub fn load_example(name: &str, overrides: &[&str]) -> ValidatedScene {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    load(&example(name), &o)
}

/// The short cantilever of the F-bar tests (L = 0.5 m, h = 0.1 m, 4 cells thick, a small
/// load of g = 1 m/s², beam-theory reference) with Poisson's ratio `nu`, then `overrides`.
pub fn short_cantilever(nu: f64, overrides: &[&str]) -> ValidatedScene {
    let (material, reference) = (
        format!("materials.beam.poisson_ratio={nu}"),
        format!("reference.poisson_ratio={nu}"),
    );
    let mut all = vec![
        "domain.cell_size=0.025",
        "domain.min=[0,-0.3]",
        "domain.max=[0.6,0.2]",
        "bodies[0].shape.box.max=[0.5,0.1]",
        &material,
        &reference,
        "reference.length=0.5",
        "reference.thickness=0.1",
        "solver.gravity=[0,-1]",
        "reference.gravity=1",
    ];
    all.extend_from_slice(overrides);
    load_example("cantilever.json", &all)
}

/// The issues (`path: message` lines) of an example made invalid by `overrides`; panics
/// when the scene is accepted.
pub fn invalid_example(name: &str, overrides: &[&str]) -> Vec<String> {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    match mpm_cli::load_scene(&example(name), &o, &mpm_cli::default_registry()) {
        Ok(_) => panic!("accepted {overrides:?}"),
        Err(mpm_cli::LoadError::Invalid(e)) => e.issues.iter().map(|i| i.to_string()).collect(),
        Err(mpm_cli::LoadError::Io(e)) => panic!("{e:#}"),
    }
}

/// Runs a scene without writing results.
pub fn run(scene: &ValidatedScene) -> Metrics {
    run_scene(scene, &mut NullSink, &mut |_: &Progress| Control::Continue).expect("run")
}

/// Runs a scene and writes its results to a Zarr store at `store`.
pub fn run_to_store(scene: &ValidatedScene, store: &Path) -> Metrics {
    let mut sink = mpm_io::ZarrSink::new(store);
    run_scene(scene, &mut sink, &mut |_: &Progress| Control::Continue).expect("run")
}

/// Writes a JSON scene to a file in `dir` and returns its path.
pub fn write_scene(dir: &Path, name: &str, scene: &serde_json::Value) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_string_pretty(scene).unwrap()).unwrap();
    path
}

/// The vibrating bar example as JSON.
pub fn bar_json() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(example("vibrating-bar.json")).unwrap()).unwrap()
}

/// Runs the built `mpm` with `args` in `dir` and collects its output.
pub fn mpm(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mpm"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("mpm starts")
}

/// Stdout then stderr of a finished command, as text.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A child process killed (SIGKILL) and reaped when dropped, so a failing test leaves no
/// server behind.
pub struct Process(pub Child);

impl Process {
    /// Kills and reaps it now (a crash, for the tests that restart a server).
    pub fn kill(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        self.kill();
    }
}

/// A blocking HTTP client whose requests give up after `seconds`.
pub fn http_client(seconds: u64) -> reqwest::blocking::Client {
    reqwest::blocking::Client::builder()
        .timeout(std::time::Duration::from_secs(seconds))
        .build()
        .unwrap()
}

/// Spawns `command` (an `mpm serve` on `127.0.0.1:0`), waits for the address it prints and
/// keeps draining its stdout so it never blocks; returns the child and its base URL. Its
/// stderr goes where the caller set it (inherited by default).
pub fn serve(command: &mut Command) -> (Child, String) {
    let mut child = command
        .stdout(Stdio::piped())
        .spawn()
        .expect("mpm serve starts");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let url = loop {
        let line = lines.next().expect("server prints its address").unwrap();
        if let Some(url) = line.strip_prefix("listening on ") {
            break url.to_string();
        }
    };
    std::thread::spawn(move || for _ in lines {});
    (child, url)
}

/// An output sink that keeps the time and the values of the named fields of every frame
/// (`values[k][frame]`, particles in output order), for tests that follow a run.
pub struct FieldFrames {
    names: &'static [&'static str],
    index: Vec<usize>,
    /// Time of each frame.
    pub times: Vec<f64>,
    /// Per named field, per frame, its values.
    pub values: Vec<Vec<Vec<f64>>>,
    /// Per frame, the run's diagnostics (`mpm_core::output::FRAME_DIAGNOSTICS`).
    pub diagnostics: Vec<Vec<f64>>,
}

impl FieldFrames {
    /// A sink for the fields `names` (output names: `x`, `v`, `stress`, ...).
    pub fn new(names: &'static [&'static str]) -> Self {
        Self {
            names,
            index: vec![0; names.len()],
            times: Vec::new(),
            values: vec![Vec::new(); names.len()],
            diagnostics: Vec::new(),
        }
    }
}

impl OutputSink for FieldFrames {
    fn begin(&mut self, info: &RunInfo<'_>) -> Result<(), OutputError> {
        for (k, name) in self.names.iter().enumerate() {
            self.index[k] = info
                .fields
                .iter()
                .position(|f| f.name == *name)
                .ok_or_else(|| OutputError(format!("the scene must write {name}")))?;
        }
        Ok(())
    }
    fn write_frame(&mut self, frame: &Frame<'_>) -> Result<(), OutputError> {
        self.times.push(frame.time);
        for (k, &i) in self.index.iter().enumerate() {
            self.values[k].push(frame.values[i].clone());
        }
        self.diagnostics.push(frame.diagnostics.to_vec());
        Ok(())
    }
    fn finish(&mut self, _: &Metrics) -> Result<(), OutputError> {
        Ok(())
    }
}

/// Runs `scene` keeping the fields `names` of every frame.
pub fn run_fields(
    scene: &ValidatedScene,
    names: &'static [&'static str],
) -> (Metrics, FieldFrames) {
    let mut frames = FieldFrames::new(names);
    let m = run_scene(scene, &mut frames, &mut |_: &Progress| Control::Continue).expect("run");
    (m, frames)
}

/// A block (0.2 × 0.08 m, E 1 MPa) on an elastic slab (1.6 × 0.1 m, E 2 MPa) held at its
/// base, gravity tilted by `angle` degrees, the contact `law` between them, writing
/// `fields` 50 times over 0.5 s.
pub fn incline_scene(angle: f64, law: serde_json::Value, fields: &[&str]) -> serde_json::Value {
    let (s, c) = angle.to_radians().sin_cos();
    serde_json::json!({
        "name": "incline", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1.6, 0.3], "cell_size": 0.02,
                   "walls": [{"sides": ["y-"], "condition": "stick"}]},
        "solver": {"end_time": 0.5, "gravity": [9.81 * s, -9.81 * c], "cfl": 0.3},
        "materials": {
            "slab": {"type": "linear_elastic", "density": 2000.0, "youngs_modulus": 2e6, "poisson_ratio": 0.3},
            "block": {"type": "linear_elastic", "density": 1000.0, "youngs_modulus": 1e6, "poisson_ratio": 0.3}
        },
        "bodies": [
            {"name": "slab", "material": "slab", "shape": {"box": {"min": [0, 0], "max": [1.6, 0.1]}}},
            {"name": "block", "material": "block", "shape": {"box": {"min": [0.2, 0.1], "max": [0.4, 0.18]}}}
        ],
        "contact": {"pairs": [{"bodies": ["slab", "block"], "law": law}]},
        "output": {"frames": 50, "fields": fields}
    })
}

/// Copies the folder `from` (a result store, say) to `to`, recursively.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.path().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

/// Writes `scene` to `dir/<name>.json`, runs it with `mpm run --json` into `dir/<name>/`
/// and returns its metrics (failing the test if the run fails).
pub fn run_scene_json(dir: &Path, name: &str, scene: &serde_json::Value) -> serde_json::Value {
    let path = write_scene(dir, &format!("{name}.json"), scene);
    let out = mpm(
        &["run", path.to_str().unwrap(), "--out", name, "-q", "--json"],
        dir,
    );
    assert!(out.status.success(), "{}", text(&out));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Runs the staged `scene` (it must write checkpoints) into `dir/whole/`, resumes a copy of
/// its store from its latest checkpoint and checks that the checkpoint lies in a stage after
/// the first and that the `fields` of every frame of stage `stage` are the uninterrupted
/// run's bit for bit. Returns the whole run's and the resumed run's metrics.
pub fn resume_staged_copy(
    dir: &Path,
    scene: &serde_json::Value,
    stage: &str,
    fields: &[&str],
) -> (serde_json::Value, serde_json::Value) {
    let whole = run_scene_json(dir, "whole", scene);
    let store = dir.join(format!("whole/{}.zarr", scene["name"].as_str().unwrap()));
    let copy = dir.join("copy.zarr");
    copy_dir(&store, &copy);
    let out = mpm(&["run", "--resume", "copy.zarr", "-q", "--json"], dir);
    assert!(out.status.success(), "{}", text(&out));
    let resumed: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let step = resumed["resumed_from_step"].as_u64().unwrap();
    let first_steps = whole["stages"][0]["steps"].as_u64().unwrap();
    assert!(step > first_steps, "resumed at {step}, in the first stage");
    let open = |path: &Path| {
        mpm_io::ResultStore::open(path)
            .unwrap()
            .stage(stage)
            .unwrap()
    };
    let (a, b) = (open(&store), open(&copy));
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for frame in 0..a.frame_count().unwrap() {
        for name in fields {
            let (p, q) = (
                a.frame(name, frame).unwrap().1,
                b.frame(name, frame).unwrap().1,
            );
            assert_eq!(bits(&p), bits(&q), "{name} differs at frame {frame}");
        }
    }
    (whole, resumed)
}

/// The measured and reference values of the run's comparison `name` (panics if missing).
#[allow(dead_code)]
pub fn comparison(m: &mpm_core::output::Metrics, name: &str) -> (f64, f64) {
    let c = m
        .comparisons
        .iter()
        .find(|c| c.quantity == name)
        .unwrap_or_else(|| panic!("no comparison {name}: {:?}", m.comparisons));
    (c.measured, c.reference)
}

/// Override of examples/liquid-void-pit.json that times the pit's fill (`fill_region`).
pub const PIT_FILL_REGION: &str =
    r#"physics.liquid_voids.fill_region={"min":[0.008,0],"max":[0.012,0.006]}"#;

/// Override of examples/liquid-void-pit.json (with [`PIT_FILL_REGION`]) in two stages: the
/// fill, ended at its fill time by `solver.end_when`, then the rest to 0.09 s.
pub const PIT_STAGES_FILL_THEN_REST: &str = concat!(
    r#"stages=[{"name":"fill","changes":{"solver":{"end_when":"underfill.fill_time"}}},"#,
    r#"{"name":"after","changes":{"solver":{"end_time":0.09},"physics":{"liquid_voids":null}}}]"#
);

/// Overrides that make examples/liquid-void-pit.json 3D: 4 mm deep between slip walls, the
/// pit 4 × 6 × 4 mm between two blocks.
pub const PIT_3D: [&str; 8] = [
    "dimension=3",
    "domain.min=[0,0,0]",
    "domain.max=[0.02,0.03,0.004]",
    r#"domain.walls=[{"sides":["x-","x+","y-","z-","z+"],"condition":"slip"}]"#,
    "solver.gravity=[0,-9.81,0]",
    r#"bodies[0].shape={"box":{"min":[0.004,0.011,0],"max":[0.016,0.015,0.004]}}"#,
    r#"obstacles[0].shape={"box":{"min":[0,0,0],"max":[0.008,0.006,0.004]}}"#,
    r#"obstacles[1].shape={"box":{"min":[0.012,0,0],"max":[0.02,0.006,0.004]}}"#,
];

/// The RGB pixels of a PNG picture, with its width and height.
pub fn decode_png(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(file).read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("a PNG frame");
    assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
    let pixels = buf[..info.buffer_size()]
        .chunks_exact(3)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    (info.width, info.height, pixels)
}

/// The largest ratio, over neighbouring particles of the reference lattice (spacing `h`
/// along x and y), of their distance in the last frame to the distance their mean F maps
/// their reference offset to: about 1 where the body is whole, far above it across a gap
/// that opened between particles whose F did not stretch (numerical fracture).
pub fn largest_separation(store: &Path, h: f64) -> f64 {
    let s = mpm_io::ResultStore::open(store).unwrap();
    let last = s.times().unwrap().len() as u64 - 1;
    let (_, x0) = s.frame("x", 0).unwrap();
    let (_, x) = s.frame("x", last).unwrap();
    let (_, f) = s.frame("F", last).unwrap();
    let key = |p: usize| {
        (
            (x0[2 * p] / h).round() as i64,
            (x0[2 * p + 1] / h).round() as i64,
        )
    };
    let n = x0.len() / 2;
    let at: std::collections::HashMap<(i64, i64), usize> = (0..n).map(|p| (key(p), p)).collect();
    let mut largest = 0.0f64;
    for p in 0..n {
        let (i, j) = key(p);
        for q in [at.get(&(i + 1, j)), at.get(&(i, j + 1))]
            .into_iter()
            .flatten()
        {
            let q = *q;
            let d0 = [x0[2 * q] - x0[2 * p], x0[2 * q + 1] - x0[2 * p + 1]];
            let fm: Vec<f64> = (0..4)
                .map(|k| 0.5 * (f[4 * p + k] + f[4 * q + k]))
                .collect();
            let mapped = [fm[0] * d0[0] + fm[1] * d0[1], fm[2] * d0[0] + fm[3] * d0[1]];
            let d = [x[2 * q] - x[2 * p], x[2 * q + 1] - x[2 * p + 1]];
            let ratio = d[0].hypot(d[1]) / mapped[0].hypot(mapped[1]);
            largest = largest.max(ratio);
        }
    }
    largest
}
