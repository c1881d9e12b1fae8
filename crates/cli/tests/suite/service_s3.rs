//! The job service with its results in an S3-compatible bucket and no shared folder: a real
//! PostgreSQL and a real moto server (both started by the test on free loopback ports), one
//! API process (`mpm serve --workers 0 --store s3://...`) and two `mpm worker` processes,
//! each with its own scratch folder. One worker is killed with SIGKILL in the middle of a
//! job after it uploaded a checkpoint; the other resumes the job from that checkpoint. Every
//! store is then read back through the API. Skips (with a message) when PostgreSQL or
//! `moto_server` is missing; `.ci/run` installs both.

use crate::common;

use common::jobs::{
    api_client as client, assert_png, assert_same_stage_frames, check_runs, get_json, kill_worker,
    long_bar, small_bar, staged_bar, submit_job, submit_job_from, submit_long_then_small, tally,
    wait_for_all,
};
use common::moto::{Moto, moto_server};
use common::postgres::{Postgres, postgres_bin};
use common::*;
use serde_json::{Value, json};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Small jobs submitted besides the one that is interrupted.
const SMALL_JOBS: usize = 100;
const BUCKET: &str = "mpm-results";
const PREFIX: &str = "runs/test";

/// Downloads a job's whole store through the API (`/files`, then each file from
/// `/results/...`, as a Zarr reader over HTTP would) into `to`.
fn fetch_store(url: &str, id: &str, to: &Path) -> Vec<String> {
    let files: Vec<String> =
        serde_json::from_value(get_json(&format!("{url}/v1/jobs/{id}/files"))["files"].clone())
            .unwrap();
    for file in &files {
        let r = client()
            .get(format!("{url}/v1/jobs/{id}/results/{file}"))
            .send()
            .unwrap();
        assert_eq!(r.status(), 200, "{file}");
        let kind = r.headers()["content-type"].to_str().unwrap().to_string();
        let expected = if file.ends_with(".json") {
            "application/json"
        } else {
            "application/octet-stream"
        };
        assert_eq!(kind, expected, "{file}");
        let path = to.join(file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, r.bytes().unwrap()).unwrap();
    }
    files
}

/// The files under `root` as sorted `/`-separated relative paths.
fn walk(root: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(root).unwrap();
                out.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    out.sort();
    out
}

/// `mpm serve` with a store that cannot be used exits 2 before listening, saying why.
fn refused(args: &[&str], moto: &Moto, dir: &Path) -> String {
    let out = moto
        .env(&mut Command::new(env!("CARGO_BIN_EXE_mpm")))
        .args(["serve", "--listen", "127.0.0.1:0", "--workers", "0"])
        .arg("--data")
        .arg(dir)
        .args(args)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(!text(&out).contains("listening"), "{}", text(&out));
    text(&out)
}

