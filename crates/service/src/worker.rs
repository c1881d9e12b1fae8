//! Workers: take queued jobs in order under a lease renewed by a heartbeat, run each in a
//! process of its own (or on a blocking thread), report progress at a bounded rate and honour
//! cancellation within one step. A job whose worker died goes back to the queue when its
//! lease runs out; any worker requeues it.

use crate::child::ChildEnd;
use crate::db::Claimed;
use crate::results_store::JobSync;
use crate::{JobStart, State};
use mpm_core::solver::{Control, Progress, RunError};
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::{Notify, watch};

/// Progress is written to the database at most this often per job.
const PROGRESS_INTERVAL: Duration = Duration::from_millis(200);

/// Cancellation flags of running jobs, and the bell that wakes idle workers.
#[derive(Default)]
pub struct JobBoard {
    flags: Mutex<HashMap<String, Arc<AtomicBool>>>,
    shutting_down: AtomicBool,
    /// Rung when a job is queued.
    pub wake: Notify,
}

impl JobBoard {
    fn register(&self, id: &str) -> Arc<AtomicBool> {
        let flag = Arc::new(AtomicBool::new(false));
        self.flags
            .lock()
            .expect("job board lock")
            .insert(id.to_string(), flag.clone());
        flag
    }

    fn remove(&self, id: &str) {
        self.flags.lock().expect("job board lock").remove(id);
    }

    /// Asks a running job to stop; returns whether it was running here.
    pub fn cancel(&self, id: &str) -> bool {
        match self.flags.lock().expect("job board lock").get(id) {
            Some(flag) => {
                flag.store(true, Ordering::Relaxed);
                true
            }
            None => false,
        }
    }

    /// Stops every running job for a shutdown (they are requeued on the next start).
    pub fn cancel_all(&self) {
        self.shutting_down.store(true, Ordering::Relaxed);
        for flag in self.flags.lock().expect("job board lock").values() {
            flag.store(true, Ordering::Relaxed);
        }
    }
}

/// A name for this process's `n`th worker that is unique across machines:
/// `host:pid:n`.
pub fn worker_name(n: usize) -> String {
    format!("{}:{}:{n}", host_name(), std::process::id())
}

/// This machine's host name (`localhost` when it cannot be read).
fn host_name() -> String {
    #[cfg(unix)]
    {
        let mut buf = [0u8; 256];
        // SAFETY: the buffer is valid for its length; gethostname writes at most that.
        let ok = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) } == 0;
        if ok {
            let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
            if let Ok(name) = std::str::from_utf8(&buf[..end])
                && !name.is_empty()
            {
                return name.to_string();
            }
        }
    }
    "localhost".to_string()
}

