//! The README's exit status table, command by command, against the real binary: 0 done,
//! 1 an operational failure (files, I/O, server unreachable), 2 invalid input (scene, option
//! values, a 4xx of the server, clap's usage errors), 3 the run stopped on a check; and a
//! closed stdout ends `mpm` quietly with 141.

use crate::common;

use common::*;
use serde_json::json;
use std::io::Read;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `mpm` in `dir`, with no server or token from the environment.
fn command(args: &[&str], dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_mpm"));
    c.args(args)
        .current_dir(dir)
        .env_remove("MPM_SERVER")
        .env_remove("MPM_TOKEN")
        .env_remove("MPM_LISTEN")
        .env_remove("MPM_DATA")
        .env_remove("MPM_DATABASE")
        .env_remove("MPM_STORE")
        .env_remove("MPM_TOKENS");
    c
}

/// Runs `mpm`, giving up after two minutes (a failure of `mpm serve` must end it).
fn mpm(args: &[&str], dir: &Path) -> Output {
    let mut child = command(args, dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mpm starts");
    // Drain both pipes while waiting, so a long output cannot block the child.
    let mut stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let out = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = stdout.read_to_end(&mut v);
        v
    });
    let err = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = stderr.read_to_end(&mut v);
        v
    });
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("mpm {args:?} did not end within two minutes");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Output {
        status,
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
    }
}