#[test]
fn two_workers_on_s3_one_killed_the_other_resumes_from_the_uploaded_checkpoint() {
    let (Some(pg_bin), Some(moto_bin)) = (postgres_bin(), moto_server()) else {
        println!(
            "SKIPPED: needs PostgreSQL (initdb, pg_ctl, createdb, psql in $PG_BIN, \
             /usr/lib/postgresql/*/bin or the PATH: the `postgresql` package) and moto's \
             `moto_server` ($MPM_MOTO_SERVER or .venv/bin/moto_server: `pip install -r \
             tests/python/requirements.txt`); .ci/run installs both"
        );
        return;
    };
    let began = Instant::now();
    let pg = Postgres::start(pg_bin);
    let moto = Moto::start(&moto_bin);
    moto.create_bucket(BUCKET);
    let dir = tempfile::tempdir().unwrap();
    let mpm = env!("CARGO_BIN_EXE_mpm");
    let store = format!("s3://{BUCKET}/{PREFIX}");

    // A malformed location and a missing bucket stop the service before it listens.
    let bad = refused(&["--store", "s3:///runs"], &moto, &dir.path().join("bad"));
    assert!(bad.contains("no bucket name"), "{bad}");
    let missing = refused(
        &[
            "--store",
            "s3://no-such-bucket/runs",
            "--database",
            &pg.url(),
        ],
        &moto,
        &dir.path().join("missing"),
    );
    assert!(
        missing.contains("bucket `no-such-bucket` not found"),
        "{missing}"
    );

    let setup = began.elapsed();
    let (api, url) = serve(
        moto.env(&mut Command::new(mpm))
            .args(["serve", "--listen", "127.0.0.1:0", "--workers", "0"])
            .arg("--data")
            .arg(dir.path().join("api"))
            .args(["--store", &store, "--database", &pg.url()])
            .env("RUST_LOG", "warn"),
    );
    let _api = Process(api);
    let scratch = |n: usize| dir.path().join(format!("scratch{n}"));
    let start_worker = |n: usize| {
        let log = std::fs::File::create(dir.path().join(format!("worker{n}.log"))).unwrap();
        Process(
            moto.env(&mut Command::new(mpm))
                .args(["worker", "--database", &pg.url(), "--lease-seconds", "2"])
                .args(["--store", &store])
                .arg("--scratch")
                .arg(scratch(n))
                .stdout(Stdio::null())
                .stderr(log)
                .spawn()
                .unwrap(),
        )
    };
    let mut workers = [Some(start_worker(1)), Some(start_worker(2))];
    let logs = || -> String {
        (1..=2)
            .map(|n| {
                std::fs::read_to_string(dir.path().join(format!("worker{n}.log")))
                    .unwrap_or_default()
            })
            .collect()
    };

    // One job long enough to write and upload checkpoints (a few seconds), then the small
    // ones.
    let start = Instant::now();
    let mut long = long_bar(4.0, 20);
    long["output"]["checkpoint"] = json!({"steps": 400});
    let small = small_bar();
    let ids = submit_long_then_small(&url, &long, &small, SMALL_JOBS);
    let long_id = ids[0].clone();

    // Once the bucket's copy of the long job names a checkpoint, kill (SIGKILL) its worker.
    let (killed_name, uploaded_step) = loop {
        assert!(
            start.elapsed() < Duration::from_secs(90),
            "no checkpoint of the long job was uploaded: {}\n{}",
            get_json(&format!("{url}/v1/jobs/{long_id}")),
            logs()
        );
        let root = client()
            .get(format!("{url}/v1/jobs/{long_id}/results/zarr.json"))
            .send()
            .unwrap();
        let step = if root.status() == 200 {
            root.json::<Value>().unwrap()["attributes"]["checkpoint"]["step"].as_u64()
        } else {
            None
        };
        let j = get_json(&format!("{url}/v1/jobs/{long_id}"));
        if let (Some(step), "running") = (step, j["status"].as_str().unwrap_or("")) {
            let worker = j["worker"].as_str().unwrap().to_string();
            kill_worker(&mut workers, &worker);
            break (worker, step);
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let killed_at = start.elapsed();

    // Every job ends (the limit is generous: the machine may be shared).
    let finals = wait_for_all(&url, &ids, start, Duration::from_secs(400), logs);
    let elapsed = start.elapsed();
    let (statuses, failures) = tally(&finals);
    assert_eq!(failures, 0, "{statuses:?}\n{finals:?}\n{}", logs());

    // Exactly one successful run per job; the only other run is the killed worker's.
    let runs = pg.query("SELECT job_id, attempt, worker, COALESCE(outcome, 'open') FROM job_runs");
    let (per_job, duplicates) = check_runs(&runs, &ids, &killed_name);
    let long_runs = &per_job[&long_id];
    assert_eq!(long_runs.len(), 2, "{long_runs:?}");
    let survivor = long_runs
        .iter()
        .find(|r| r[3] == "succeeded")
        .map(|r| r[2].clone())
        .unwrap();
    assert_ne!(survivor, killed_name, "the surviving worker reran it");

    // The survivor, on its own scratch folder, resumed from the checkpoint the killed one
    // uploaded (or a later one it uploaded before dying), and the result equals a local run
    // (resumed runs are bit-identical: tests/resume.rs).
    let long_job = &finals[&long_id];
    let resumed = long_job["metrics"]["resumed_from_step"].as_u64();
    assert!(
        resumed.is_some_and(|s| s >= uploaded_step),
        "resumed from {resumed:?}, uploaded {uploaded_step}: {long_job}"
    );
    let local_dir = tempfile::tempdir().unwrap();
    let local_store = |name: &str, scene: &Value| {
        let path = write_scene(local_dir.path(), &format!("{name}.json"), scene);
        let store = local_dir.path().join(format!("{name}.zarr"));
        let metrics = run_to_store(&load(&path, &[]), &store);
        // The checkpoint group is named by its step, which the resumed run reaches too.
        (metrics, walk(&store))
    };
    let (local, long_files) = local_store("long", &long);
    assert_eq!(long_job["metrics"]["error"].as_f64(), local.error);
    let (_, small_files) = local_store("small", &small);

    // Every store is whole as the API serves it: the same files as a local run of its scene
    // (the long job's: its last checkpoint only) and the metrics of a finished run. Every
    // tenth store, and the long one, is read whole through the API and opened.
    let read_at = Instant::now();
    let copies = tempfile::tempdir().unwrap();
    let check = |(n, id): (usize, &String)| -> usize {
        let listed: Vec<String> =
            serde_json::from_value(get_json(&format!("{url}/v1/jobs/{id}/files"))["files"].clone())
                .unwrap();
        let expected = if *id == long_id {
            &long_files
        } else {
            &small_files
        };
        assert_eq!(&listed, expected, "job {id}");
        let root = get_json(&format!("{url}/v1/jobs/{id}/results/zarr.json"));
        assert_eq!(
            root["attributes"]["metrics"]["outcome"], "finished",
            "job {id}"
        );
        if *id != long_id && n % 10 != 0 {
            return 0;
        }
        let to = copies.path().join(id);
        let files = fetch_store(&url, id, &to);
        let s = mpm_io::ResultStore::open(&to).unwrap();
        let frames = if *id == long_id { 21 } else { 5 };
        assert_eq!(s.frame_count().unwrap(), frames, "job {id}");
        assert_eq!(s.attributes()["metrics"]["outcome"], "finished", "job {id}");
        if *id == long_id {
            // The bucket holds exactly the served files, under the documented keys.
            let mut keys = moto.keys(BUCKET, &format!("{PREFIX}/{id}/results.zarr/"));
            keys.sort();
            let expected: Vec<String> = files
                .iter()
                .map(|f| format!("{PREFIX}/{id}/results.zarr/{f}"))
                .collect();
            assert_eq!(keys, expected);
        }
        files.len()
    };
    // Read by a few clients at once, as several readers would.
    let jobs: Vec<(usize, &String)> = ids.iter().enumerate().collect();
    let files_read: usize = std::thread::scope(|scope| {
        let readers: Vec<_> = jobs
            .chunks(jobs.len().div_ceil(4))
            .map(|chunk| scope.spawn(move || chunk.iter().copied().map(check).sum::<usize>()))
            .collect();
        readers.into_iter().map(|r| r.join().unwrap()).sum()
    });
    let read_time = read_at.elapsed();
    let missing = client()
        .get(format!(
            "{url}/v1/jobs/{long_id}/results/particles/nope/zarr.json"
        ))
        .send()
        .unwrap();
    assert_eq!(missing.status(), 404);
    assert_png(&format!("{url}/v1/jobs/{long_id}/frames/-1.png"));

    // A job that starts at a later stage of another job's store: the worker downloads only
    // the end state it starts from, and the stages it runs equal the whole job's.
    let staged = staged_bar();
    let whole_id = submit_job(&url, &staged);
    let whole = wait_for_all(
        &url,
        std::slice::from_ref(&whole_id),
        Instant::now(),
        Duration::from_secs(120),
        logs,
    );
    assert_eq!(whole[&whole_id]["status"], "succeeded", "{whole:?}");
    let from_id = submit_job_from(&url, &format!("?from={whole_id}&stage=second"), &staged);
    let from = wait_for_all(
        &url,
        std::slice::from_ref(&from_id),
        Instant::now(),
        Duration::from_secs(120),
        logs,
    );
    assert_eq!(
        from[&from_id]["status"],
        "succeeded",
        "{from:?}\n{}",
        logs()
    );
    let (a, b) = (copies.path().join("whole"), copies.path().join("from"));
    fetch_store(&url, &whole_id, &a);
    fetch_store(&url, &from_id, &b);
    for stage in ["second", "third"] {
        assert_same_stage_frames(&a, &b, stage);
    }

    // Nothing is left in the survivor's scratch folder: every store went to the bucket.
    let survivor_n = workers.iter().position(Option::is_some).unwrap() + 1;
    let left: Vec<_> = std::fs::read_dir(scratch(survivor_n))
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert!(left.is_empty(), "{left:?}");

    println!(
        "s3: {} jobs, 2 workers with their own scratch folders (one killed with SIGKILL at \
         {:.1} s, after it uploaded the checkpoint of step {uploaded_step}), all ended in \
         {:.1} s: {failures} failures, {duplicates} duplicate runs, {} runs lost to the killed \
         worker's lease; the long job resumed from step {} on the other worker; every store \
         listed and checked, {files_read} files of 11 of them read, through the API in {:.1} s; \
         set-up (PostgreSQL, moto, the refused starts) {:.1} s, the whole test {:.1} s; moto used \
         {:.1} s of CPU",
        ids.len(),
        killed_at.as_secs_f64(),
        elapsed.as_secs_f64(),
        runs.len() - ids.len(),
        resumed.unwrap_or(0),
        read_time.as_secs_f64(),
        setup.as_secs_f64(),
        began.elapsed().as_secs_f64(),
        moto.cpu_seconds().unwrap_or(f64::NAN)
    );
}
