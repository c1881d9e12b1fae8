//! Jobs in a process of their own: the worker starts the service's binary with its hidden
//! job subcommand (`mpm run-job`), which runs one scene and reports on stdout; a crash, a
//! panic or an exhausted memory limit there fails that job only.
//!
//! Protocol: the worker writes the scene to `jobs/<id>/scene.json` and starts
//! `PROGRAM ARGS... --scene FILE --store DIR --base DATA_DIR`, with `--from STORE [--stage
//! NAME]` for a job that starts from another job's stored state. The child prints one JSON
//! [`Report`] per line: progress at most every 200 ms, then the metrics or the refusal. A
//! line `cancel` on its stdin, or stdin closing (the service died), cancels the run within a
//! step; it keeps what it wrote.

use mpm_core::plugin::Registry;
use mpm_core::scene::Limits;
use mpm_core::solver::{Control, Progress, RunError};
use serde::{Deserialize, Serialize};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt};

/// How the service starts a job's process: the program and the arguments before the
/// job's own (`--scene`, `--store`, `--base`).
#[derive(Clone, Debug)]
pub struct JobCommand {
    /// The executable (the running `mpm`, so the child has the same plugins).
    pub program: PathBuf,
    /// Arguments naming the job subcommand and the limits.
    pub args: Vec<String>,
    /// Address-space limit of the child (RLIMIT_AS), bytes; `None`: no limit.
    pub memory_bytes: Option<u64>,
}

/// One line a job's process prints.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Report {
    /// Steps, simulated time and wall seconds so far.
    Progress(u64, f64, f64),
    /// The run ended (finished, stopped or cancelled) with these metrics.
    Metrics(serde_json::Value),
    /// The scene could not start (invalid, or refused by the solver).
    Refused(String),
}

/// Progress is reported at most this often.
const PROGRESS_INTERVAL: Duration = Duration::from_millis(200);

fn emit(out: &mut impl Write, report: &Report) {
    // The service may be gone (a broken pipe): the run then ends by the closed stdin.
    if let Ok(line) = serde_json::to_string(report) {
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
    }
}

/// The job subcommand: runs the scene in `scene` into the store `store` (from `start` when
/// given), reporting on stdout. Returns the exit code: 0 finished, 3 stopped or cancelled,
/// 2 refused, 1 failed.
pub fn run_job_process(
    registry: &Registry,
    scene: &Path,
    store: &Path,
    base: &Path,
    limits: &Limits,
    start: Option<&crate::JobStart>,
) -> u8 {
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = cancel.clone();
    std::thread::spawn(move || {
        let stdin = std::io::stdin();
        let mut lines = stdin.lock().lines();
        // Any line that says cancel, or the end of stdin, stops the run.
        while let Some(Ok(line)) = lines.next() {
            if line.trim() == "cancel" {
                break;
            }
        }
        flag.store(true, Ordering::Relaxed);
    });
    let mut out = std::io::stdout();
    let refuse = |out: &mut std::io::Stdout, message: String| {
        emit(out, &Report::Refused(message));
        2
    };
    let text = match std::fs::read_to_string(scene) {
        Ok(t) => t,
        Err(e) => return refuse(&mut out, format!("cannot read the job's scene: {e}")),
    };
    let value: serde_json::Value = match serde_json::from_str(&text) {
        Ok(v) => v,
        Err(e) => return refuse(&mut out, format!("stored scene is not JSON: {e}")),
    };
    let validated = match mpm_core::scene::parse_scene_value_limited(value, registry, base, limits)
    {
        Ok(v) => v,
        Err(e) => return refuse(&mut out, e.to_string()),
    };
    let last = Mutex::new((0u64, 0.0f64, 0.0f64));
    let mut next = Instant::now();
    let mut observer = |p: &Progress| {
        if Instant::now() >= next {
            next = Instant::now() + PROGRESS_INTERVAL;
            emit(
                &mut std::io::stdout(),
                &Report::Progress(p.step, p.time, p.wall_seconds),
            );
        }
        if let Ok(mut l) = last.lock() {
            *l = (p.step, p.time, p.wall_seconds);
        }
        if cancel.load(Ordering::Relaxed) {
            Control::Cancel
        } else {
            Control::Continue
        }
    };
    let result = crate::resume::run_or_resume(&validated, store, start, registry, &mut observer);
    let (step, time, wall) = last.lock().map(|l| *l).unwrap_or_default();
    emit(&mut out, &Report::Progress(step, time, wall));
    match result {
        Ok(m) => {
            let finished = m.outcome == Some(mpm_core::output::Outcome::Finished);
            emit(
                &mut out,
                &Report::Metrics(serde_json::to_value(&m).unwrap_or_default()),
            );
            if finished { 0 } else { 3 }
        }
        Err(RunError::Refused { path, message }) => refuse(&mut out, format!("{path}: {message}")),
        Err(e) => {
            emit(&mut out, &Report::Refused(e.to_string()));
            1
        }
    }
}