/// Runs every case in `dir` and asserts its exit status and that the output contains the
/// given text; reports all mismatches at once.
fn expect(dir: &Path, cases: &[(Vec<&str>, i32, &str)]) {
    let mut wrong = Vec::new();
    for (args, code, needle) in cases {
        let o = mpm(args, dir);
        let t = text(&o);
        if o.status.code() != Some(*code) || !t.contains(needle) {
            wrong.push(format!(
                "mpm {args:?}: expected exit {code} and `{needle}`, got {:?}:\n{t}",
                o.status.code()
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n\n"));
}

/// The vibrating bar made invalid: a Poisson ratio of 0.5.
fn invalid_bar() -> serde_json::Value {
    let mut s = bar_json();
    s["materials"]["bar"]["poisson_ratio"] = json!(0.5);
    s
}

/// The vibrating bar at a fixed step five times the stable one, allowed: it stops on a check.
const UNSTABLE: [&str; 6] = [
    "--set",
    "solver.dt=0.0125",
    "--set",
    "solver.max_cfl=10",
    "--set",
    "output.frames=10",
];

/// A folder with `bar.json` (valid, short), `bad.json` (invalid), `not-json.json`, and the
/// result store `res/vibrating-bar.zarr` of a short 2D run.
fn workspace() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let mut bar = bar_json();
    bar["solver"]["end_time"] = json!(0.01);
    bar["output"]["frames"] = json!(2);
    write_scene(dir.path(), "bar.json", &bar);
    write_scene(dir.path(), "bad.json", &invalid_bar());
    std::fs::write(dir.path().join("not-json.json"), "{ \"name\": ").unwrap();
    std::fs::write(dir.path().join("a-file"), "not a folder").unwrap();
    let o = mpm(&["run", "bar.json", "--out", "res", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    dir
}

#[test]
fn a_missing_or_unwritable_file_exits_1() {
    let dir = workspace();
    let tower = example("rom-tower-2d.json");
    let tower = tower.to_str().unwrap();
    let missing = "does-not-exist.json";
    let cases = vec![
        (vec!["run", missing], 1, missing),
        (vec!["validate", missing], 1, missing),
        (
            vec!["export", "does-not-exist.zarr", "--vtk", "vtk"],
            1,
            "does-not-exist.zarr",
        ),
        (
            vec!["export", "res/vibrating-bar.zarr", "--vtk", "a-file"],
            1,
            "a-file",
        ),
        (
            vec![
                "render",
                "does-not-exist.zarr",
                "--field",
                "x",
                "--out",
                "a.png",
            ],
            1,
            "does-not-exist.zarr",
        ),
        (
            vec![
                "render",
                "res/vibrating-bar.zarr",
                "--field",
                "x",
                "--out",
                "a-file/a.png",
            ],
            1,
            "a-file/a.png",
        ),
        (vec!["study", missing, "--vary", "cfl=0.2"], 1, missing),
        (
            vec![
                "rom",
                "train",
                "--runs",
                "no-runs",
                "--latent",
                "2",
                "--out",
                "m.safetensors",
            ],
            1,
            "no-runs",
        ),
        (
            vec!["rom", "run", missing, "--model", "m.safetensors"],
            1,
            missing,
        ),
        (
            vec!["rom", "run", tower, "--model", "no-model.safetensors"],
            1,
            "no-model.safetensors",
        ),
        (
            vec!["rom", "error", "no-run.zarr", "res/vibrating-bar.zarr"],
            1,
            "no-run.zarr",
        ),
        (
            vec!["rom", "study", missing, "--full", "f.zarr", "--runs", "r"],
            1,
            missing,
        ),
        (
            vec![
                "rom",
                "study",
                tower,
                "--full",
                "no-full.zarr",
                "--runs",
                "r",
            ],
            1,
            "no-full.zarr",
        ),
        (
            vec![
                "check-stability",
                "--only",
                "leaving",
                "--json",
                "a-file/s.json",
            ],
            1,
            "a-file/s.json",
        ),
        (
            vec!["submit", missing, "--server", "http://127.0.0.1:9"],
            1,
            missing,
        ),
        (
            vec!["serve", "--listen", "127.0.0.1:0", "--data", "a-file"],
            1,
            "a-file",
        ),
    ];
    expect(dir.path(), &cases);
    assert!(!dir.path().join("vtk").exists() && !dir.path().join("a.png").exists());
}

#[test]
fn invalid_input_exits_2_and_writes_nothing() {
    let dir = workspace();
    let store = "res/vibrating-bar.zarr";
    let render = |extra: &[&'static str]| {
        let mut v = vec!["render", store, "--out", "r.png"];
        v.extend_from_slice(extra);
        v
    };
    let path = "materials.bar.poisson_ratio";
    let cases = vec![
        // The scene, named by its JSON path.
        (vec!["validate", "bad.json"], 2, path),
        (vec!["run", "bad.json", "--out", "out"], 2, path),
        (
            vec!["run", "not-json.json", "--out", "out"],
            2,
            "not valid JSON",
        ),
        (
            vec!["run", "bar.json", "--out", "out", "--set", "no-equals"],
            2,
            "--set",
        ),
        (
            vec!["study", "bad.json", "--vary", "cfl=0.2,0.3", "--out", "out"],
            2,
            path,
        ),
        (
            vec![
                "study",
                "not-json.json",
                "--vary",
                "cfl=0.2",
                "--out",
                "out",
            ],
            2,
            "not valid JSON",
        ),
        (
            vec![
                "rom",
                "run",
                "bad.json",
                "--model",
                "m.safetensors",
                "--out",
                "out",
            ],
            2,
            path,
        ),
        (
            vec![
                "rom", "study", "bad.json", "--full", "f.zarr", "--runs", "r", "--out", "out",
            ],
            2,
            path,
        ),
        // Option values.
        (
            vec!["study", "bar.json", "--vary", "cfl", "--out", "out"],
            2,
            "--vary `cfl`",
        ),
        (render(&["--field", "nope"]), 2, "`nope`"),
        (
            render(&["--field", "x", "--frame", "7"]),
            2,
            "frame 7 is out of range",
        ),
        (
            render(&["--field", "x", "--component", "5"]),
            2,
            "--component",
        ),
        (
            vec!["render", store, "--field", "x", "--out", "r.jpg"],
            2,
            "PNG",
        ),
        (
            vec!["check-stability", "--only", "no-such-case"],
            2,
            "impact-50",
        ),
        // Command lines clap refuses: it exits 2 itself.
        (vec![], 2, "Usage"),
        (vec!["frobnicate"], 2, "frobnicate"),
        (vec!["run"], 2, "SCENE"),
        (vec!["serve", "--listen", "nowhere"], 2, "--listen"),
        (vec!["worker", "--store", "results"], 2, "--database"),
        (
            vec!["serve", "--token", "t", "--tokens", "file"],
            2,
            "--tokens",
        ),
        (
            vec![
                "rom", "train", "--runs", "r", "--latent", "two", "--out", "m",
            ],
            2,
            "--latent",
        ),
    ];
    expect(dir.path(), &cases);
    assert!(!dir.path().join("out").exists(), "nothing may be written");
    assert!(!dir.path().join("r.png").exists() && !dir.path().join("r.jpg").exists());
}

#[test]
fn a_run_that_stops_on_a_check_exits_3() {
    let dir = workspace();
    let mut args = vec![
        "run",
        "bar.json",
        "--out",
        "out",
        "--set",
        "solver.end_time=0.4",
    ];
    args.extend(UNSTABLE);
    expect(dir.path(), &[(args, 3, "diagnostic")]);
}

/// `mpm serve` on a free loopback port with its data in a temporary folder.
struct Server {
    _child: Process,
    url: String,
    _data: tempfile::TempDir,
}

impl Server {
    fn start() -> Server {
        let data = tempfile::tempdir().unwrap();
        let (child, url) = serve(
            command(&["serve", "--listen", "127.0.0.1:0", "--data"], data.path()).arg(data.path()),
        );
        Server {
            _child: Process(child),
            url,
            _data: data,
        }
    }
}

#[test]
fn client_commands_follow_the_table_against_a_real_server() {
    let dir = workspace();
    let d = dir.path();
    let server = Server::start();
    let url = server.url.as_str();
    let s = ["--server", url];
    let with = |args: &[&'static str]| [args, &s[..]].concat();

    // A finished job to look at, fetch and (fail to) cancel.
    let o = mpm(&with(&["submit", "bar.json", "--wait"]), d);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let id = out
        .lines()
        .find_map(|l| l.strip_prefix("submitted job "))
        .expect("the job id is printed")
        .to_string();
    let id = id.as_str();
    // A staged job: the process report follows its metrics.
    let staged = mpm(
        &with(&[
            "submit",
            "bar.json",
            "--wait",
            "--set",
            r#"stages=[{"name":"first","changes":{"solver":{"end_time":0.005}}},{"name":"second","changes":{"solver":{"end_time":0.01}}}]"#,
        ]),
        d,
    );
    assert_eq!(staged.status.code(), Some(0), "{}", text(&staged));
    let report = String::from_utf8_lossy(&staged.stdout).into_owned();
    for stage in ["first", "second"] {
        assert!(
            report.contains(&format!("report         {stage}: peak von Mises, MPa: ")),
            "{report}"
        );
    }

    let mut unstable = with(&[
        "submit",
        "bar.json",
        "--wait",
        "--set",
        "solver.end_time=0.4",
    ]);
    unstable.extend(UNSTABLE);
    let path = "materials.bar.poisson_ratio";
    let cases = vec![
        (with(&["plugins"]), 0, "elastic"),
        (with(&["list"]), 0, id),
        ([&["status", id], &s[..]].concat(), 0, "succeeded"),
        (
            [&["fetch", id, "--out", "fetched"], &s[..]].concat(),
            0,
            "vibrating-bar.zarr",
        ),
        // The scene is validated by the server: 422 with the JSON path.
        (with(&["submit", "bad.json"]), 2, path),
        (with(&["submit", "not-json.json"]), 2, "not valid JSON"),
        (
            with(&["submit", "bar.json", "--set", "no-equals"]),
            2,
            "--set",
        ),
        (
            with(&["study", "bad.json", "--vary", "cfl=0.2,0.3", "--out", "out"]),
            2,
            path,
        ),
        // Requests the server refuses: unknown jobs (404), a bad filter (400), a finished
        // job cancelled (409).
        (with(&["status", "no-such-job"]), 2, "404"),
        (with(&["fetch", "no-such-job", "--out", "out"]), 2, "404"),
        (with(&["cancel", "no-such-job"]), 2, "404"),
        (with(&["list", "--status", "sleeping"]), 2, "400"),
        ([&["cancel", id], &s[..]].concat(), 2, "409"),
        // Files of this machine.
        (
            [&["fetch", id, "--out", "a-file"], &s[..]].concat(),
            1,
            "a-file",
        ),
        // A job that stops on a check.
        (unstable, 3, "the run stopped on a check"),
    ];
    expect(d, &cases);
    assert!(!d.join("out").exists(), "nothing may be written");
}

#[test]
fn a_server_that_is_not_listening_exits_1() {
    let dir = workspace();
    // A loopback port that was free a moment ago, and is closed now.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let url = format!("http://127.0.0.1:{port}");
    let url = url.as_str();
    let reach = "cannot reach the server";
    let cases = vec![
        (vec!["plugins", "--server", url], 1, reach),
        (
            vec!["study", "bar.json", "--vary", "cfl=0.2", "--server", url],
            1,
            reach,
        ),
        (vec!["submit", "bar.json", "--server", url], 1, reach),
        (vec!["status", "some-job", "--server", url], 1, reach),
        (vec!["list", "--server", url], 1, reach),
        (vec!["cancel", "some-job", "--server", url], 1, reach),
        (vec!["fetch", "some-job", "--server", url], 1, reach),
    ];
    expect(dir.path(), &cases);

    // `mpm serve` on an address in use is an operational failure too.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let data = dir.path().join("data");
    let data = data.to_str().unwrap();
    expect(
        dir.path(),
        &[(
            vec!["serve", "--listen", &addr, "--data", data],
            1,
            addr.as_str(),
        )],
    );
}

/// Spawns `mpm` with its stdout piped and a backtrace asked for (a panic would show one).
fn spawn_piped(args: &[&str], dir: &Path) -> Child {
    command(args, dir)
        .env("RUST_BACKTRACE", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mpm starts")
}

#[test]
fn a_closed_stdout_ends_mpm_quietly() {
    let dir = workspace();
    let d = dir.path();
    // A long output, as `| head` sees it: a few bytes read, then the pipe closed while `mpm`
    // still has more to write than the pipe holds.
    let args = ["schema"];
    let full = mpm(&args, d);
    assert_eq!(full.status.code(), Some(0), "{}", text(&full));
    assert!(
        full.stdout.len() > 64 * 1024,
        "mpm {args:?} prints {} bytes, which fit in a pipe: the test would not close it \
         before the end",
        full.stdout.len()
    );
    let mut child = spawn_piped(&args, d);
    let mut head = [0u8; 64];
    child
        .stdout
        .as_mut()
        .unwrap()
        .read_exact(&mut head)
        .unwrap();
    assert_eq!(head[..], full.stdout[..64]);
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(141), "mpm {args:?}: {stderr}");
    assert!(stderr.is_empty(), "mpm {args:?} printed: {stderr}");

    // Shorter outputs (`plugins --schemas` is about 40 kB, which a pipe may swallow whole):
    // a pipe whose reader is gone before `mpm` starts, so that every write fails.
    let short: [&[&str]; 5] = [
        &["plugins", "--schemas"],
        &["plugins"],
        &["validate", "bar.json"],
        &["run", "bar.json", "--out", "closed", "--json"],
        &["check-stability", "--only", "leaving"],
    ];
    for args in short {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = command(args, d)
            .env("RUST_BACKTRACE", "1")
            .stdout(writer)
            .output()
            .expect("mpm starts");
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(141), "mpm {args:?}: {stderr}");
        assert!(
            !stderr.contains("panicked") && !stderr.contains("Broken pipe"),
            "mpm {args:?}: {stderr}"
        );
    }
}
