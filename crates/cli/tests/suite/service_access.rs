//! The job service's users (a token file), its bounds on a job's work, its structured logs
//! and `/metrics`: the real `mpm serve` on SQLite, driven over HTTP.

use crate::common;

use common::*;
use reqwest::blocking::{Client, RequestBuilder};
use serde_json::{Value, json};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// `mpm serve` killed when dropped; its stderr (the log) goes to a file.
struct Server {
    _child: Process,
    url: String,
    log: std::path::PathBuf,
}

impl Server {
    fn start(data: &Path, extra: &[&str]) -> Server {
        let log = data.with_extension("log");
        let (child, url) = serve(
            Command::new(env!("CARGO_BIN_EXE_mpm"))
                .args(["serve", "--listen", "127.0.0.1:0", "--data"])
                .arg(data)
                .args(extra)
                .env_remove("RUST_LOG")
                .stderr(std::fs::File::create(&log).unwrap()),
        );
        Server {
            _child: Process(child),
            url,
            log,
        }
    }

    /// The JSON log lines so far.
    fn log_lines(&self) -> Vec<Value> {
        std::fs::read_to_string(&self.log)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON: {l}: {e}")))
            .collect()
    }
}

fn client() -> Client {
    http_client(60)
}

fn small_bar() -> Value {
    let mut s = bar_json();
    s["solver"]["end_time"] = json!(0.01);
    s["output"]["frames"] = json!(4);
    s
}

/// Status and JSON body of a request.
fn send(r: RequestBuilder) -> (u16, Value) {
    let r = r.send().unwrap();
    let status = r.status().as_u16();
    (status, r.json().unwrap_or(Value::Null))
}

