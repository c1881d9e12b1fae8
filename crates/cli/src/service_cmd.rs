//! `mpm serve` and `mpm worker`: the job service's API and workers, their options, and the
//! log set-up (`tracing`, level from `RUST_LOG`, text or JSON lines).

use crate::exit_status::ExitStatus;
use anyhow::Context;
use mpm_core::plugin::Registry;
use std::path::PathBuf;
use std::sync::Arc;

/// How log lines are written.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum LogFormat {
    /// Human-readable lines.
    Text,
    /// One JSON object per line (for log collectors).
    Json,
}

/// Options both the API and the workers take.
#[derive(Debug, clap::Args)]
pub struct QueueArgs {
    /// The job queue: `postgres://USER@HOST:PORT/DB` (shared by several machines) or a SQLite
    /// file (`mpm serve`'s default: DATA/jobs.sqlite; `mpm worker` needs it given).
    #[arg(long, env = "MPM_DATABASE")]
    pub database: Option<String>,
    /// Seconds a running job's lease lasts; its worker renews it every second (or every third
    /// of the lease), and a job whose worker died goes back to the queue when it runs out.
    #[arg(long, default_value_t = 30.0)]
    pub lease_seconds: f64,
    /// Memory limit of each job's process, MB (default: half the machine's memory).
    #[arg(long, default_value_t = 0)]
    pub job_memory_mb: u64,
    /// Log line format (the level comes from RUST_LOG, default `info`).
    #[arg(long, value_enum, default_value = "text")]
    pub log_format: LogFormat,
}

/// Options of `mpm serve`.
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1:8080", env = "MPM_LISTEN")]
    pub listen: std::net::SocketAddr,
    /// Folder for the job database and results.
    #[arg(long, default_value = "mpm-data", env = "MPM_DATA")]
    pub data: PathBuf,
    /// Where the result stores are: a folder shared with the workers (default: DATA/jobs),
    /// or `s3://BUCKET/PREFIX` (endpoint, region and keys from the AWS_* variables).
    #[arg(long, env = "MPM_STORE")]
    pub store: Option<String>,
    /// With an S3 store: a local folder for copies of stores to draw pictures from (and the
    /// jobs of this process's own workers) (default: DATA/scratch).
    #[arg(long, env = "MPM_SCRATCH")]
    pub scratch: Option<PathBuf>,
    /// Require `Authorization: Bearer TOKEN` on every route but /v1/health.
    #[arg(long, env = "MPM_TOKEN", conflicts_with = "tokens")]
    pub token: Option<String>,
    /// Users: a token file of lines `NAME ROLE SHA256HEX` (ROLE `user` or `admin`; the hash
    /// is `printf %s TOKEN | sha256sum`). Each user sees and cancels only their own jobs.
    #[arg(long, env = "MPM_TOKENS")]
    pub tokens: Option<PathBuf>,
    /// Most queued jobs of one user (with --tokens).
    #[arg(long, default_value_t = 100)]
    pub max_queued_per_user: usize,
    /// Jobs run at once by this process (0: API only; jobs run in `mpm worker` processes).
    #[arg(long, default_value_t = 1)]
    pub workers: usize,
    /// Largest request body, bytes.
    #[arg(long, default_value_t = 2 * 1024 * 1024)]
    pub max_body_bytes: usize,
    /// Largest particle count of a submitted scene.
    #[arg(long, default_value_t = 5_000_000)]
    pub max_particles: usize,
    /// Most queued jobs.
    #[arg(long, default_value_t = 1000)]
    pub max_queued: usize,
    /// Largest grid a submitted scene may need, bytes (estimated from the domain and cell
    /// size; refused with 422 at `domain.cell_size`).
    #[arg(long)]
    pub max_grid_bytes: Option<u64>,
    /// Most time steps a submitted scene may take (end_time over its initial time step;
    /// refused with 422 at `solver.end_time`, or `solver.dt` when the step is fixed).
    #[arg(long)]
    pub max_steps: Option<u64>,
    /// Longest a submitted scene's validation may take, seconds (then 422).
    #[arg(long, default_value_t = 10.0)]
    pub validation_seconds: f64,
    /// Validations at once (default: one per core).
    #[arg(long)]
    pub max_validations: Option<usize>,
    #[command(flatten)]
    pub queue: QueueArgs,
}

/// Options of `mpm worker`.
#[derive(Debug, clap::Args)]
pub struct WorkerArgs {
    /// Where the result stores are, as the API has them (`mpm serve --store`): the shared
    /// folder, or `s3://BUCKET/PREFIX`.
    #[arg(long, env = "MPM_STORE")]
    pub store: String,
    /// With an S3 store: this machine's folder where jobs write before their stores are
    /// uploaded (default: mpm-scratch in the temporary folder).
    #[arg(long, env = "MPM_SCRATCH")]
    pub scratch: Option<PathBuf>,
    /// Jobs run at once by this process.
    #[arg(long, default_value_t = 1)]
    pub workers: usize,
    #[command(flatten)]
    pub queue: QueueArgs,
}