/// One worker's loop: requeue jobs whose lease ran out, claim the oldest queued job, run
/// it under a lease renewed by a heartbeat; until `stop`. On a stop, the jobs it was
/// running go back to the queue at once.
pub async fn run(state: Arc<State>, name: String, mut stop: watch::Receiver<bool>) {
    let lease = state.config.lease.as_secs_f64();
    seen(&state, &name).await;
    tracing::info!(worker = %name, database = state.db.backend(), "worker started");
    loop {
        if *stop.borrow() {
            break;
        }
        match state.db.requeue_expired().await {
            Ok(requeued) => {
                for r in requeued {
                    tracing::warn!(
                        job = %r.id,
                        lost_by = r.worker.as_deref().unwrap_or("?"),
                        status = %r.status,
                        "job requeued: its worker's lease ran out"
                    );
                }
            }
            Err(e) => {
                tracing::error!(worker = %name, error = %e, "requeueing expired leases failed")
            }
        }
        match state.db.claim(&name, lease).await {
            Ok(Some(claimed)) => {
                tracing::info!(
                    job = %claimed.id,
                    worker = %name,
                    attempt = claimed.attempt,
                    waited_s = claimed.waited,
                    "job claimed"
                );
                run_job(&state, &name, claimed).await;
            }
            Ok(None) => {
                tokio::select! {
                    _ = state.jobs.wake.notified() => {}
                    _ = tokio::time::sleep(state.config.poll) => {}
                    _ = stop.changed() => {}
                }
            }
            Err(e) => {
                tracing::error!(worker = %name, error = %e, "claiming a job failed");
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
        }
        seen(&state, &name).await;
    }
    match state.db.release(&name).await {
        Ok(released) => {
            for r in released {
                tracing::info!(job = %r.id, worker = %name, status = %r.status, "job requeued: its worker stopped");
            }
        }
        Err(e) => tracing::error!(worker = %name, error = %e, "giving back running jobs failed"),
    }
    if let Err(e) = state.db.worker_gone(&name).await {
        tracing::warn!(worker = %name, error = %e, "removing the worker's heartbeat failed");
    }
    tracing::info!(worker = %name, "worker stopped");
}

/// Records the worker's heartbeat (for `/metrics`); a failure is only logged.
async fn seen(state: &State, worker: &str) {
    if let Err(e) = state.db.worker_seen(worker).await {
        tracing::warn!(worker = %worker, error = %e, "recording the worker's heartbeat failed");
    }
}

/// Renews the lease of a running job every third of the lease; raises `cancel` when the
/// lease is lost or a cancellation was requested (possibly by an API process elsewhere).
/// Returns whether the lease was lost.
async fn keep_lease(
    state: Arc<State>,
    id: String,
    worker: String,
    cancel: Arc<AtomicBool>,
) -> bool {
    let lease = state.config.lease;
    // At least every second, so that a cancellation from an API process elsewhere is seen
    // within a second.
    let every = (lease / 3).clamp(Duration::from_millis(100), Duration::from_secs(1));
    loop {
        tokio::time::sleep(every).await;
        match state.db.heartbeat(&id, &worker, lease.as_secs_f64()).await {
            Ok(Some(cancel_requested)) => {
                seen(&state, &worker).await;
                if cancel_requested {
                    cancel.store(true, Ordering::Relaxed);
                }
            }
            Ok(None) => {
                tracing::warn!(job = %id, worker = %worker, "lease lost: stopping the run");
                cancel.store(true, Ordering::Relaxed);
                return true;
            }
            // A database hiccup: try again; the lease covers two more beats.
            Err(e) => tracing::warn!(job = %id, worker = %worker, error = %e, "heartbeat failed"),
        }
    }
}

/// How often a running job's store is looked at for a new checkpoint to upload (S3).
const CHECKPOINT_POLL: Duration = Duration::from_secs(1);

/// Uploads a running job's store whenever it names a new checkpoint (S3 stores; a no-op
/// for a folder), until `stop`; returns the mirror for the final upload.
async fn upload_checkpoints(
    mut sync: JobSync,
    id: String,
    mut stop: watch::Receiver<bool>,
) -> JobSync {
    if !sync.is_remote() {
        return sync;
    }
    loop {
        tokio::select! {
            _ = tokio::time::sleep(CHECKPOINT_POLL) => {}
            _ = stop.changed() => return sync,
        }
        match sync.checkpoint().await {
            Ok(Some(step)) => tracing::info!(job = %id, step, "checkpoint uploaded"),
            Ok(None) => {}
            Err(e) => tracing::warn!(job = %id, error = %e, "uploading a checkpoint failed"),
        }
    }
}

/// The job's heartbeat: `None` once it ended or was stopped.
type Heartbeat = Option<tokio::task::JoinHandle<bool>>;

/// JSON text of a failure with a message.
fn failure_text(message: String) -> Option<String> {
    serde_json::to_string(&serde_json::json!({ "message": message })).ok()
}

async fn run_job(state: &Arc<State>, worker: &str, claimed: Claimed) {
    let Claimed {
        id,
        scene,
        attempt,
        particles,
        from_job,
        from_stage,
        ..
    } = claimed;
    // The lease is renewed from the start: downloading and uploading a large store take
    // time too.
    let flag = state.jobs.register(&id);
    let mut heartbeat = Some(tokio::spawn(keep_lease(
        state.clone(),
        id.clone(),
        worker.to_string(),
        flag.clone(),
    )));
    // With an S3 store, an earlier attempt's store (and checkpoint) comes down first.
    let from = from_job.as_deref().map(|job| (job, from_stage.as_deref()));
    let end = match state.results.prepare(&id, attempt).await {
        Ok(sync) => match fetch_start(state, &id, &scene, from).await {
            Ok(start) => {
                let run = Run {
                    id: &id,
                    scene,
                    start,
                };
                run_attempt(state, worker, run, flag, sync, &mut heartbeat).await
            }
            Err(message) => {
                sync.discard().await;
                Some(("failed", None, failure_text(message), None))
            }
        },
        Err(e) => Some((
            "failed",
            None,
            failure_text(format!(
                "fetching the job's store from the result store failed: {e}"
            )),
            None,
        )),
    };
    state.jobs.remove(&id);
    // `None`: the lease was lost (another worker may own the job now), or the job goes
    // back to the queue as this worker stops; nothing is recorded.
    let Some(end) = end else { return };
    if lease_lost(&mut heartbeat).await {
        return;
    }
    if let Some(h) = heartbeat {
        h.abort();
    }
    record_end(state, &id, worker, attempt, particles, end).await;
}

/// The stored state a job starts from (`from`: the source job and stage), made local.
async fn fetch_start(
    state: &Arc<State>,
    id: &str,
    scene: &str,
    from: Option<(&str, Option<&str>)>,
) -> Result<Option<JobStart>, String> {
    match from {
        None => Ok(None),
        Some((source, stage)) => crate::start_state::fetch(state, id, scene, source, stage)
            .await
            .map(Some),
    }
}

/// One run of a claimed job: its id, its scene (JSON text) and where it starts.
struct Run<'a> {
    id: &'a str,
    scene: String,
    start: Option<JobStart>,
}

