//! The mpm job service: an HTTP API (axum) over a SQLite job queue (sqlx). Workers take jobs
//! in submission order, run them with the core solver off the async threads, and store the
//! results as Zarr in the data folder, served read-only so zarr-python can open them over
//! HTTP. Knows no physics: scenes are validated by the registry the binary passes in.

mod api;
mod child;
mod db;
mod error;
mod worker;

pub use api::ROUTES;
pub use child::{JobCommand, default_job_memory, run_job_process};
pub use error::ServiceError;
pub use mpm_core::scene::Limits;

use mpm_core::plugin::Registry;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

/// Settings of a service instance.
#[derive(Clone, Debug)]
pub struct Config {
    /// Address to listen on (127.0.0.1:8080 by default; port 0 picks a free one).
    pub listen: SocketAddr,
    /// Folder for the job database (`jobs.sqlite`) and the results (`jobs/<id>/results.zarr`).
    pub data_dir: PathBuf,
    /// When set, every route but `/v1/health` needs `Authorization: Bearer <token>`.
    pub token: Option<String>,
    /// Jobs run at once (the solver already uses every core).
    pub workers: usize,
    /// Largest request body, bytes.
    pub max_body_bytes: usize,
    /// Largest particle count a submitted scene may have.
    pub max_particles: usize,
    /// Most jobs waiting in the queue at once.
    pub max_queued: usize,
    /// Bounds on a scene's work (grid, frames, store, ...), checked before anything is
    /// generated; `max_particles` above applies too.
    pub limits: Limits,
    /// Longest a submitted scene's validation may take before the request gets a 422.
    pub validation_timeout: std::time::Duration,
    /// Validations running at once; further submissions wait (up to the timeout, then 503).
    pub max_validations: usize,
    /// Runs each job in a process of its own (see [`JobCommand`]); `None` runs jobs on a
    /// thread of the service, where an abort or exhausted memory ends the service too.
    pub job_command: Option<JobCommand>,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            data_dir: PathBuf::from("mpm-data"),
            token: None,
            workers: 1,
            max_body_bytes: 2 * 1024 * 1024,
            max_particles: 5_000_000,
            max_queued: 1000,
            limits: Limits::default(),
            validation_timeout: std::time::Duration::from_secs(10),
            max_validations: std::thread::available_parallelism().map_or(2, |n| n.get()),
            job_command: None,
        }
    }
}

/// Shared state of a running service.
pub(crate) struct State {
    pub config: Config,
    pub registry: Arc<Registry>,
    pub db: sqlx::SqlitePool,
    pub jobs: worker::JobBoard,
    /// Permits for validations running at once.
    pub validations: Arc<tokio::sync::Semaphore>,
}

/// Runs the service until `shutdown` resolves. Prints `listening on http://ADDR` once the
/// socket is bound (tests read the port from it).
pub async fn serve(
    config: Config,
    registry: Arc<Registry>,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<(), ServiceError> {
    std::fs::create_dir_all(config.data_dir.join("jobs")).map_err(|e| ServiceError::Io {
        path: config.data_dir.display().to_string(),
        source: e,
    })?;
    let db = db::open(&config.data_dir.join("jobs.sqlite")).await?;
    let requeued = db::requeue_interrupted(&db).await?;
    let state = Arc::new(State {
        config: config.clone(),
        registry,
        db,
        jobs: worker::JobBoard::default(),
        validations: Arc::new(tokio::sync::Semaphore::new(config.max_validations.max(1))),
    });
    let listener = tokio::net::TcpListener::bind(config.listen)
        .await
        .map_err(|e| ServiceError::Io {
            path: config.listen.to_string(),
            source: e,
        })?;
    let addr = listener.local_addr().map_err(|e| ServiceError::Io {
        path: config.listen.to_string(),
        source: e,
    })?;
    println!("listening on http://{addr}");
    if requeued > 0 {
        println!("requeued {requeued} job(s) interrupted by the last shutdown");
    }
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    for _ in 0..config.workers.max(1) {
        tokio::spawn(worker::run(state.clone(), stop_rx.clone()));
    }
    let app = api::router(state.clone(), stop_rx.clone());
    let result = axum::serve(listener, app)
        .with_graceful_shutdown(async move {
            shutdown.await;
            let _ = stop_tx.send(true);
        })
        .await;
    // Running jobs see the stop flag and end within a step; they are requeued on restart.
    state.jobs.cancel_all();
    result.map_err(|e| ServiceError::Io {
        path: addr.to_string(),
        source: e,
    })
}