/// Sends `tracing` events to stderr, filtered by `RUST_LOG` (default `info`; sqlx's own
/// per-query lines off), as text or JSON lines.
fn init_logs(format: LogFormat) {
    use tracing_subscriber::EnvFilter;
    let filter =
        EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info,sqlx=warn"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    // A second initialisation (a library caller that set its own) is not an error.
    let _ = match format {
        LogFormat::Text => builder.with_ansi(false).try_init(),
        LogFormat::Json => builder.json().flatten_event(true).try_init(),
    };
}

/// Resolves on Ctrl-C or SIGTERM (what service managers send): a clean stop, whose running
/// jobs go back to the queue at once.
async fn stop_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        if let Ok(mut term) = signal(SignalKind::terminate()) {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
            return;
        }
    }
    let _ = tokio::signal::ctrl_c().await;
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the async runtime")
}

/// The service settings both commands share.
fn base_config(queue: &QueueArgs) -> anyhow::Result<mpm_service::Config> {
    let limits = mpm_core::scene::Limits::current();
    let lease = std::time::Duration::try_from_secs_f64(queue.lease_seconds)
        .ok()
        .filter(|d| d.as_secs_f64() >= 0.3)
        .context("--lease-seconds must be a number of seconds >= 0.3")?;
    Ok(mpm_service::Config {
        database: queue.database.clone(),
        lease,
        limits,
        job_command: Some(crate::job::job_command(&limits, queue.job_memory_mb)?),
        ..mpm_service::Config::default()
    })
}

/// Reads `--store` (exit 2 on a malformed one).
fn store_location(text: &str) -> anyhow::Result<mpm_service::StoreLocation> {
    mpm_service::StoreLocation::parse(text)
        .map_err(|e| crate::exit_status::input_error!("--store {e}"))
}

/// A bucket the server does not have is an input error (exit 2, before listening); a folder
/// that cannot be created or an unreachable server stays an operational failure (1).
fn service_result(result: Result<(), mpm_service::ServiceError>) -> anyhow::Result<()> {
    match result {
        Err(mpm_service::ServiceError::Store(e)) if e.is_input() => {
            Err(crate::exit_status::input_error!("--store: {e}"))
        }
        other => Ok(other?),
    }
}

/// `mpm serve`.
pub fn serve(args: ServeArgs, registry: Arc<Registry>) -> anyhow::Result<ExitStatus> {
    init_logs(args.queue.log_format);
    let defaults = mpm_service::Config::default();
    let users = match &args.tokens {
        Some(path) => {
            Some(Arc::new(mpm_service::Users::load(path).map_err(|e| {
                crate::exit_status::input_error!("--tokens {e}")
            })?))
        }
        None => None,
    };
    let config = mpm_service::Config {
        users,
        max_queued_per_user: args.max_queued_per_user,
        max_grid_bytes: args.max_grid_bytes,
        max_steps: args.max_steps,
        listen: args.listen,
        data_dir: args.data,
        store: args.store.as_deref().map(store_location).transpose()?,
        scratch_dir: args.scratch,
        token: args.token,
        workers: args.workers,
        max_body_bytes: args.max_body_bytes,
        max_particles: args.max_particles,
        max_queued: args.max_queued,
        validation_timeout: std::time::Duration::try_from_secs_f64(args.validation_seconds)
            .context("--validation-seconds must be a number of seconds >= 0")?,
        max_validations: args.max_validations.unwrap_or(defaults.max_validations),
        frame_renderer: Some(Arc::new(crate::render::ServiceRenderer)),
        ..base_config(&args.queue)?
    };
    service_result(runtime()?.block_on(mpm_service::serve(config, registry, stop_signal())))?;
    Ok(ExitStatus::Success)
}

/// `mpm worker`.
pub fn worker(args: WorkerArgs, registry: Arc<Registry>) -> anyhow::Result<ExitStatus> {
    init_logs(args.queue.log_format);
    if args.queue.database.is_none() {
        return Err(crate::exit_status::input_error!(
            "mpm worker needs --database (or MPM_DATABASE): the queue it shares with `mpm serve`"
        ));
    }
    let store = store_location(&args.store)?;
    let scratch = args
        .scratch
        .unwrap_or_else(|| std::env::temp_dir().join("mpm-scratch"));
    // The jobs' base folder: the shared folder, or with S3 this machine's scratch folder.
    let data_dir = match &store {
        mpm_service::StoreLocation::Folder(dir) => dir.clone(),
        mpm_service::StoreLocation::S3 { .. } => scratch.clone(),
    };
    let config = mpm_service::Config {
        data_dir,
        store: Some(store),
        scratch_dir: Some(scratch),
        workers: args.workers.max(1),
        ..base_config(&args.queue)?
    };
    service_result(runtime()?.block_on(mpm_service::work(config, registry, stop_signal())))?;
    Ok(ExitStatus::Success)
}
