//! Workers: take queued jobs in order and run them with the solver on a blocking thread,
//! reporting progress at a bounded rate and honouring cancellation within one step.

use crate::child::ChildEnd;
use crate::{State, db};
use mpm_core::solver::{Control, Progress, RunError, run_scene};
use std::collections::HashMap;
use std::path::PathBuf;
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

/// Where a job's results live.
pub fn results_path(state: &State, id: &str) -> PathBuf {
    state
        .config
        .data_dir
        .join("jobs")
        .join(id)
        .join("results.zarr")
}

/// One worker's loop.
pub async fn run(state: Arc<State>, mut stop: watch::Receiver<bool>) {
    loop {
        if *stop.borrow() {
            return;
        }
        match db::claim(&state.db).await {
            Ok(Some((id, scene))) => run_job(&state, id, scene).await,
            Ok(None) => {
                tokio::select! {
                    _ = state.jobs.wake.notified() => {}
                    _ = tokio::time::sleep(Duration::from_millis(500)) => {}
                    _ = stop.changed() => {}
                }
            }
            Err(e) => {
                eprintln!("worker: claiming a job failed: {e}");
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
        }
    }
}

async fn run_job(state: &Arc<State>, id: String, scene: String) {
    let flag = state.jobs.register(&id);
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<(u64, f64, f64)>();
    let writer = {
        let db = state.db.clone();
        let id = id.clone();
        tokio::spawn(async move {
            while let Some((step, time, wall)) = rx.recv().await {
                if let Err(e) = db::progress(&db, &id, step, time, wall).await {
                    eprintln!("job {id}: writing progress failed: {e}");
                }
            }
        })
    };
    let last = Arc::new(Mutex::new((0u64, 0.0f64, 0.0f64)));
    let outcome = match &state.config.job_command {
        Some(command) => {
            let job_dir = results_path(state, &id)
                .parent()
                .map(PathBuf::from)
                .unwrap_or_default();
            crate::child::run_in_child(
                command,
                &job_dir,
                &state.config.data_dir,
                &scene,
                flag.clone(),
                tx,
                last.clone(),
            )
            .await
        }
        None => run_in_process(state, &id, scene, flag.clone(), tx, last.clone()).await,
    };
    let _ = writer.await;
    state.jobs.remove(&id);
    let progress = *last.lock().expect("progress lock");
    let failed =
        |message: String| serde_json::to_string(&serde_json::json!({ "message": message })).ok();
    let result = match outcome {
        ChildEnd::Metrics(m) => {
            let metrics = serde_json::to_string(&m).ok();
            match m["outcome"].as_str() {
                Some("finished") => {
                    db::finish(&state.db, &id, "succeeded", metrics, None, Some(progress)).await
                }
                Some("cancelled") if state.jobs.shutting_down.load(Ordering::Relaxed) => {
                    // Left `running`: the next start requeues it.
                    Ok(())
                }
                Some("cancelled") => {
                    db::finish(&state.db, &id, "cancelled", metrics, None, Some(progress)).await
                }
                _ => {
                    let failure = serde_json::to_string(&serde_json::json!({
                        "message": "the run stopped on a check",
                        "diagnostic": m["diagnostic"],
                    }))
                    .ok();
                    db::finish(&state.db, &id, "failed", metrics, failure, Some(progress)).await
                }
            }
        }
        ChildEnd::Refused(message) => {
            db::finish(&state.db, &id, "failed", None, failed(message), None).await
        }
        ChildEnd::Crashed(_) if state.jobs.shutting_down.load(Ordering::Relaxed) => Ok(()),
        ChildEnd::Crashed(message) => {
            eprintln!("job {id}: {message}");
            db::finish(
                &state.db,
                &id,
                "failed",
                None,
                failed(message),
                Some(progress),
            )
            .await
        }
    };
    if let Err(e) = result {
        eprintln!("job {id}: recording its end failed: {e}");
    }
}

/// Runs a job on a blocking thread of this process (when no job command is configured): a
/// panic fails the job, but an abort or exhausted memory takes the service down with it.
async fn run_in_process(
    state: &Arc<State>,
    id: &str,
    scene: String,
    cancel: Arc<AtomicBool>,
    tx: tokio::sync::mpsc::UnboundedSender<(u64, f64, f64)>,
    last: Arc<Mutex<(u64, f64, f64)>>,
) -> ChildEnd {
    let store = results_path(state, id);
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
        let mut sink = mpm_io::ZarrSink::new(&store);
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
        match run_scene(&validated, &mut sink, &mut observer) {
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
