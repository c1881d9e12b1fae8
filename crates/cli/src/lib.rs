//! The `mpm` command as a library: the binary is `main_with(default_registry())`, and a
//! plugin author builds their own `mpm` with one more line (see the plugin template).

pub mod bench;
pub mod bench_peer;
mod client;
mod commands;
mod exit_status;
mod from_store;
mod job;
mod overrides;
mod plot;
mod process_report;
mod progress;
mod render;
mod resume;
pub mod rom;
mod rom_design;
mod rom_study_plot;
mod scene_file;
mod schema;
mod service_cmd;
pub mod stability;
pub mod stability_case;
pub mod stability_cohesive;
pub mod stability_implicit;
pub mod stability_liquid;
pub mod stability_long;
mod stability_long_plot;
pub mod stability_map;
mod stability_map_plot;
pub mod stability_peer;
mod stdout;
pub mod study;

pub use commands::{Cli, Command, run_cli};
pub use exit_status::ExitStatus;
pub use overrides::apply_override;
pub use scene_file::{LoadError, load_scene};
pub use schema::scene_schema;

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
    registry
        .register(Box::new(mpm_viscoplastic::ViscoplasticPlugin))
        .expect("built-in plugins have distinct names");
    registry.set_particle_store_reader(Box::new(mpm_io::read_particles));
    registry
}

/// Parses the command line, runs it with `registry`, and returns the process exit code:
/// the README's table (2 for invalid input, 1 for other failures), 141 quietly when stdout
/// was closed by its reader.
pub fn main_with(registry: Registry) -> std::process::ExitCode {
    use clap::Parser;
    let cli = Cli::parse();
    match run_cli(cli, registry) {
        Ok(status) => status.into(),
        Err(e) if stdout::is_closed(&e) => std::process::ExitCode::from(stdout::CLOSED_EXIT_CODE),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitStatus::of_error(&e).into()
        }
    }
}