/// How a job's process ended, seen from the worker.
pub(crate) enum ChildEnd {
    /// It reported metrics.
    Metrics(serde_json::Value),
    /// It refused the scene or failed with a message.
    Refused(String),
    /// It died without a report (panic, signal, memory): what is known about it.
    Crashed(String),
}

/// Keeps the last `TAIL` bytes of the child's stderr for the job's diagnostic.
const TAIL: usize = 2000;

/// What a job's process is given: its folder, the folder particle files resolve against,
/// its scene (JSON text) and where it starts.
pub(crate) struct ChildJob<'a> {
    pub job_dir: &'a Path,
    pub base: &'a Path,
    pub scene: &'a str,
    pub start: Option<&'a crate::JobStart>,
}

/// Runs one job in a child process; progress goes to `progress` and `last`, `cancel` is
/// passed on as a `cancel` line.
pub(crate) async fn run_in_child(
    command: &JobCommand,
    ChildJob {
        job_dir,
        base,
        scene,
        start,
    }: ChildJob<'_>,
    cancel: Arc<AtomicBool>,
    progress: tokio::sync::mpsc::UnboundedSender<(u64, f64, f64)>,
    last: Arc<Mutex<(u64, f64, f64)>>,
) -> ChildEnd {
    let scene_file = job_dir.join("scene.json");
    if let Err(e) = tokio::fs::create_dir_all(job_dir).await {
        return ChildEnd::Crashed(format!("cannot create `{}`: {e}", job_dir.display()));
    }
    if let Err(e) = tokio::fs::write(&scene_file, scene).await {
        return ChildEnd::Crashed(format!("cannot write `{}`: {e}", scene_file.display()));
    }
    let mut cmd = tokio::process::Command::new(&command.program);
    cmd.args(&command.args)
        .arg("--scene")
        .arg(&scene_file)
        .arg("--store")
        .arg(job_dir.join("results.zarr"))
        .arg("--base")
        .arg(base);
    if let Some(start) = start {
        cmd.arg("--from").arg(&start.store);
        if let Some(stage) = &start.stage {
            cmd.arg("--stage").arg(stage);
        }
    }
    cmd.stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .kill_on_drop(false);
    limit_memory(&mut cmd, command.memory_bytes);
    let mut child = match cmd.spawn() {
        Ok(c) => c,
        Err(e) => {
            return ChildEnd::Crashed(format!(
                "cannot start the job's process `{}`: {e}",
                command.program.display()
            ));
        }
    };
    let mut stdin = child.stdin.take();
    let stderr = child.stderr.take();
    let tail = tokio::spawn(async move {
        let mut kept = Vec::new();
        if let Some(mut err) = stderr {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err.read(&mut buf).await {
                if n == 0 {
                    break;
                }
                kept.extend_from_slice(&buf[..n]);
                if kept.len() > TAIL {
                    kept.drain(..kept.len() - TAIL);
                }
            }
        }
        String::from_utf8_lossy(&kept).trim().to_string()
    });
    let mut end = None;
    if let Some(stdout) = child.stdout.take() {
        let mut lines = tokio::io::BufReader::new(stdout).lines();
        loop {
            tokio::select! {
                line = lines.next_line() => match line {
                    Ok(Some(line)) => match serde_json::from_str::<Report>(&line) {
                        Ok(Report::Progress(step, time, wall)) => {
                            let _ = progress.send((step, time, wall));
                            if let Ok(mut l) = last.lock() {
                                *l = (step, time, wall);
                            }
                        }
                        Ok(Report::Metrics(m)) => end = Some(ChildEnd::Metrics(m)),
                        Ok(Report::Refused(m)) => {
                            end = Some(ChildEnd::Refused(name_the_limit(m, command.memory_bytes)))
                        }
                        Err(_) => {}
                    },
                    Ok(None) | Err(_) => break,
                },
                _ = tokio::time::sleep(Duration::from_millis(50)), if stdin.is_some() => {
                    if cancel.load(Ordering::Relaxed)
                        && let Some(mut pipe) = stdin.take()
                    {
                        let _ = pipe.write_all(b"cancel\n").await;
                        let _ = pipe.flush().await;
                    }
                }
            }
        }
    }
    drop(stdin);
    let status = child.wait().await;
    let stderr = tail.await.unwrap_or_default();
    match (end, status) {
        (Some(end), Ok(s)) if matches!(s.code(), Some(0..=3)) => end,
        (_, Ok(s)) => ChildEnd::Crashed(describe_exit(s, command.memory_bytes, &stderr)),
        (_, Err(e)) => ChildEnd::Crashed(format!("waiting for the job's process failed: {e}")),
    }
}