/// Runs a claimed job, uploading its store at checkpoints and at the end (S3); returns how
/// it ended, or `None` when nothing is to be recorded (see [`run_job`]).
async fn run_attempt(
    state: &Arc<State>,
    worker: &str,
    Run { id, scene, start }: Run<'_>,
    flag: Arc<AtomicBool>,
    sync: JobSync,
    heartbeat: &mut Heartbeat,
) -> Option<End> {
    let (stop_uploads, uploads_stop) = watch::channel(false);
    let uploads = tokio::spawn(upload_checkpoints(sync, id.to_string(), uploads_stop));
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<(u64, f64, f64)>();
    let writer = {
        let db = state.db.clone();
        let id = id.to_string();
        let worker = worker.to_string();
        tokio::spawn(async move {
            while let Some((step, time, wall)) = rx.recv().await {
                if let Err(e) = db.progress(&id, &worker, step, time, wall).await {
                    tracing::warn!(job = %id, error = %e, "writing progress failed");
                }
            }
        })
    };
    let last = Arc::new(Mutex::new((0u64, 0.0f64, 0.0f64)));
    let outcome = match &state.config.job_command {
        Some(command) => {
            let job = crate::child::ChildJob {
                job_dir: &state.results.job_dir(id),
                base: &state.config.data_dir,
                scene: &scene,
                start: start.as_ref(),
            };
            crate::child::run_in_child(command, job, flag.clone(), tx, last.clone()).await
        }
        None => {
            let run = Run { id, scene, start };
            run_in_process(state, run, flag.clone(), tx, last.clone()).await
        }
    };
    let _ = writer.await;
    let _ = stop_uploads.send(true);
    let sync = match uploads.await {
        Ok(sync) => Some(sync),
        Err(e) => {
            tracing::error!(job = %id, error = %e, "the checkpoint uploads failed unexpectedly");
            None
        }
    };
    if lease_lost(heartbeat).await {
        // Another worker may own the job now; nothing of this run is uploaded.
        if let Some(sync) = sync {
            sync.discard().await;
        }
        return None;
    }
    // The store goes up before the job's end is recorded, so a finished job's store is
    // whole when read; also when the job goes back to the queue (another machine resumes
    // it from what was uploaded). The lease is still renewed meanwhile.
    let uploaded = match sync {
        Some(sync) => sync.finish().await.map_err(|e| e.to_string()),
        None => Err("the upload task failed".to_string()),
    };
    if let Err(e) = &uploaded {
        tracing::error!(job = %id, error = %e, "uploading the job's store failed");
    }
    let progress = *last.lock().expect("progress lock");
    let shutting_down = state.jobs.shutting_down.load(Ordering::Relaxed);
    let (status, metrics, failure, progress) = match outcome {
        ChildEnd::Metrics(m) => {
            let metrics = serde_json::to_string(&m).ok();
            match m["outcome"].as_str() {
                Some("finished") => ("succeeded", metrics, None, Some(progress)),
                // Left `running`: the worker gives it back to the queue as it stops.
                Some("cancelled") if shutting_down => return None,
                Some("cancelled") => ("cancelled", metrics, None, Some(progress)),
                _ => {
                    let failure = serde_json::to_string(&serde_json::json!({
                        "message": "the run stopped on a check",
                        "diagnostic": m["diagnostic"],
                    }))
                    .ok();
                    ("failed", metrics, failure, Some(progress))
                }
            }
        }
        ChildEnd::Refused(message) => ("failed", None, failure_text(message), None),
        ChildEnd::Crashed(_) if shutting_down => return None,
        ChildEnd::Crashed(message) => ("failed", None, failure_text(message), Some(progress)),
    };
    Some(match uploaded {
        Err(e) if status != "cancelled" => (
            "failed",
            metrics,
            failure_text(format!("the run ended but uploading its store failed: {e}")),
            progress,
        ),
        _ => (status, metrics, failure, progress),
    })
}

