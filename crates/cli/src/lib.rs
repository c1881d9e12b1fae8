//! The `mpm` command as a library: the binary is `main_with(default_registry())`, and a
//! plugin author builds their own `mpm` with one more line (see the plugin template).

mod client;
mod commands;
mod job;
mod overrides;
mod plot;
mod progress;
mod render;
pub mod rom;
pub mod stability;
pub mod study;

pub use commands::{Cli, Command, ExitStatus, LoadError, load_scene, run_cli};
pub use overrides::apply_override;

use mpm_core::plugin::Registry;

/// The registry of the stock `mpm` binary: every plugin in this repository, and the Zarr
/// reader for bodies made from result stores.
pub fn default_registry() -> Registry {
    let mut registry = Registry::new();
    registry
        .register(Box::new(mpm_elastic::ElasticPlugin))
        .expect("built-in plugins have distinct names");
    registry
        .register(Box::new(mpm_johnson_cook::JohnsonCookPlugin))
        .expect("built-in plugins have distinct names");
    registry
        .register(Box::new(mpm_thermal::ThermalPlugin))
        .expect("built-in plugins have distinct names");
    registry
        .register(Box::new(mpm_phase_change::PhaseChangePlugin))
        .expect("built-in plugins have distinct names");
    registry
        .register(Box::new(mpm_underfill::UnderfillPlugin))
        .expect("built-in plugins have distinct names");
    registry.set_particle_store_reader(Box::new(mpm_io::read_particles));
    registry
}

/// The JSON Schema of a scene file, with the material sections of every registered plugin.
pub fn scene_schema(registry: &Registry) -> serde_json::Value {
    let mut schema = schemars::schema_for!(mpm_core::scene::Scene).to_value();
    let materials: Vec<serde_json::Value> = registry
        .material_types()
        .map(|t| registry.material(t).expect("listed").schema())
        .collect();
    if let Some(slot) = schema.pointer_mut("/properties/materials") {
        slot["additionalProperties"] = serde_json::json!({ "oneOf": materials });
    }
    let physics: serde_json::Map<String, serde_json::Value> = registry
        .physics_names()
        .map(|n| {
            let (_, f) = registry.physics(n).expect("listed");
            (n.to_string(), f.schema())
        })
        .collect();
    if let Some(slot) = schema.pointer_mut("/properties/physics") {
        slot["properties"] = serde_json::Value::Object(physics);
        slot["additionalProperties"] = serde_json::json!(false);
    }
    schema
}

/// Parses the command line, runs it with `registry`, and returns the process exit code.
pub fn main_with(registry: Registry) -> std::process::ExitCode {
    use clap::Parser;
    let cli = Cli::parse();
    match run_cli(cli, registry) {
        Ok(status) => status.into(),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitStatus::Failure.into()
        }
    }
}
