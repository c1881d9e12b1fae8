//! The mpm job service: an HTTP API (axum) over a job queue in SQLite or PostgreSQL (sqlx).
//! Workers (in the API's process, or in `mpm worker` processes on other machines) take jobs
//! in submission order under a lease, run them with the core solver off the async threads,
//! and store the results as Zarr in the store folder or an S3 bucket (`results_store`),
//! served read-only so zarr-python can open them over HTTP. Knows no physics: scenes are
//! validated by the registry the binary passes in.

mod api;
mod child;
mod db;
mod error;
mod frames;
mod metrics;
mod results_store;
mod resume;
mod start_state;
mod users;
mod worker;

pub use api::ROUTES;
pub use child::{JobCommand, default_job_memory, run_job_process};
pub use error::ServiceError;
pub use frames::{FrameError, FrameRenderer, FrameRequest};
pub use mpm_core::scene::Limits;
pub use results_store::{StoreError, StoreLocation};
pub use start_state::JobStart;
pub use users::{User, Users, UsersError, token_hash};

use mpm_core::plugin::Registry;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

/// Settings of a service instance.
#[derive(Clone, Debug)]
pub struct Config {
    /// Address to listen on (127.0.0.1:8080 by default; port 0 picks a free one).
    pub listen: SocketAddr,
    /// Folder for the job database (`jobs.sqlite`), the results (`jobs/<id>/results.zarr`)
    /// and the scratch folder, unless those are given.
    pub data_dir: PathBuf,
    /// The queue database: `postgres://...`, or a SQLite file; `None`: `data_dir/jobs.sqlite`.
    pub database: Option<String>,
    /// Where the result stores are: a folder of `<id>/results.zarr` shared by the API and
    /// every worker, or an S3 bucket and prefix; `None`: the folder `data_dir/jobs`.
    pub store: Option<StoreLocation>,
    /// With an S3 store, this process's own folder where jobs write before their stores are
    /// uploaded (and where the API keeps copies to draw from); `None`: `data_dir/scratch`.
    pub scratch_dir: Option<PathBuf>,
    /// A running job's lease: its worker renews it every third of this; a job whose lease
    /// ran out (its worker died) goes back to the queue.
    pub lease: std::time::Duration,
    /// How often an idle worker looks for a job (jobs queued by this process wake it at once).
    pub poll: std::time::Duration,
    /// When set, every route but `/v1/health` needs `Authorization: Bearer <token>`.
    pub token: Option<String>,
    /// Users (a token file): each sees and cancels only their own jobs, admins every job;
    /// replaces `token` when set.
    pub users: Option<Arc<Users>>,
    /// Most queued jobs of one user (with `users`).
    pub max_queued_per_user: usize,
    /// Largest grid a submitted scene may need, bytes (estimated from the domain and cell
    /// size before anything is built); `None`: only `limits.max_grid_nodes`.
    pub max_grid_bytes: Option<u64>,
    /// Most time steps a submitted scene may take (end_time over its initial step);
    /// `None`: no bound beyond `limits`.
    pub max_steps: Option<u64>,
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
    /// Draws the frame pictures of `GET /v1/jobs/{id}/frames/{frame}`; `None`: that route
    /// answers 501.
    pub frame_renderer: Option<Arc<dyn FrameRenderer>>,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            data_dir: PathBuf::from("mpm-data"),
            database: None,
            store: None,
            scratch_dir: None,
            lease: std::time::Duration::from_secs(30),
            poll: std::time::Duration::from_millis(500),
            token: None,
            users: None,
            max_queued_per_user: 100,
            max_grid_bytes: None,
            max_steps: None,
            workers: 1,
            max_body_bytes: 2 * 1024 * 1024,
            max_particles: 5_000_000,
            max_queued: 1000,
            limits: Limits::default(),
            validation_timeout: std::time::Duration::from_secs(10),
            max_validations: std::thread::available_parallelism().map_or(2, |n| n.get()),
            job_command: None,
            frame_renderer: None,
        }
    }
}

impl Config {
    /// Where the result stores are.
    pub fn store_location(&self) -> StoreLocation {
        self.store
            .clone()
            .unwrap_or_else(|| StoreLocation::Folder(self.data_dir.join("jobs")))
    }

