//! `mpm`: run, validate and export material point method scenes.

fn main() -> std::process::ExitCode {
    mpm_cli::main_with(mpm_cli::default_registry())
}
