//! The command line's integration tests, one binary: each module is one subject (a solver
//! mode, a physics, the service, ...), run with `cargo test -p mpm-cli --test suite
//! MODULE::` (all of them: `--test suite`). One binary links once where one per file
//! linked ~45 times, and the test threads share the two cores across subjects.

mod bench;
mod bounds;
mod capillary_rise;
mod cli;
mod cohesive;
mod cohesive_mode_ii;
mod common;
mod conservation;
mod contact;
mod contact_conductance;
mod cpdi;
mod cure_probe;
mod enclosed_air;
mod energy_ledger;
mod exit_codes;
mod fuzz;
mod hertz;
mod implicit;
mod johnson_cook;
mod layered_stack;
mod liquid;
mod liquid_inflow;
mod liquid_voids;
mod loads;
mod phase_change;
mod pressure_inlet;
mod process_chain;
mod process_fill_chain;
mod render;
mod resume;
mod rom;
mod run_from;
mod service;
mod service_access;
mod service_postgres;
mod service_s3;
mod setup;
mod sparse_grid;
mod stability_long;
mod stability_map;
mod stability_peer;
mod stage_conversion;
mod stage_removal;
mod stages;
mod stress_averaging;
mod surface_tension;
mod thermal;
mod thermal_contact;
mod total_lagrangian;
mod underfill;
mod underfill_delamination;
mod verification;
mod web_page;
