//! The job service across processes on a real PostgreSQL: the test starts its own server
//! (initdb in a temporary folder, a free loopback port, the socket in that folder), one API
//! process (`mpm serve --workers 0`) and two `mpm worker` processes, submits many jobs, kills
//! one worker with SIGKILL in the middle of a job, and checks that every job finished exactly
//! once with a complete store. Skips (with a message) only when no PostgreSQL binaries are
//! installed; `.ci/run` installs them.

use crate::common;

use common::jobs::{
    api_client as client, assert_png, check_runs, get_json, kill_worker, long_bar, small_bar,
    submit_job as submit, submit_long_then_small, tally, wait_for_all,
};
use common::postgres::{Postgres, postgres_bin};
use common::*;
use serde_json::{Value, json};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Small jobs submitted besides the one that is interrupted.
const SMALL_JOBS: usize = 100;

#[test]
fn two_workers_on_postgres_one_killed_every_job_runs_to_the_end_once() {
    let Some(bin) = postgres_bin() else {
        println!(
            "SKIPPED: no PostgreSQL binaries (initdb, pg_ctl, createdb, psql) found in $PG_BIN, \
             /usr/lib/postgresql/*/bin or the PATH; install the `postgresql` package (.ci/run does)"
        );
        return;
    };
    let pg = Postgres::start(bin);
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("store");
    let mpm = env!("CARGO_BIN_EXE_mpm");
    let (api, url) = serve(
        Command::new(mpm)
            .args(["serve", "--listen", "127.0.0.1:0", "--workers", "0"])
            .arg("--data")
            .arg(dir.path().join("api"))
            .arg("--store")
            .arg(&store)
            .args(["--database", &pg.url()])
            .env("RUST_LOG", "warn"),
    );
    let _api = Process(api);
    let start_worker = |n: usize| {
        let log = std::fs::File::create(dir.path().join(format!("worker{n}.log"))).unwrap();
        Process(
            Command::new(mpm)
                .args(["worker", "--database", &pg.url(), "--lease-seconds", "2"])
                .arg("--store")
                .arg(&store)
                .stdout(Stdio::null())
                .stderr(log)
                .spawn()
                .unwrap(),
        )
    };
    let mut workers = [Some(start_worker(1)), Some(start_worker(2))];

    // One job long enough to be caught running (a second or so), then the small ones.
    let start = Instant::now();
    let long = long_bar(1.0, 10);
    let ids = submit_long_then_small(&url, &long, &small_bar(), SMALL_JOBS);
    let long_id = ids[0].clone();

    // Kill (SIGKILL) whichever worker runs the long job once it has made progress.
    let killed_name = loop {
        let j = get_json(&format!("{url}/v1/jobs/{long_id}"));
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the long job never ran: {j}"
        );
        if j["status"] == "running" && j["progress"]["steps"].as_i64().unwrap_or(0) > 0 {
            let worker = j["worker"].as_str().unwrap().to_string();
            kill_worker(&mut workers, &worker);
            break worker;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let killed_at = start.elapsed();

    // Every job ends.
    let logs = || {
        (1..=2)
            .map(|n| {
                std::fs::read_to_string(dir.path().join(format!("worker{n}.log")))
                    .unwrap_or_default()
            })
            .collect::<String>()
    };
    let finals = wait_for_all(&url, &ids, start, Duration::from_secs(180), logs);
    let elapsed = start.elapsed();
    let (statuses, failures) = tally(&finals);

    // The runs table: exactly one successful run per job, nothing left open, and the only
    // other runs are the killed worker's, ended by its lease.
    let runs = pg.query("SELECT job_id, attempt, worker, COALESCE(outcome, 'open') FROM job_runs");
    let (per_job, duplicates) = check_runs(&runs, &ids, &killed_name);
    let mut long_runs = per_job[&long_id].clone();
    long_runs.sort_by_key(|r| r[1].parse::<i64>().unwrap());
    assert_eq!(
        long_runs.len(),
        2,
        "the interrupted job ran twice: {long_runs:?}"
    );
    assert_eq!(
        (
            long_runs[0][1].as_str(),
            long_runs[0][2].as_str(),
            long_runs[0][3].as_str()
        ),
        ("1", killed_name.as_str(), "lease_expired")
    );
    assert_eq!(
        (long_runs[1][1].as_str(), long_runs[1][3].as_str()),
        ("2", "succeeded")
    );
    assert_ne!(
        long_runs[1][2], killed_name,
        "the surviving worker reran it"
    );
    let attempts = pg.query("SELECT COUNT(*), SUM(attempts) FROM jobs");
    assert_eq!(attempts[0][0], ids.len().to_string());
    assert_eq!(attempts[0][1], runs.len().to_string(), "attempts = runs");

    // Every store is complete: all frames, and the metrics of a finished run.
    for id in &ids {
        let s = mpm_io::ResultStore::open(store.join(id).join("results.zarr")).unwrap();
        let frames = if *id == long_id { 11 } else { 5 };
        assert_eq!(s.frame_count().unwrap(), frames, "job {id}");
        assert_eq!(s.attributes()["metrics"]["outcome"], "finished", "job {id}");
    }
    // The interrupted job's rerun equals a local run.
    let job = get_json(&format!("{url}/v1/jobs/{long_id}"));
    let local_dir = tempfile::tempdir().unwrap();
    let path = write_scene(local_dir.path(), "long.json", &long);
    let local = run(&load(&path, &[]));
    assert_eq!(job["metrics"]["error"].as_f64(), local.error);

    // The API over PostgreSQL serves a job's scene, and its frame pictures from the shared
    // store.
    let scene = get_json(&format!("{url}/v1/jobs/{long_id}/scene"));
    assert_eq!(scene["name"], long["name"]);
    assert_png(&format!("{url}/v1/jobs/{long_id}/frames/-1.png"));

    // The surviving worker logged the requeueing, naming the worker that lost the job.
    let logs: String = (1..=2)
        .map(|n| std::fs::read_to_string(dir.path().join(format!("worker{n}.log"))).unwrap())
        .collect();
    assert!(
        logs.lines()
            .any(|l| l.contains("job requeued: its worker's lease ran out")
                && l.contains(&long_id)
                && l.contains(&killed_name)),
        "{logs}"
    );

    let metrics = client()
        .get(format!("{url}/metrics"))
        .send()
        .unwrap()
        .text()
        .unwrap();
    assert!(
        metrics.contains(&format!("mpm_jobs{{state=\"succeeded\"}} {}", ids.len())),
        "{metrics}"
    );
    // The API process runs no job, yet shows every job's times and both workers' heartbeats
    // (from the database); the killed worker's heartbeat is the older.
    for expected in [
        format!("mpm_job_queue_wait_seconds_count {}", ids.len()),
        format!("mpm_job_run_seconds_count {}", ids.len()),
    ] {
        assert!(metrics.contains(&expected), "{expected} in\n{metrics}");
    }
    let age = |worker: &str| -> f64 {
        metrics
            .lines()
            .find_map(|l| {
                l.strip_prefix(&format!(
                    "mpm_worker_heartbeat_age_seconds{{worker=\"{worker}\"}} "
                ))
            })
            .unwrap_or_else(|| panic!("no heartbeat of {worker} in\n{metrics}"))
            .parse()
            .unwrap()
    };
    let survivor = &long_runs[1][2];
    assert!(age(&killed_name) > age(survivor), "{metrics}");

    // A cancel made through the API reaches the worker on another process by its heartbeat.
    let mut endless = long.clone();
    endless["solver"]["end_time"] = json!(100.0);
    endless["output"]["frames"] = json!(1000);
    let cancel_id = submit(&url, &endless);
    let since = Instant::now();
    while get_json(&format!("{url}/v1/jobs/{cancel_id}"))["progress"]["steps"]
        .as_i64()
        .unwrap_or(0)
        == 0
    {
        assert!(since.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(20));
    }
    let cancelled: Value = client()
        .delete(format!("{url}/v1/jobs/{cancel_id}"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(cancelled["status"], "cancelled", "{cancelled}");
    assert_eq!(cancelled["metrics"]["outcome"], "cancelled");
    assert_eq!(
        pg.query(&format!(
            "SELECT outcome FROM job_runs WHERE job_id = '{cancel_id}'"
        )),
        vec![vec!["cancelled".to_string()]]
    );

    println!(
        "postgres: {} jobs, 2 workers (one killed with SIGKILL at {:.1} s in the middle of a job), \
         all ended in {:.1} s: {failures} failures, {duplicates} duplicate runs, {} runs lost to \
         the killed worker's lease",
        ids.len(),
        killed_at.as_secs_f64(),
        elapsed.as_secs_f64(),
        runs.len() - ids.len()
    );
    assert_eq!(failures, 0, "{statuses:?}");
}
