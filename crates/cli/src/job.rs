//! `mpm run-job` (hidden): one job of `mpm serve`, run in a process of its own so that a
//! crash or an exhausted memory limit fails that job only; and the command that starts it.

use crate::exit_status::ExitStatus;
use mpm_core::plugin::Registry;
use mpm_core::scene::Limits;
use std::path::PathBuf;

/// Arguments of the job subcommand (the service passes them).
#[derive(Debug, clap::Args)]
pub struct RunJobArgs {
    /// The job's scene (JSON, as validated on submission).
    #[arg(long)]
    pub scene: PathBuf,
    /// The result store to write.
    #[arg(long)]
    pub store: PathBuf,
    /// Folder that relative particle-file paths resolve against.
    #[arg(long)]
    pub base: PathBuf,
    /// A store whose state the run starts from (a job submitted with `from`).
    #[arg(long)]
    pub from: Option<PathBuf>,
    /// With `--from`: the stage of the staged scene to start at.
    #[arg(long, requires = "from")]
    pub stage: Option<String>,
}

/// Runs one job, reporting to the service on stdout (see `mpm_service::run_job_process`).
pub fn run(args: &RunJobArgs, registry: &Registry) -> ExitStatus {
    let start = args.from.as_ref().map(|store| mpm_service::JobStart {
        store: store.clone(),
        stage: args.stage.clone(),
    });
    let code = mpm_service::run_job_process(
        registry,
        &args.scene,
        &args.store,
        &args.base,
        &Limits::current(),
        start.as_ref(),
    );
    match code {
        0 => ExitStatus::Success,
        2 => ExitStatus::InvalidInput,
        3 => ExitStatus::Stopped,
        _ => ExitStatus::Failure,
    }
}

/// How `mpm serve` starts a job: this executable's `run-job` with the service's limits, in
/// an address space of `memory_mb` MB (0: half the machine's memory).
pub fn job_command(limits: &Limits, memory_mb: u64) -> anyhow::Result<mpm_service::JobCommand> {
    let program = std::env::current_exe()
        .map_err(|e| anyhow::anyhow!("cannot find this executable to run jobs with: {e}"))?;
    let mut args = vec!["run-job".to_string()];
    for (name, value) in [
        ("particles", limits.max_particles),
        ("grid_nodes", limits.max_grid_nodes),
        ("frames", limits.max_frames),
        ("store_bytes", limits.max_store_bytes),
        ("file_bytes", limits.max_file_bytes),
        ("steps", limits.max_steps),
        ("setup_tests", limits.max_setup_tests),
    ] {
        args.push("--limit".into());
        args.push(format!("{name}={value}"));
    }
    let memory_bytes = match memory_mb {
        0 => mpm_service::default_job_memory(),
        mb => Some(mb.saturating_mul(1_000_000)),
    };
    Ok(mpm_service::JobCommand {
        program,
        args,
        memory_bytes,
    })
}

/// This process's limits from `--limit NAME=N` options.
pub fn limits_from(options: &[String]) -> Result<Limits, String> {
    let mut limits = Limits::default();
    for o in options {
        limits.apply(o)?;
    }
    Ok(limits)
}