/// A refusal for want of memory (a fallible allocation that failed, such as a body's
/// particles at validation) names the job's memory limit when it had one: under a limit the
/// same scene fails in validation or in the run, depending on what fills the address space.
fn name_the_limit(message: String, memory: Option<u64>) -> String {
    match memory {
        Some(m) if message.contains("memory allocation failed") => {
            format!(
                "{message} (the job's process memory limit is {} MB)",
                m / 1_000_000
            )
        }
        _ => message,
    }
}

/// Words for a child that ended without a report.
fn describe_exit(status: std::process::ExitStatus, memory: Option<u64>, stderr: &str) -> String {
    let limit = memory
        .map(|m| format!("; its memory limit is {} MB", m / 1_000_000))
        .unwrap_or_default();
    let how = match (status.code(), signal_of(status)) {
        (Some(101), _) => "the job's process panicked".to_string(),
        (Some(c), _) => format!("the job's process ended with exit code {c}"),
        (None, Some(6)) => {
            format!(
                "the job's process aborted (signal 6: a failed allocation, out of memory{limit})"
            )
        }
        (None, Some(9)) => {
            format!(
                "the job's process was killed (signal 9: the system's out-of-memory killer or an operator{limit})"
            )
        }
        (None, Some(s)) => format!("the job's process ended by signal {s}{limit}"),
        (None, None) => "the job's process ended without a status".to_string(),
    };
    if stderr.is_empty() {
        how
    } else {
        format!("{how}: {stderr}")
    }
}

#[cfg(unix)]
fn signal_of(status: std::process::ExitStatus) -> Option<i32> {
    std::os::unix::process::ExitStatusExt::signal(&status)
}

#[cfg(not(unix))]
fn signal_of(_: std::process::ExitStatus) -> Option<i32> {
    None
}

/// Sets the child's address-space limit (RLIMIT_AS) before it starts.
#[cfg(unix)]
fn limit_memory(cmd: &mut tokio::process::Command, bytes: Option<u64>) {
    let Some(bytes) = bytes else { return };
    let limit = libc::rlimit {
        rlim_cur: bytes as libc::rlim_t,
        rlim_max: bytes as libc::rlim_t,
    };
    // SAFETY: setrlimit is async-signal-safe and touches only the child between fork and
    // exec; `limit` is a plain value copied into the closure.
    unsafe {
        cmd.pre_exec(move || {
            if libc::setrlimit(libc::RLIMIT_AS, &limit) == 0 {
                Ok(())
            } else {
                Err(std::io::Error::last_os_error())
            }
        });
    }
}

#[cfg(not(unix))]
fn limit_memory(_: &mut tokio::process::Command, _: Option<u64>) {}

/// Half the machine's memory: the default memory limit of a job's process.
pub fn default_job_memory() -> Option<u64> {
    #[cfg(unix)]
    {
        // SAFETY: sysconf only reads system constants.
        let (pages, size) = unsafe {
            (
                libc::sysconf(libc::_SC_PHYS_PAGES),
                libc::sysconf(libc::_SC_PAGESIZE),
            )
        };
        if pages > 0 && size > 0 {
            return Some(pages as u64 * size as u64 / 2);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::name_the_limit;

    #[test]
    fn a_refusal_for_want_of_memory_names_the_limit() {
        let m = "bodies[0].shape: cannot hold 1.061e6 particles: memory allocation failed";
        assert!(name_the_limit(m.into(), Some(100_000_000)).ends_with("memory limit is 100 MB)"));
        assert_eq!(name_the_limit(m.into(), None), m);
        assert_eq!(
            name_the_limit("solver.cfl: bad".into(), Some(1)),
            "solver.cfl: bad"
        );
    }
}