fn hex(bytes: [u8; 32]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn users_see_list_and_cancel_only_their_own_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let tokens = dir.path().join("tokens");
    std::fs::write(
        &tokens,
        format!(
            "# name role sha256(token)\nalice user {}\nbob user {}\nops admin {}\n",
            hex(mpm_service::token_hash("alice-token")),
            hex(mpm_service::token_hash("bob-token")),
            hex(mpm_service::token_hash("ops-token"))
        ),
    )
    .unwrap();
    assert!(
        !std::fs::read_to_string(&tokens)
            .unwrap()
            .contains("alice-token"),
        "the file holds hashes only"
    );
    // No workers: jobs stay queued, so the per-user queue limit shows.
    let server = Server::start(
        &dir.path().join("data"),
        &[
            "--workers",
            "0",
            "--max-queued-per-user",
            "2",
            "--log-format",
            "json",
            "--tokens",
            tokens.to_str().unwrap(),
        ],
    );
    let url = &server.url;
    let c = client();
    let as_user = |r: RequestBuilder, token: &str| send(r.bearer_auth(token));
    let submit = |token: &str| as_user(c.post(format!("{url}/v1/jobs")).json(&small_bar()), token);

    // Health needs no token; everything else a known one (401 with the JSON error body).
    assert_eq!(send(c.get(format!("{url}/v1/health"))).0, 200);
    let (s, e) = send(c.get(format!("{url}/v1/jobs")));
    assert_eq!(
        (s, e["error"]["code"].as_str()),
        (401, Some("unauthorized"))
    );
    let (s, e) = submit("alice-token2");
    assert_eq!(
        (s, e["error"]["code"].as_str()),
        (401, Some("unauthorized"))
    );

    let (s, a1) = submit("alice-token");
    assert_eq!(s, 202, "{a1}");
    assert_eq!(a1["owner"], "alice");
    let a1 = a1["id"].as_str().unwrap().to_string();
    let (s, a2) = submit("alice-token");
    assert_eq!(s, 202);
    let a2 = a2["id"].as_str().unwrap().to_string();
    // Alice's share of the queue is full; Bob's is not.
    let (s, e) = submit("alice-token");
    assert_eq!(
        (s, e["error"]["code"].as_str()),
        (429, Some("user_queue_full"))
    );
    let (s, b1) = submit("bob-token");
    assert_eq!(s, 202);
    let b1 = b1["id"].as_str().unwrap().to_string();

    // Each user lists their own jobs; the admin lists all, or one owner's.
    let (_, list) = as_user(c.get(format!("{url}/v1/jobs")), "alice-token");
    assert_eq!(list["total"], 2);
    assert!(
        list["jobs"]
            .as_array()
            .unwrap()
            .iter()
            .all(|j| j["owner"] == "alice")
    );
    let (_, list) = as_user(c.get(format!("{url}/v1/jobs")), "bob-token");
    assert_eq!(list["total"], 1);
    let (_, list) = as_user(c.get(format!("{url}/v1/jobs")), "ops-token");
    assert_eq!(list["total"], 3);
    let (_, list) = as_user(c.get(format!("{url}/v1/jobs?owner=bob")), "ops-token");
    assert_eq!(list["total"], 1);
    let (s, e) = as_user(c.get(format!("{url}/v1/jobs?owner=bob")), "alice-token");
    assert_eq!((s, e["error"]["code"].as_str()), (403, Some("forbidden")));

    // Another user's job is unknown (404), for reading, its files, events and cancelling.
    for path in ["", "/files", "/events", "/results/zarr.json"] {
        let (s, e) = as_user(c.get(format!("{url}/v1/jobs/{b1}{path}")), "alice-token");
        assert_eq!(
            (s, e["error"]["code"].as_str()),
            (404, Some("not_found")),
            "{path}"
        );
    }
    let (s, _) = as_user(c.delete(format!("{url}/v1/jobs/{b1}")), "alice-token");
    assert_eq!(s, 404);
    let (s, job) = as_user(c.get(format!("{url}/v1/jobs/{b1}")), "bob-token");
    assert_eq!((s, job["status"].as_str()), (200, Some("queued")));
    // Alice cancels her own; the admin cancels Bob's.
    let (s, job) = as_user(c.delete(format!("{url}/v1/jobs/{a1}")), "alice-token");
    assert_eq!((s, job["status"].as_str()), (200, Some("cancelled")));
    let (s, job) = as_user(c.delete(format!("{url}/v1/jobs/{b1}")), "ops-token");
    assert_eq!((s, job["status"].as_str()), (200, Some("cancelled")));
    let (s, job) = as_user(c.get(format!("{url}/v1/jobs/{a2}")), "ops-token");
    assert_eq!((s, job["owner"].as_str()), (200, Some("alice")));

    // /metrics is the admin's.
    let (s, e) = as_user(c.get(format!("{url}/metrics")), "alice-token");
    assert_eq!((s, e["error"]["code"].as_str()), (403, Some("forbidden")));
    let r = c
        .get(format!("{url}/metrics"))
        .bearer_auth("ops-token")
        .send()
        .unwrap();
    assert_eq!(r.status(), 200);
    let exposition = r.text().unwrap();
    assert!(
        exposition.contains("mpm_jobs{state=\"queued\"} 1"),
        "{exposition}"
    );
    assert!(
        exposition.contains("mpm_jobs{state=\"cancelled\"} 2"),
        "{exposition}"
    );

    // One JSON log line per request, with the user.
    let logs = server.log_lines();
    let request = |method: &str, status: u64, user: &str| {
        logs.iter().any(|l| {
            l["message"] == "request"
                && l["method"] == method
                && l["path"] == "/v1/jobs"
                && l["status"] == status
                && l["user"] == user
                && l["duration_ms"].as_f64().is_some()
        })
    };
    assert!(request("POST", 202, "alice"), "{logs:?}");
    assert!(request("POST", 429, "alice"), "{logs:?}");
    assert!(request("GET", 401, "-"), "{logs:?}");
    assert!(
        logs.iter().any(|l| l["message"] == "job queued"
            && l["owner"] == "bob"
            && l["job"] == b1.as_str())
    );

    // A bad token file stops the server before it starts, naming the line.
    std::fs::write(&tokens, "alice user 12345\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_mpm"))
        .args(["serve", "--listen", "127.0.0.1:0", "--tokens"])
        .arg(&tokens)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("line 1"), "{}", text(&o));
}

