//! Scenes whose work comes from one wrong number are refused before anything is allocated,
//! by `mpm validate` (exit 2, JSON path, within a second) and by `mpm serve` (422), which
//! keeps answering and running jobs; a job that crashes fails alone.

use crate::common;

use common::*;
use reqwest::blocking::Client;
use serde_json::{Value, json};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

fn example_json(name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(example(name)).unwrap()).unwrap()
}

/// The three scenes of issue 24, with the JSON path each must be refused at.
fn bad_scenes() -> Vec<(&'static str, Value, &'static str)> {
    let mut a = example_json("capillary-cross-section.json");
    let y = a["bodies"][0]["shape"]["box"]["max"][1].as_f64().unwrap();
    a["bodies"][0]["shape"]["box"]["max"][1] = json!(y * 1e6);
    let mut b = example_json("vibrating-bar.json");
    b["bodies"][0]["shape"]["box"]["min"][0] = json!(-1e308);
    let mut c = example_json("two-disks.json");
    let r = c["bodies"][0]["shape"]["sphere"]["radius"]
        .as_f64()
        .unwrap();
    c["bodies"][0]["shape"]["sphere"]["radius"] = json!(r * 1e6);
    vec![
        ("capillary-box-max", a, "bodies[0].shape.box.max[1]"),
        ("bar-box-min", b, "bodies[0].shape.box.min[0]"),
        ("disk-radius", c, "bodies[0].shape.sphere.radius"),
    ]
}

#[test]
fn the_three_scenes_are_refused_with_their_path_within_a_second() {
    let dir = tempfile::tempdir().unwrap();
    for (name, scene, path) in bad_scenes() {
        let file = write_scene(dir.path(), &format!("{name}.json"), &scene);
        let start = Instant::now();
        let o = mpm(&["validate", file.to_str().unwrap()], dir.path());
        let elapsed = start.elapsed();
        let t = text(&o);
        println!("{name}: exit {:?} in {elapsed:?}", o.status.code());
        assert_eq!(o.status.code(), Some(2), "{t}");
        assert!(t.contains(path), "expected `{path}` in: {t}");
        assert!(t.contains("outside the domain"), "{t}");
        assert!(elapsed < Duration::from_secs(2), "{name}: {elapsed:?}");
    }
}