/// Whether the job's heartbeat ended because the lease was lost (it runs until aborted
/// otherwise); a heartbeat that ended is taken out.
async fn lease_lost(heartbeat: &mut Heartbeat) -> bool {
    match heartbeat.take_if(|h| h.is_finished()) {
        Some(h) => h.await.unwrap_or(false),
        None => false,
    }
}

/// What a run ends with: status, metrics, failure (JSON text) and last progress.
type End = (
    &'static str,
    Option<String>,
    Option<String>,
    Option<(u64, f64, f64)>,
);

/// Records a run's end (under its lease) and logs it.
async fn record_end(
    state: &Arc<State>,
    id: &str,
    worker: &str,
    attempt: i64,
    particles: i64,
    (status, metrics, failure, progress): End,
) {
    let failure_message = failure.clone();
    match state
        .db
        .finish(id, worker, attempt, status, metrics, failure, progress)
        .await
    {
        Ok(true) => {
            let (steps, _, wall) = progress.unwrap_or_default();
            let rate = if wall > 0.0 {
                steps as f64 * particles as f64 / wall
            } else {
                0.0
            };
            if status == "failed" {
                tracing::warn!(job = %id, worker = %worker, status, failure = failure_message.as_deref().unwrap_or(""), "job failed");
            } else {
                tracing::info!(
                    job = %id,
                    worker = %worker,
                    status,
                    steps,
                    wall_s = wall,
                    particle_steps_per_s = rate,
                    "job finished"
                );
            }
        }
        Ok(false) => tracing::warn!(
            job = %id,
            worker = %worker,
            "the run ended after its lease ran out; its result is not recorded"
        ),
        Err(e) => tracing::error!(job = %id, error = %e, "recording the job's end failed"),
    }
}

/// Runs a job on a blocking thread of this process (when no job command is configured): a
/// panic fails the job, but an abort or exhausted memory takes the service down with it.
async fn run_in_process(
    state: &Arc<State>,
    Run { id, scene, start }: Run<'_>,
    cancel: Arc<AtomicBool>,
    tx: tokio::sync::mpsc::UnboundedSender<(u64, f64, f64)>,
    last: Arc<Mutex<(u64, f64, f64)>>,
) -> ChildEnd {
    let store = state.results.results_dir(id);
    let registry = state.registry.clone();
    let data_dir = state.config.data_dir.clone();
    let limits = state.config.limits;
    let outcome = tokio::task::spawn_blocking(move || -> ChildEnd {
        let value: serde_json::Value = match serde_json::from_str(&scene) {
            Ok(v) => v,
            Err(e) => return ChildEnd::Refused(format!("stored scene is not JSON: {e}")),
        };
        let validated = match mpm_core::scene::parse_scene_value_limited(
            value, &registry, &data_dir, &limits,
        ) {
            Ok(v) => v,
            Err(e) => return ChildEnd::Refused(e.to_string()),
        };
        let mut next = Instant::now();
        let mut observer = |p: &Progress| {
            if Instant::now() >= next {
                next = Instant::now() + PROGRESS_INTERVAL;
                let _ = tx.send((p.step, p.time, p.wall_seconds));
            }
            *last.lock().expect("progress lock") = (p.step, p.time, p.wall_seconds);
            if cancel.load(Ordering::Relaxed) {
                Control::Cancel
            } else {
                Control::Continue
            }
        };
        let run = crate::resume::run_or_resume(
            &validated,
            &store,
            start.as_ref(),
            &registry,
            &mut observer,
        );
        match run {
            Ok(m) => ChildEnd::Metrics(serde_json::to_value(&m).unwrap_or_default()),
            Err(RunError::Refused { path, message }) => {
                ChildEnd::Refused(format!("{path}: {message}"))
            }
            Err(e) => ChildEnd::Refused(e.to_string()),
        }
    })
    .await;
    outcome.unwrap_or_else(|panic| {
        ChildEnd::Crashed(format!("the solver failed unexpectedly: {panic}"))
    })
}