#[test]
fn grid_and_step_bounds_are_refused_at_submission_with_the_json_path() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(
        &dir.path().join("data"),
        &[
            "--workers",
            "0",
            "--max-grid-bytes",
            "100000",
            "--max-steps",
            "1000",
        ],
    );
    let c = client();
    let submit = |scene: &Value| send(c.post(format!("{}/v1/jobs", server.url)).json(scene));
    let problem = |(status, body): (u16, Value)| {
        (
            status,
            body["error"]["problems"][0]["path"]
                .as_str()
                .unwrap_or("")
                .to_string(),
            body["error"]["problems"][0]["message"]
                .as_str()
                .unwrap_or("")
                .to_string(),
        )
    };
    // The example itself fits: about 320 grid nodes, 440 steps.
    assert_eq!(submit(&bar_json()).0, 202);
    let mut fine = bar_json();
    fine["domain"]["cell_size"] = json!(0.01);
    let (s, path, message) = problem(submit(&fine));
    assert_eq!((s, path.as_str()), (422, "domain.cell_size"), "{message}");
    assert!(message.contains("--max-grid-bytes"), "{message}");
    let mut long = bar_json();
    long["solver"]["end_time"] = json!(4.0);
    let (s, path, message) = problem(submit(&long));
    assert_eq!((s, path.as_str()), (422, "solver.end_time"), "{message}");
    assert!(message.contains("--max-steps"), "{message}");
    let mut fixed = bar_json();
    fixed["solver"]["dt"] = json!(1e-4);
    let (s, path, _) = problem(submit(&fixed));
    assert_eq!((s, path.as_str()), (422, "solver.dt"));
    let list: Value = c
        .get(format!("{}/v1/jobs", server.url))
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(list["total"], 1, "refused scenes queue nothing");
}

#[test]
fn job_transitions_are_logged_and_counted_in_metrics() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&dir.path().join("data"), &["--log-format", "json"]);
    let c = client();
    let id = send(c.post(format!("{}/v1/jobs", server.url)).json(&small_bar())).1["id"]
        .as_str()
        .unwrap()
        .to_string();
    let start = Instant::now();
    loop {
        let (_, j) = send(c.get(format!("{}/v1/jobs/{id}", server.url)));
        if j["status"] == "succeeded" {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "{j}");
        std::thread::sleep(Duration::from_millis(50));
    }
    let text = c
        .get(format!("{}/metrics", server.url))
        .send()
        .unwrap()
        .text()
        .unwrap();
    for expected in [
        "mpm_jobs{state=\"succeeded\"} 1",
        "mpm_job_queue_wait_seconds_count 1",
        "mpm_job_run_seconds_count 1",
        "mpm_worker_last_heartbeat_seconds{worker=",
    ] {
        assert!(text.contains(expected), "{expected} in\n{text}");
    }
    let rate: f64 = text
        .lines()
        .find_map(|l| l.strip_prefix("mpm_particle_steps_per_second "))
        .unwrap()
        .parse()
        .unwrap();
    assert!(rate > 0.0, "{text}");
    let logs = server.log_lines();
    let event = |message: &str| {
        logs.iter()
            .find(|l| l["message"] == message && l["job"] == id.as_str())
            .unwrap_or_else(|| panic!("no `{message}` line for {id}: {logs:?}"))
    };
    event("job queued");
    assert!(
        event("job claimed")["worker"]
            .as_str()
            .unwrap()
            .ends_with(":0")
    );
    assert_eq!(event("job finished")["status"], "succeeded");
}
