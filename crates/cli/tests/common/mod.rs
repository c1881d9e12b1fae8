//! Helpers shared by the integration tests.
#![allow(dead_code)]

use mpm_core::output::{Metrics, NullSink};
use mpm_core::scene::ValidatedScene;
use mpm_core::solver::{Control, Progress, run_scene};
use std::path::{Path, PathBuf};

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
