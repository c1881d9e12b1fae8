//! End-to-end tests of the job service: the real `mpm serve` binary on an ephemeral port
//! with a temporary data folder, driven over HTTP.

use crate::common;

use common::*;
use reqwest::blocking::Client;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

struct Server {
    child: Process,
    url: String,
}

impl Server {
    fn start(data: &Path, extra: &[&str]) -> Server {
        let (child, url) = serve(
            Command::new(env!("CARGO_BIN_EXE_mpm"))
                .args(["serve", "--listen", "127.0.0.1:0", "--data"])
                .arg(data)
                .args(extra),
        );
        Server {
            child: Process(child),
            url,
        }
    }

    fn kill(&mut self) {
        self.child.kill(); // SIGKILL
    }
}

fn client() -> Client {
    http_client(60)
}

fn submit(url: &str, scene: &Value) -> reqwest::blocking::Response {
    client()
        .post(format!("{url}/v1/jobs"))
        .json(scene)
        .send()
        .unwrap()
}

/// GET a URL and read its JSON body.
fn get_json(url: &str) -> Value {
    client().get(url).send().unwrap().json().unwrap()
}

fn job(url: &str, id: &str) -> Value {
    get_json(&format!("{url}/v1/jobs/{id}"))
}

fn wait_final(url: &str, id: &str, limit: Duration) -> Value {
    let start = Instant::now();
    loop {
        let j = job(url, id);
        if matches!(
            j["status"].as_str(),
            Some("succeeded" | "failed" | "cancelled")
        ) {
            return j;
        }
        assert!(start.elapsed() < limit, "job {id} did not finish: {j}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// `mpm fetch` of a job into a temporary folder; the folder and the store opened.
fn fetch(url: &str, id: &str, name: &str) -> (tempfile::TempDir, mpm_io::ResultStore) {
    let out = tempfile::tempdir().unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_mpm"))
        .args(["fetch", id, "--server", url, "--out"])
        .arg(out.path())
        .status()
        .unwrap();
    assert!(status.success());
    let store = mpm_io::ResultStore::open(out.path().join(format!("{name}.zarr"))).unwrap();
    (out, store)
}

fn small_bar(end_time: f64) -> Value {
    let mut s = bar_json();
    s["solver"]["end_time"] = json!(end_time);
    s["output"]["frames"] = json!(4);
    s
}

fn error_code(r: reqwest::blocking::Response) -> (u16, Value) {
    let status = r.status().as_u16();
    (status, r.json().unwrap_or(Value::Null))
}

#[test]
fn submit_watch_fetch_and_compare_with_a_local_run() {
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(data.path(), &[]);
    let r = submit(&server.url, &bar_json());
    assert_eq!(r.status().as_u16(), 202);
    let location = r.headers()["location"].to_str().unwrap().to_string();
    let accepted: Value = r.json().unwrap();
    let id = accepted["id"].as_str().unwrap().to_string();
    assert_eq!(location, format!("/v1/jobs/{id}"));

    // Server-sent events: progress events, then one final event, then the stream ends.
    let events = client()
        .get(format!("{}/v1/jobs/{id}/events", server.url))
        .send()
        .unwrap()
        .text()
        .unwrap();
    let finals: Vec<&str> = events.lines().filter(|l| *l == "event: final").collect();
    assert_eq!(finals.len(), 1, "{events}");
    let last_data = events.lines().rfind(|l| l.starts_with("data: ")).unwrap();
    let last: Value = serde_json::from_str(&last_data[6..]).unwrap();
    assert_eq!(last["status"], "succeeded");

    let done = job(&server.url, &id);
    assert_eq!(done["progress"]["fraction"], 1.0);
    assert!(done["progress"].get("stage").is_none(), "{done}");
    let local = run(&load_example("vibrating-bar.json", &[]));
    assert_eq!(done["metrics"]["error"].as_f64(), local.error);

    // `mpm fetch` brings the store home; it opens as a result store.
    let (_out, store) = fetch(&server.url, &id, "vibrating-bar");
    assert_eq!(store.frame_count().unwrap(), 41);

    // Listing with a status filter.
    let list: Value = get_json(&format!("{}/v1/jobs?status=succeeded", server.url));
    assert_eq!(list["total"], 1);
}

#[test]
fn bad_requests_get_json_errors_and_change_nothing() {
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(
        data.path(),
        &["--max-particles", "1000", "--max-body-bytes", "100000"],
    );
    let url = &server.url;
    let c = client();
    let post = |body: &str, content_type: &str| {
        c.post(format!("{url}/v1/jobs"))
            .header("content-type", content_type)
            .body(body.to_string())
            .send()
            .unwrap()
    };
    let (s, e) = error_code(post("{\"name\": ", "application/json"));
    assert_eq!((s, e["error"]["code"].as_str()), (400, Some("bad_json")));
    let (s, _) = error_code(post(&bar_json().to_string(), "text/plain"));
    assert_eq!(s, 415);
    let deep = "[".repeat(5000) + &"]".repeat(5000);
    let (s, e) = error_code(post(&deep, "application/json"));
    assert_eq!((s, e["error"]["code"].as_str()), (400, Some("bad_json")));
    let huge_number = bar_json()
        .to_string()
        .replace("\"end_time\":0.4", "\"end_time\":1e999");
    let (s, _) = error_code(post(&huge_number, "application/json"));
    assert_eq!(s, 400);
    let big = format!("{{\"name\": \"{}\"}}", "x".repeat(200_000));
    let (s, e) = error_code(post(&big, "application/json"));
    assert_eq!(
        (s, e["error"]["code"].as_str()),
        (413, Some("body_too_large"))
    );

    let mut bad = bar_json();
    bad["materials"]["bar"]["poisson_ratio"] = json!(0.7);
    let (s, e) = error_code(submit(url, &bad));
    assert_eq!(s, 422);
    assert_eq!(
        e["error"]["problems"][0]["path"],
        "materials.bar.poisson_ratio"
    );
    let mut file = bar_json();
    file["bodies"][0]["shape"] = json!({"file": {"path": "/etc/passwd", "format": "csv"}});
    let (s, e) = error_code(submit(url, &file));
    assert_eq!(
        (s, e["error"]["problems"][0]["path"].as_str()),
        (422, Some("bodies[0].shape.file"))
    );
    let (s, e) = error_code(submit(url, &{
        let mut s = bar_json();
        s["domain"]["cell_size"] = json!(0.0125);
        s
    }));
    assert_eq!(
        (s, e["error"]["code"].as_str()),
        (422, Some("too_many_particles"))
    );

    // Unknown jobs, ids that are not ids, paths that try to leave the store: 404 + JSON.
    let get = |path: &str| error_code(c.get(format!("{url}{path}")).send().unwrap());
    for path in [
        "/v1/jobs/not-an-id",
        "/v1/jobs/00000000-0000-0000-0000-000000000000",
        "/v1/jobs/00000000-0000-0000-0000-000000000000/events",
        "/v1/nothing-here",
    ] {
        let (s, e) = get(path);
        assert_eq!(
            (s, e["error"]["code"].as_str()),
            (404, Some("not_found")),
            "{path}"
        );
    }
    let r = submit(url, &small_bar(0.01));
    let id = r.json::<Value>().unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    wait_final(url, &id, Duration::from_secs(30));
    std::fs::write(data.path().join("secret.txt"), "secret").unwrap();
    for path in [
        "../../secret.txt",
        "..%2F..%2Fsecret.txt",
        "%2e%2e/%2e%2e/secret.txt",
        "%2Fetc%2Fpasswd",
        "particles/../../../secret.txt",
    ] {
        let (s, e) = get(&format!("/v1/jobs/{id}/results/{path}"));
        assert_eq!(s, 404, "{path}: {e}");
        assert!(!e.to_string().contains("secret\""), "{path}");
    }
    let (s, _) = get(&format!("/v1/jobs/{id}/results/zarr.json"));
    assert_eq!(s, 200);
    // Cancelling a finished job is a conflict.
    let (s, _) = error_code(c.delete(format!("{url}/v1/jobs/{id}")).send().unwrap());
    assert_eq!(s, 409);
    // Nothing above queued a job.
    let list: Value = c
        .get(format!("{url}/v1/jobs"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(list["total"], 1);
    // The server is still up.
    assert_eq!(get("/v1/health").0, 200);
}

#[test]
fn bearer_token_guards_every_route_but_health() {
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(data.path(), &["--token", "s3cret"]);
    let c = client();
    assert_eq!(
        c.get(format!("{}/v1/health", server.url))
            .send()
            .unwrap()
            .status(),
        200
    );
    let (s, e) = error_code(submit(&server.url, &small_bar(0.01)));
    assert_eq!(
        (s, e["error"]["code"].as_str()),
        (401, Some("unauthorized"))
    );
    let r = c
        .get(format!("{}/v1/jobs", server.url))
        .bearer_auth("wrong")
        .send()
        .unwrap();
    assert_eq!(r.status(), 401);
    let r = c
        .post(format!("{}/v1/jobs", server.url))
        .bearer_auth("s3cret")
        .json(&small_bar(0.01))
        .send()
        .unwrap();
    assert_eq!(r.status(), 202);
    let list: Value = c
        .get(format!("{}/v1/jobs", server.url))
        .bearer_auth("s3cret")
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(
        list["total"], 1,
        "the unauthorised submission queued nothing"
    );
}

#[test]
fn queue_limit_and_cancellation() {
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(data.path(), &["--max-queued", "2"]);
    let url = &server.url;
    // A long job occupies the worker.
    let long = {
        let mut s = bar_json();
        s["domain"]["cell_size"] = json!(0.0125);
        s["solver"]["end_time"] = json!(4.0);
        s
    };
    let running = submit(url, &long).json::<Value>().unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let start = Instant::now();
    while job(url, &running)["progress"]["steps"].as_i64().unwrap() == 0 {
        assert!(start.elapsed() < Duration::from_secs(30));
        std::thread::sleep(Duration::from_millis(20));
    }
    let q1 = submit(url, &small_bar(0.01)).json::<Value>().unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let _q2 = submit(url, &small_bar(0.01));
    let (s, e) = error_code(submit(url, &small_bar(0.01)));
    assert_eq!((s, e["error"]["code"].as_str()), (429, Some("queue_full")));
    // Cancel a queued job: it never runs.
    let c = client();
    let cancelled: Value = c
        .delete(format!("{url}/v1/jobs/{q1}"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(cancelled["status"], "cancelled");
    assert_eq!(cancelled["attempts"], 0);
    // Cancel the running one: it stops within a step and keeps what it wrote.
    let cancelled: Value = c
        .delete(format!("{url}/v1/jobs/{running}"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(cancelled["status"], "cancelled", "{cancelled}");
    assert_eq!(cancelled["metrics"]["outcome"], "cancelled");
    let store = data.path().join("jobs").join(&running).join("results.zarr");
    let frames = mpm_io::ResultStore::open(&store)
        .unwrap()
        .frame_count()
        .unwrap();
    assert!(frames >= 1);
}

#[test]
fn a_staged_scene_is_one_job_with_one_store() {
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(data.path(), &[]);
    let mut scene = bar_json();
    scene["name"] = json!("bar-staged");
    scene["output"]["frames"] = json!(4);
    scene["stages"] = json!([
        {"name": "first", "changes": {"solver": {"end_time": 0.1}}},
        {"name": "second", "changes": {"solver": {"end_time": 0.3, "transfer": "pic"}}}
    ]);
    let r = submit(&server.url, &scene);
    assert_eq!(r.status().as_u16(), 202);
    let id = r.json::<Value>().unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let done = wait_final(&server.url, &id, Duration::from_secs(60));
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["progress"]["end_time"], 0.3, "the last stage's end");
    assert_eq!(done["progress"]["stage"], "second", "{done}");
    let stages = done["metrics"]["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 2);
    assert_eq!(stages[1]["end_time"], 0.3);
    let (_out, store) = fetch(&server.url, &id, "bar-staged");
    assert_eq!(store.stages(), ["0-first", "1-second"]);
    assert_eq!(store.stage("second").unwrap().frame_count().unwrap(), 5);
    // A stage's problem is refused at submission with its path.
    scene["stages"][1]["changes"]["solver"]["end_time"] = json!(0.05);
    let (code, body) = error_code(submit(&server.url, &scene));
    assert_eq!(code, 422, "{body}");
    assert!(
        body.to_string()
            .contains("stages[1].changes.solver.end_time"),
        "{body}"
    );
}

#[test]
fn a_killed_server_resumes_its_jobs_with_the_same_results() {
    let data = tempfile::tempdir().unwrap();
    let mut scene = bar_json();
    scene["domain"]["cell_size"] = json!(0.0125);
    scene["solver"]["end_time"] = json!(1.2);
    scene["output"]["checkpoint"] = json!({"steps": 100});
    let mut server = Server::start(data.path(), &[]);
    let id = submit(&server.url, &scene).json::<Value>().unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let queued = submit(&server.url, &small_bar(0.02))
        .json::<Value>()
        .unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let start = Instant::now();
    while job(&server.url, &id)["progress"]["steps"].as_i64().unwrap() < 200 {
        assert!(start.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(20));
    }
    server.kill(); // kill -9 in the middle of the run
    let server = Server::start(data.path(), &[]);
    let done = wait_final(&server.url, &id, Duration::from_secs(120));
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["attempts"], 2, "the interrupted job ran again");
    // From its last checkpoint (taken every 100 steps; killed after step 200).
    let resumed = done["metrics"]["resumed_from_step"].as_u64();
    assert!(resumed.is_some_and(|s| s >= 200), "{done}");
    assert_eq!(
        wait_final(&server.url, &queued, Duration::from_secs(60))["status"],
        "succeeded"
    );

    // Same results as an uninterrupted local run, bit for bit.
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "scene.json", &scene);
    let local_store = dir.path().join("local.zarr");
    let metrics = run_to_store(&load(&path, &[]), &local_store);
    assert_eq!(done["metrics"]["error"].as_f64(), metrics.error);
    let remote: PathBuf = data.path().join("jobs").join(&id).join("results.zarr");
    let (a, b) = (
        mpm_io::ResultStore::open(&remote).unwrap(),
        mpm_io::ResultStore::open(&local_store).unwrap(),
    );
    let last = a.frame_count().unwrap() - 1;
    assert_eq!(last, b.frame_count().unwrap() - 1);
    assert_eq!(a.frame("x", last).unwrap(), b.frame("x", last).unwrap());
    assert_eq!(a.frame("v", last).unwrap(), b.frame("v", last).unwrap());
}

#[test]
fn a_burst_of_100_concurrent_jobs_all_finish_once() {
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(data.path(), &[]);
    let url = server.url.clone();
    let start = Instant::now();
    let handles: Vec<_> = (0..10)
        .map(|_| {
            let url = url.clone();
            std::thread::spawn(move || {
                (0..10)
                    .map(|_| {
                        let r = submit(&url, &small_bar(0.01));
                        assert_eq!(r.status().as_u16(), 202);
                        r.json::<Value>().unwrap()["id"]
                            .as_str()
                            .unwrap()
                            .to_string()
                    })
                    .collect::<Vec<_>>()
            })
        })
        .collect();
    let ids: Vec<String> = handles
        .into_iter()
        .flat_map(|h| h.join().unwrap())
        .collect();
    let submitted = start.elapsed();
    let unique: std::collections::BTreeSet<&String> = ids.iter().collect();
    assert_eq!(unique.len(), 100);
    let mut failures = 0;
    for id in &ids {
        if wait_final(&url, id, Duration::from_secs(120))["status"] != "succeeded" {
            failures += 1;
        }
    }
    let total = start.elapsed();
    let list: Value = get_json(&format!("{url}/v1/jobs?limit=1000"));
    assert_eq!(list["total"], 100, "none lost, none duplicated");
    let attempts: i64 = list["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["attempts"].as_i64().unwrap())
        .sum();
    assert_eq!(attempts, 100, "each job ran exactly once");
    println!(
        "burst: 100 jobs submitted from 10 threads in {:.2} s, all finished in {:.2} s, {failures} failures",
        submitted.as_secs_f64(),
        total.as_secs_f64()
    );
    assert_eq!(failures, 0);
}

/// (method, path, documented status codes) read from api/openapi.yaml. The file's layout
/// is fixed (two-space indents: paths at 2, methods at 4, response codes at 8), which this
/// reader relies on and checks.
fn documented_operations() -> Vec<(String, String, Vec<u16>)> {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../api/openapi.yaml"),
    )
    .unwrap();
    let mut in_paths = false;
    let mut path = String::new();
    let mut ops: Vec<(String, String, Vec<u16>)> = Vec::new();
    for line in text.lines() {
        if line == "paths:" {
            in_paths = true;
            continue;
        }
        if !in_paths {
            continue;
        }
        let method = line.strip_prefix("    ").and_then(|l| l.strip_suffix(':'));
        let code = line.strip_prefix("        '").and_then(|l| l.get(..3));
        if let Some(p) = line.strip_prefix("  /").and_then(|l| l.strip_suffix(':')) {
            path = format!("/{p}");
        } else if let Some(m) =
            method.filter(|m| ["get", "post", "delete", "put", "patch"].contains(m))
        {
            ops.push((m.to_string(), path.clone(), Vec::new()));
        } else if let (Some(Ok(code)), Some(op)) = (code.map(str::parse::<u16>), ops.last_mut()) {
            op.2.push(code);
        }
    }
    assert!(
        ops.iter().all(|o| !o.2.is_empty()),
        "every operation documents its responses"
    );
    ops
}

#[test]
fn the_server_and_openapi_yaml_agree() {
    let ops = documented_operations();
    let documented: std::collections::BTreeSet<(String, String)> =
        ops.iter().map(|(m, p, _)| (m.clone(), p.clone())).collect();
    let served: std::collections::BTreeSet<(String, String)> = mpm_service::ROUTES
        .iter()
        .map(|(m, p)| (m.to_string(), p.to_string()))
        .collect();
    assert_eq!(documented, served, "api/openapi.yaml and the router differ");

    // Every documented operation answers a live server with a documented status.
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(data.path(), &[]);
    let r = submit(&server.url, &small_bar(0.01));
    let id = r.json::<Value>().unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    wait_final(&server.url, &id, Duration::from_secs(30));
    let c = client();
    for (method, path, codes) in &ops {
        let concrete = path
            .replace("{id}", &id)
            .replace("{path}", "time/zarr.json")
            .replace("{frame}", "-1");
        let url = format!("{}{}", server.url, concrete);
        let response = match method.as_str() {
            "get" => c.get(&url).send().unwrap(),
            "post" => c.post(&url).json(&small_bar(0.01)).send().unwrap(),
            "delete" => c.delete(&url).send().unwrap(),
            other => panic!("undocumented method {other}"),
        };
        let status = response.status().as_u16();
        assert!(
            codes.contains(&status),
            "{method} {path} answered {status}, documented {codes:?}"
        );
        let missing = format!(
            "{}{}",
            server.url,
            path.replace("{id}", "00000000-0000-0000-0000-000000000000")
                .replace("{path}", "zarr.json")
                .replace("{frame}", "0")
        );
        if path.contains("{id}") && method == "get" {
            assert_eq!(
                c.get(&missing).send().unwrap().status(),
                404,
                "{path} with an unknown job"
            );
        }
    }
    // Routes not in the file do not exist.
    for (method, path) in [
        ("put", "/v1/jobs"),
        ("get", "/v1/job"),
        ("post", "/v1/health"),
        ("get", "/v2/jobs"),
    ] {
        let url = format!("{}{}", server.url, path);
        let status = c
            .request(method.parse().unwrap(), &url)
            .send()
            .unwrap()
            .status()
            .as_u16();
        assert!(
            status == 404 || status == 405,
            "{method} {path} answered {status}"
        );
    }
}

#[test]
fn a_study_runs_as_a_group_of_jobs_on_the_server() {
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(data.path(), &[]);
    let out = tempfile::tempdir().unwrap();
    let scene = example("vibrating-bar.json");
    let o = Command::new(env!("CARGO_BIN_EXE_mpm"))
        .args([
            "study",
            scene.to_str().unwrap(),
            "--vary",
            "cell_size=0.1,0.05",
            "--server",
            &server.url,
            "--out",
        ])
        .arg(out.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows: Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("study.json")).unwrap())
            .unwrap();
    let local = run(&load_example(
        "vibrating-bar.json",
        &["domain.cell_size=0.05"],
    ));
    assert_eq!(
        rows[1]["error"].as_f64(),
        local.error,
        "the server's run equals the local one"
    );
    let list: Value = get_json(&format!("{}/v1/jobs", server.url));
    assert_eq!(list["total"], 2);
}
