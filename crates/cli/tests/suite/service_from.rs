//! Jobs that start from another job's stored state (`POST /v1/jobs?from=JOB[&stage=NAME]`,
//! `mpm submit --from JOB [--stage NAME]`), on the real `mpm serve` with its job processes:
//! a staged scene started at a later stage gives the frames of the whole job's later stages
//! bit for bit, a plain scene takes over a finished job's checkpoint, and every refusal is a
//! JSON error that queues nothing.

use crate::common;

use common::jobs::{assert_same_stage_frames, staged_bar, wait_for_all};
use common::*;
use serde_json::{Value, json};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// `mpm serve` on a free port over the data folder `data`, with `extra` options; the
/// process (killed when dropped) and its URL.
fn start_server(data: &Path, extra: &[&str]) -> (Process, String) {
    let (child, url) = serve(
        Command::new(env!("CARGO_BIN_EXE_mpm"))
            .args(["serve", "--listen", "127.0.0.1:0", "--data"])
            .arg(data)
            .args(extra),
    );
    (Process(child), url)
}

fn submit(url: &str, query: &str, scene: &Value) -> (u16, Value) {
    let r = http_client(60)
        .post(format!("{url}/v1/jobs{query}"))
        .json(scene)
        .send()
        .unwrap();
    (r.status().as_u16(), r.json().unwrap_or(Value::Null))
}

/// Submits and waits; the job, which must have succeeded.
fn run_job(url: &str, query: &str, scene: &Value) -> Value {
    let (code, body) = submit(url, query, scene);
    assert_eq!(code, 202, "{body}");
    let id = body["id"].as_str().unwrap().to_string();
    let limit = Duration::from_secs(120);
    let done = wait_for_all(
        url,
        std::slice::from_ref(&id),
        Instant::now(),
        limit,
        String::new,
    )
    .remove(&id);
    let done = done.unwrap();
    assert_eq!(done["status"], "succeeded", "{done}");
    done
}

/// `mpm fetch` of job `id` into `out`; its store opened.
fn fetch(url: &str, id: &str, out: &Path, name: &str) -> mpm_io::ResultStore {
    let status = Command::new(env!("CARGO_BIN_EXE_mpm"))
        .args(["fetch", id, "--server", url, "--out"])
        .arg(out)
        .status()
        .unwrap();
    assert!(status.success());
    mpm_io::ResultStore::open(out.join(format!("{name}.zarr"))).unwrap()
}

