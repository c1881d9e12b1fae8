//! Helpers of the tests that drive a job service of several processes over HTTP: submit,
//! wait, kill a worker, and check the `job_runs` table.

use super::{Process, http_client};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// The vibrating bar at 0.0125 m cells run to `end_time` with `frames` frames: a job of
/// about 1,300 steps per simulated second, long enough to be caught running.
pub fn long_bar(end_time: f64, frames: u64) -> Value {
    let mut long = super::bar_json();
    long["domain"]["cell_size"] = json!(0.0125);
    long["solver"]["end_time"] = json!(end_time);
    long["output"]["frames"] = json!(frames);
    long
}

/// The vibrating bar run for 0.01 s with 4 frames: a job of a few steps.
pub fn small_bar() -> Value {
    let mut small = super::bar_json();
    small["solver"]["end_time"] = json!(0.01);
    small["output"]["frames"] = json!(4);
    small
}

/// Submits `long`, then `count` copies of `small`; returns the ids, the long job's first.
pub fn submit_long_then_small(url: &str, long: &Value, small: &Value, count: usize) -> Vec<String> {
    let mut ids = vec![submit_job(url, long)];
    ids.extend((0..count).map(|_| submit_job(url, small)));
    ids
}

/// The vibrating bar in three stages (to 0.1 s; to 0.2 s with PIC; to 0.3 s), 4 frames each,
/// every stage keeping the state it ended with, so a job can start at any later stage.
pub fn staged_bar() -> Value {
    let mut scene = super::bar_json();
    scene["name"] = json!("bar-stages");
    scene["output"]["frames"] = json!(4);
    scene["output"]["end_state"] = json!(true);
    scene["stages"] = json!([
        {"name": "first", "changes": {"solver": {"end_time": 0.1}}},
        {"name": "second", "changes": {"solver": {"end_time": 0.2, "transfer": "pic"}}},
        {"name": "third", "changes": {"solver": {"end_time": 0.3}}}
    ]);
    scene
}

/// Asserts the stage `stage` of the stores at `a` and `b` has the same frame times and
/// positions, velocities and stresses, bit for bit.
pub fn assert_same_stage_frames(a: &std::path::Path, b: &std::path::Path, stage: &str) {
    let open = |p: &std::path::Path| mpm_io::ResultStore::open(p).unwrap().stage(stage).unwrap();
    let (a, b) = (open(a), open(b));
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    assert_eq!(
        bits(&a.times().unwrap()),
        bits(&b.times().unwrap()),
        "{stage}"
    );
    for frame in 0..a.frame_count().unwrap() {
        for field in ["x", "v", "stress"] {
            assert_eq!(
                bits(&a.frame(field, frame).unwrap().1),
                bits(&b.frame(field, frame).unwrap().1),
                "{stage}: {field} differs at frame {frame}"
            );
        }
    }
}

/// A client for the API (requests give up after a minute).
pub fn api_client() -> reqwest::blocking::Client {
    http_client(60)
}

/// Submits `scene` (must be accepted: 202) and returns the job's id.
pub fn submit_job(url: &str, scene: &Value) -> String {
    submit_job_from(url, "", scene)
}

/// Submits `scene` with the query `query` (`?from=JOB[&stage=NAME]`, or empty); it must be
/// accepted (202). Returns the job's id.
pub fn submit_job_from(url: &str, query: &str, scene: &Value) -> String {
    let r = api_client()
        .post(format!("{url}/v1/jobs{query}"))
        .json(scene)
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 202);
    r.json::<Value>().unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string()
}

/// The JSON body of a GET.
pub fn get_json(url: &str) -> Value {
    api_client().get(url).send().unwrap().json().unwrap()
}

/// Fetches `url` and checks it is a PNG (200, the PNG signature).
pub fn assert_png(url: &str) {
    let picture = api_client().get(url).send().unwrap();
    assert_eq!(picture.status(), 200, "{url}");
    assert!(
        picture.bytes().unwrap().starts_with(b"\x89PNG\r\n\x1a\n"),
        "{url}"
    );
}

/// Waits until every job of `ids` has ended; returns each one's final state. Fails, with
/// `context()` (the workers' logs), when a job has not ended `limit` after `start`.
pub fn wait_for_all(
    url: &str,
    ids: &[String],
    start: Instant,
    limit: Duration,
    context: impl Fn() -> String,
) -> BTreeMap<String, Value> {
    let mut finals = BTreeMap::new();
    for id in ids {
        let j = loop {
            let j = get_json(&format!("{url}/v1/jobs/{id}"));
            if matches!(
                j["status"].as_str(),
                Some("succeeded" | "failed" | "cancelled")
            ) {
                break j;
            }
            assert!(
                start.elapsed() < limit,
                "job {id} did not end: {j}\nworker logs:\n{}",
                context()
            );
            std::thread::sleep(Duration::from_millis(50));
        };
        finals.insert(id.clone(), j);
    }
    finals
}

/// How many of the `finals` (from [`wait_for_all`]) ended in each state, and how many did
/// not succeed.
pub fn tally(finals: &BTreeMap<String, Value>) -> (BTreeMap<String, usize>, usize) {
    let mut statuses = BTreeMap::new();
    for j in finals.values() {
        *statuses
            .entry(j["status"].as_str().unwrap_or("?").to_string())
            .or_insert(0) += 1;
    }
    let failures = finals.len() - statuses.get("succeeded").copied().unwrap_or(0);
    (statuses, failures)
}

/// Kills (SIGKILL) and reaps the process of `workers` that the worker name `host:pid:n`
/// names, leaving its slot empty.
pub fn kill_worker(workers: &mut [Option<Process>], name: &str) {
    let slot = workers
        .iter_mut()
        .find(|w| {
            w.as_ref()
                .is_some_and(|p| name.contains(&format!(":{}:", p.0.id())))
        })
        .expect("the job's worker is one of ours");
    slot.take().unwrap().kill();
}

/// Checks the `job_runs` rows (job, attempt, worker, outcome): every job of `ids` ran and
/// succeeded exactly once, and every other run is `killed`'s, ended by its lease. Returns
/// the rows by job and the count of duplicate successful runs (0 when the checks passed).
pub fn check_runs(
    runs: &[Vec<String>],
    ids: &[String],
    killed: &str,
) -> (BTreeMap<String, Vec<Vec<String>>>, usize) {
    let mut per_job: BTreeMap<String, Vec<Vec<String>>> = BTreeMap::new();
    for r in runs {
        per_job.entry(r[0].clone()).or_default().push(r.clone());
    }
    assert_eq!(per_job.len(), ids.len(), "every job ran");
    let mut duplicates = 0;
    for id in ids {
        let mine = &per_job[id];
        let succeeded = mine.iter().filter(|r| r[3] == "succeeded").count();
        duplicates += succeeded.saturating_sub(1);
        assert_eq!(succeeded, 1, "job {id} succeeded once: {mine:?}");
        for r in mine.iter().filter(|r| r[3] != "succeeded") {
            assert_eq!(r[3], "lease_expired", "{r:?}");
            assert_eq!(r[2], killed, "only the killed worker lost a run: {r:?}");
        }
    }
    (per_job, duplicates)
}