    /// This process's scratch folder (used with an S3 store).
    fn scratch(&self) -> PathBuf {
        self.scratch_dir
            .clone()
            .unwrap_or_else(|| self.data_dir.join("scratch"))
    }

    /// The database to open.
    fn database_url(&self) -> String {
        self.database.clone().unwrap_or_else(|| {
            self.data_dir
                .join("jobs.sqlite")
                .to_string_lossy()
                .into_owned()
        })
    }
}

/// Shared state of a running service.
pub(crate) struct State {
    pub config: Config,
    pub registry: Arc<Registry>,
    pub db: db::Db,
    /// The result stores (a folder or a bucket).
    pub results: results_store::ResultsStore,
    pub jobs: worker::JobBoard,
    /// Permits for validations running at once.
    pub validations: Arc<tokio::sync::Semaphore>,
    /// This process's counters for `/metrics`.
    pub metrics: metrics::Metrics,
    /// Permits for frame pictures drawn at once.
    pub renders: Arc<tokio::sync::Semaphore>,
}

/// Opens the result stores (creating the folders; checking an S3 bucket answers), opens the
/// database and builds the shared state.
async fn start(config: Config, registry: Arc<Registry>) -> Result<Arc<State>, ServiceError> {
    let results =
        results_store::ResultsStore::open(&config.store_location(), &config.scratch()).await?;
    let db = db::Db::open(&config.database_url()).await?;
    Ok(Arc::new(State {
        validations: Arc::new(tokio::sync::Semaphore::new(config.max_validations.max(1))),
        renders: Arc::new(tokio::sync::Semaphore::new(config.max_validations.max(1))),
        config,
        registry,
        db,
        results,
        jobs: worker::JobBoard::default(),
        metrics: metrics::Metrics::default(),
    }))
}

/// Runs the service until `shutdown` resolves: the HTTP API and `config.workers` workers
/// (0: API only, the jobs run in `mpm worker` processes). Prints `listening on http://ADDR`
/// once the socket is bound (tests read the port from it).
pub async fn serve(
    config: Config,
    registry: Arc<Registry>,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<(), ServiceError> {
    let state = start(config.clone(), registry).await?;
    // With SQLite the service's own workers are the only ones: whatever was running when it
    // last stopped is requeued now. With PostgreSQL, other workers may be running jobs;
    // leases tell the dead ones apart.
    let requeued = match (&state.db, config.workers) {
        (db::Db::Sqlite(_), 1..) => state.db.requeue_interrupted().await?,
        _ => 0,
    };
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
    let store = config.store_location().to_string();
    tracing::info!(%addr, database = state.db.backend(), %store, workers = config.workers, "listening");
    if requeued > 0 {
        println!("requeued {requeued} job(s) interrupted by the last shutdown");
        tracing::info!(requeued, "jobs interrupted by the last shutdown requeued");
    }
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    let mut workers = Vec::new();
    for n in 0..config.workers {
        workers.push(tokio::spawn(worker::run(
            state.clone(),
            worker::worker_name(n),
            stop_rx.clone(),
        )));
    }
    let app = api::router(state.clone(), stop_rx.clone());
    let result = axum::serve(listener, app)
        .with_graceful_shutdown(async move {
            shutdown.await;
            let _ = stop_tx.send(true);
        })
        .await;
    // Running jobs see the stop flag and end within a step; their workers give them back.
    state.jobs.cancel_all();
    for w in workers {
        let _ = w.await;
    }
    result.map_err(|e| ServiceError::Io {
        path: addr.to_string(),
        source: e,
    })
}

/// Runs `config.workers` workers (at least one) with no HTTP API until `shutdown` resolves:
/// `mpm worker`, on any number of machines sharing a PostgreSQL queue and a result folder
/// or bucket.
pub async fn work(
    config: Config,
    registry: Arc<Registry>,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<(), ServiceError> {
    let count = config.workers.max(1);
    let state = start(config, registry).await?;
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    let names: Vec<String> = (0..count).map(worker::worker_name).collect();
    println!("workers {} on {}", names.join(", "), state.db.backend());
    let workers: Vec<_> = names
        .into_iter()
        .map(|name| tokio::spawn(worker::run(state.clone(), name, stop_rx.clone())))
        .collect();
    shutdown.await;
    let _ = stop_tx.send(true);
    state.jobs.cancel_all();
    for w in workers {
        let _ = w.await;
    }
    Ok(())
}