#[test]
fn a_job_starts_at_a_later_stage_of_another_jobs_store() {
    let data = tempfile::tempdir().unwrap();
    let (_server, url) = start_server(data.path(), &[]);
    let scene = staged_bar();
    let whole = run_job(&url, "", &scene);
    let whole_id = whole["id"].as_str().unwrap();
    assert!(whole.get("from").is_none(), "{whole}");

    // Started at `second` from the whole job's end of `first`.
    let started = run_job(&url, &format!("?from={whole_id}&stage=second"), &scene);
    let started_id = started["id"].as_str().unwrap();
    assert_eq!(started["from"]["job"], whole_id, "{started}");
    assert_eq!(started["from"]["stage"], "second");
    let start_time = started["from"]["time"].as_f64().unwrap();
    assert!((start_time - 0.1).abs() < 0.01, "{started}");
    assert_eq!(started["progress"]["start_time"], started["from"]["time"]);
    assert_eq!(started["progress"]["fraction"], 1.0);
    assert_eq!(started["progress"]["stage"], "third");
    // Its metrics list every stage, `first` as the whole job ran it.
    let stages = started["metrics"]["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 3, "{started}");
    assert_eq!(stages[0], whole["metrics"]["stages"][0]);
    assert_eq!(started["metrics"]["steps"], whole["metrics"]["steps"]);

    // The later stages' frames are the whole job's, bit for bit; `first` stays in its store.
    let out = tempfile::tempdir().unwrap();
    let a_dir = out.path().join("whole");
    let b_dir = out.path().join("started");
    fetch(&url, whole_id, &a_dir, "bar-stages");
    let b = fetch(&url, started_id, &b_dir, "bar-stages");
    assert_eq!(b.stages(), ["1-second", "2-third"]);
    for name in ["second", "third"] {
        let store = |dir: &Path| dir.join("bar-stages.zarr");
        assert_same_stage_frames(&store(&a_dir), &store(&b_dir), name);
    }

    // Through the client: `mpm submit --from JOB --stage NAME --wait`.
    let file = write_scene(out.path(), "bar.json", &scene);
    let cli = Command::new(env!("CARGO_BIN_EXE_mpm"))
        .args(["submit"])
        .arg(&file)
        .args([
            "--from", whole_id, "--stage", "third", "--wait", "--server", &url,
        ])
        .output()
        .unwrap();
    assert!(cli.status.success(), "{}", text(&cli));
    assert!(text(&cli).contains("status succeeded"), "{}", text(&cli));

    // Refusals: each a JSON error, nothing queued.
    let count = || {
        let list: Value = http_client(60)
            .get(format!("{url}/v1/jobs"))
            .send()
            .unwrap()
            .json()
            .unwrap();
        list["total"].as_i64().unwrap()
    };
    let before = count();
    let unknown = "00000000-0000-4000-8000-000000000000";
    let mut earlier_changed = scene.clone();
    earlier_changed["stages"][0]["changes"]["solver"]["transfer"] = json!("flip");
    let mut plain = bar_json();
    plain["solver"]["end_time"] = json!(0.3);
    let mut no_end_state = scene.clone();
    no_end_state["output"]["end_state"] = json!(false);
    let cases: Vec<(String, &Value, u16, &str, &str)> = vec![
        (
            "?stage=second".into(),
            &scene,
            400,
            "bad_query",
            "`stage` needs `from`",
        ),
        (
            format!("?from={whole_id}&stag=x"),
            &scene,
            400,
            "bad_query",
            "stag",
        ),
        (
            format!("?from={unknown}&stage=second"),
            &scene,
            422,
            "cannot_start_from",
            "there is no such job",
        ),
        (
            format!("?from={whole_id}&stage=first"),
            &scene,
            422,
            "cannot_start_from",
            "first stage",
        ),
        (
            format!("?from={whole_id}&stage=fourth"),
            &scene,
            422,
            "cannot_start_from",
            "the scene's stages are first, second, third",
        ),
        (
            format!("?from={whole_id}&stage=third"),
            &earlier_changed,
            422,
            "cannot_start_from",
            "stage `first` runs with another `solver`",
        ),
        (
            format!("?from={whole_id}"),
            &plain,
            422,
            "cannot_start_from",
            "its run was staged",
        ),
    ];
    for (query, body, status, code, says) in &cases {
        let (got, answer) = submit(&url, query, body);
        assert_eq!(got, *status, "{query}: {answer}");
        assert_eq!(answer["error"]["code"], *code, "{query}: {answer}");
        assert!(answer.to_string().contains(says), "{query}: {answer}");
    }
    // A source whose stages kept no end state.
    let bare = run_job(&url, "", &no_end_state);
    let bare_id = bare["id"].as_str().unwrap();
    let (got, answer) = submit(
        &url,
        &format!("?from={bare_id}&stage=second"),
        &no_end_state,
    );
    assert_eq!(got, 422, "{answer}");
    assert!(
        answer
            .to_string()
            .contains("keeps no end state of stage 0 `first`"),
        "{answer}"
    );
    assert_eq!(count(), before + 1, "only the bare source was queued");
}

#[test]
fn a_plain_job_takes_over_a_finished_jobs_checkpoint() {
    let data = tempfile::tempdir().unwrap();
    let (_server, url) = start_server(data.path(), &[]);
    let mut first = bar_json();
    first["solver"]["end_time"] = json!(0.1);
    first["output"]["frames"] = json!(2);
    first["output"]["checkpoint"] = json!({"steps": 20});
    let done = run_job(&url, "", &first);
    let id = done["id"].as_str().unwrap();
    let mut next = first.clone();
    next["solver"]["end_time"] = json!(0.2);
    let taken = run_job(&url, &format!("?from={id}"), &next);
    assert_eq!(taken["from"]["job"], id, "{taken}");
    assert!(taken["from"].get("stage").is_none(), "{taken}");
    let time = taken["from"]["time"].as_f64().unwrap();
    assert!((time - 0.1).abs() < 0.01, "{taken}");
    let out = tempfile::tempdir().unwrap();
    let store = fetch(
        &url,
        taken["id"].as_str().unwrap(),
        out.path(),
        "vibrating-bar",
    );
    let times = store.times().unwrap();
    assert_eq!(
        times[0].to_bits(),
        time.to_bits(),
        "frame 0 is the state taken over"
    );
    // A checkpoint at or past the new end time is refused.
    let mut shorter = first.clone();
    shorter["solver"]["end_time"] = json!(0.05);
    let (got, answer) = submit(&url, &format!("?from={id}"), &shorter);
    assert_eq!(got, 422, "{answer}");
    assert!(
        answer
            .to_string()
            .contains("not before the scene's solver.end_time"),
        "{answer}"
    );
    // A source still running (or queued) is a conflict.
    let mut long = first.clone();
    long["solver"]["end_time"] = json!(1000.0);
    long["output"]["frames"] = json!(2);
    let (code, running) = submit(&url, "", &long);
    assert_eq!(code, 202, "{running}");
    let running_id = running["id"].as_str().unwrap();
    let (got, answer) = submit(&url, &format!("?from={running_id}"), &next);
    assert_eq!(got, 409, "{answer}");
    assert_eq!(answer["error"]["code"], "source_not_ended", "{answer}");
    let cancelled = http_client(60)
        .delete(format!("{url}/v1/jobs/{running_id}"))
        .send()
        .unwrap();
    assert!(cancelled.status().is_success());
}

#[test]
fn the_step_bound_counts_only_the_stages_a_job_runs() {
    let data = tempfile::tempdir().unwrap();
    let start = |extra: &[&str]| start_server(data.path(), extra);
    // The whole three-stage bar (about 1,100 steps per simulated second, 0.3 s) runs on a
    // server without a bound ...
    let (mut first, url) = start(&[]);
    let scene = staged_bar();
    let whole = run_job(&url, "", &scene);
    let whole_id = whole["id"].as_str().unwrap().to_string();
    first.kill();
    // ... and a server over the same data with a bound of 150 steps refuses it whole and from
    // `second` (two of its three stages), but takes it from `third`.
    let (_second, url) = start(&["--max-steps", "150"]);
    let steps_refused = |query: &str| {
        let (code, answer) = submit(&url, query, &scene);
        assert_eq!(code, 422, "{query}: {answer}");
        assert!(
            answer.to_string().contains("--max-steps"),
            "{query}: {answer}"
        );
    };
    steps_refused("");
    steps_refused(&format!("?from={whole_id}&stage=second"));
    let third = run_job(&url, &format!("?from={whole_id}&stage=third"), &scene);
    assert_eq!(third["metrics"]["stages"].as_array().unwrap().len(), 3);
}