#[test]
fn limits_name_the_estimate_and_can_be_changed() {
    let dir = tempfile::tempdir().unwrap();
    let bar = write_scene(dir.path(), "bar.json", &bar_json());
    let bar = bar.to_str().unwrap();
    // 320 particles: over a limit of 100, refused before generating them.
    let o = mpm(&["validate", bar, "--limit", "particles=100"], dir.path());
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(
        t.contains("bodies[0].shape") && t.contains("3.200e2") && t.contains("limit `particles`"),
        "{t}"
    );
    assert_eq!(mpm(&["validate", bar], dir.path()).status.code(), Some(0));
    let o = mpm(&["validate", bar, "--limit", "colour=1"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("unknown limit `colour`"), "{}", text(&o));

    // A tiny cell makes a huge grid; a huge frame count a huge store.
    for (set, path, words) in [
        (
            "domain.cell_size=1e-7",
            "domain.cell_size",
            "limit `grid_nodes`",
        ),
        (
            "output.frames=4000000000",
            "output.frames",
            "limit `frames`",
        ),
        ("solver.dt=1e-15", "solver.dt", "limit `steps`"),
        // Found by the fuzz test: a wall thicker than the domain overflowed an index.
        (
            "domain.walls[0].thickness=100",
            "domain.walls[0].thickness",
            "do not fit",
        ),
    ] {
        let o = mpm(&["validate", bar, "--set", set], dir.path());
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{set}: {t}");
        assert!(t.contains(path) && t.contains(words), "{set}: {t}");
    }

    // A body that asks to be clipped keeps only the part inside the domain, whatever its size.
    let mut clipped = bar_json();
    clipped["bodies"][0]["shape"]["box"]["min"][0] = json!(-1e300);
    clipped["bodies"][0]["clip_to_domain"] = json!(true);
    let file = write_scene(dir.path(), "clipped.json", &clipped);
    let start = Instant::now();
    let o = mpm(&["validate", file.to_str().unwrap()], dir.path());
    assert!(start.elapsed() < Duration::from_secs(2));
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("more than 1e12 particle spacings"),
        "{}",
        text(&o)
    );
    clipped["bodies"][0]["shape"]["box"]["min"][0] = json!(-1e3);
    let file = write_scene(dir.path(), "clipped.json", &clipped);
    let o = mpm(&["validate", file.to_str().unwrap()], dir.path());
    // The domain starts at x = 0: of the box from -1000 to 1, the 40 × 8 lattice points
    // in 0..1 remain, the bar's own 320 particles.
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("320 particles"), "{}", text(&o));

    // Particle files are checked for size before they are read.
    let csv = dir.path().join("p.csv");
    std::fs::write(&csv, "x,y\n0.1,0.05\n0.2,0.05\n0.3,0.05\n").unwrap();
    let mut from_file = bar_json();
    from_file["bodies"][0]["shape"] = json!({"file": {"path": "p.csv", "format": "csv"}});
    let file = write_scene(dir.path(), "file.json", &from_file);
    let f = file.to_str().unwrap();
    assert_eq!(mpm(&["validate", f], dir.path()).status.code(), Some(0));
    let o = mpm(&["validate", f, "--limit", "file_bytes=10"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("bodies[0].shape.file.path") && text(&o).contains("limit `file_bytes`"),
        "{}",
        text(&o)
    );
    let o = mpm(&["validate", f, "--limit", "particles=2"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("holds 3 particles"), "{}", text(&o));
}

struct Server {
    _child: Process,
    url: String,
}

impl Server {
    fn start(data: &Path, extra: &[&str]) -> Server {
        let (child, url) = serve(
            Command::new(env!("CARGO_BIN_EXE_mpm"))
                // One thread: the jobs' address space then does not grow with the core count.
                .env("MPM_THREADS", "1")
                .args(["serve", "--listen", "127.0.0.1:0", "--data"])
                .arg(data)
                .args(extra),
        );
        Server {
            _child: Process(child),
            url,
        }
    }
}

fn client() -> Client {
    http_client(30)
}

fn post(url: &str, scene: &Value) -> (u16, Value) {
    let r = client()
        .post(format!("{url}/v1/jobs"))
        .json(scene)
        .send()
        .unwrap();
    (r.status().as_u16(), r.json().unwrap_or(Value::Null))
}

fn wait_final(url: &str, id: &str) -> Value {
    let start = Instant::now();
    loop {
        let j: Value = client()
            .get(format!("{url}/v1/jobs/{id}"))
            .send()
            .unwrap()
            .json()
            .unwrap();
        if matches!(
            j["status"].as_str(),
            Some("succeeded" | "failed" | "cancelled")
        ) {
            return j;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "{j}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn small_bar() -> Value {
    let mut s = bar_json();
    s["solver"]["end_time"] = json!(0.01);
    s["output"]["frames"] = json!(2);
    s
}

#[test]
fn the_service_refuses_the_three_scenes_and_keeps_running_jobs() {
    let data = tempfile::tempdir().unwrap();
    let server = Server::start(data.path(), &[]);
    let url = &server.url;
    for (name, scene, path) in bad_scenes() {
        let start = Instant::now();
        let (status, body) = post(url, &scene);
        println!("{name}: {status} in {:?}", start.elapsed());
        assert_eq!(status, 422, "{name}: {body}");
        let problems = body["error"]["problems"].as_array().unwrap();
        assert!(problems.iter().any(|p| p["path"] == path), "{name}: {body}");
    }
    // A scene over the server's particle limit is refused on its estimate.
    let mut fine = bar_json();
    fine["domain"]["cell_size"] = json!(0.0002);
    let (status, body) = post(url, &fine);
    assert_eq!(
        (status, body["error"]["code"].as_str()),
        (422, Some("too_many_particles")),
        "{body}"
    );
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("estimated")
    );
    let health = client().get(format!("{url}/v1/health")).send().unwrap();
    assert_eq!(health.status().as_u16(), 200);
    let (status, body) = post(url, &small_bar());
    assert_eq!(status, 202, "{body}");
    let done = wait_final(url, body["id"].as_str().unwrap());
    assert_eq!(done["status"], "succeeded", "{done}");
    let list: Value = client()
        .get(format!("{url}/v1/jobs"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(list["total"], 1, "only the good scene was queued");
}

#[test]
fn a_job_whose_process_runs_out_of_memory_fails_alone() {
    let data = tempfile::tempdir().unwrap();
    // Each job's process gets 100 MB of address space; the cube drop at half its cell size
    // (a million particles, about 300 MB) needs more, which the server's limits allow. It
    // fails in validation (the body's particles, a fallible allocation: a refusal) or in
    // the run (an abort), depending on what else fills the address space (the binary, the
    // threads' arenas); either way the job's failure names the limit.
    let server = Server::start(data.path(), &["--job-memory-mb", "100"]);
    let url = &server.url;
    let mut big = example_json("cube-drop.json");
    let cell = big["domain"]["cell_size"].as_f64().unwrap();
    big["domain"]["cell_size"] = json!(cell / 2.0);
    big["solver"]["end_time"] = json!(1e-4);
    let (status, body) = post(url, &big);
    assert_eq!(status, 202, "{body}");
    let failed = wait_final(url, body["id"].as_str().unwrap());
    assert_eq!(failed["status"], "failed", "{failed}");
    let message = failed["failure"]["message"].as_str().unwrap();
    assert!(message.contains("memory limit is 100 MB"), "{message}");
    // The API still answers and the next job runs.
    let health = client().get(format!("{url}/v1/health")).send().unwrap();
    assert_eq!(health.status().as_u16(), 200);
    let (status, body) = post(url, &small_bar());
    assert_eq!(status, 202, "{body}");
    let done = wait_final(url, body["id"].as_str().unwrap());
    assert_eq!(done["status"], "succeeded", "{done}");
}
