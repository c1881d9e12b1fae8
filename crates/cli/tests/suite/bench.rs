//! `mpm bench`: the three built-in scenes at the smallest size run their steps and print
//! valid JSON with positive figures and the particle counts of the scenes; bad arguments
//! exit 2 naming the argument.

use std::process::{Command, Output};

fn mpm(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mpm"))
        .args(args)
        .env_remove("MPM_THREADS")
        .output()
        .expect("mpm starts")
}

#[test]
fn bench_runs_every_scene_and_prints_json() {
    let out = mpm(&["bench", "--size", "16", "--steps", "5", "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert!(doc["machine"]["cores"].as_u64().unwrap() >= 1);
    assert!(doc["machine"]["threads"].as_u64().unwrap() >= 1);
    assert_eq!(doc["steps"], 5);
    let cases = doc["cases"].as_array().unwrap();
    let names: Vec<&str> = cases.iter().map(|c| c["scene"].as_str().unwrap()).collect();
    assert_eq!(names, ["cube-drop", "impact", "thermal"]);
    for c in cases {
        assert_eq!(c["cells"], 16, "{c}");
        assert_eq!(c["steps"], 5, "{c}");
        assert_eq!(c["outcome"], "finished", "{c}");
        for key in [
            "particles",
            "wall_seconds",
            "particle_steps_per_second",
            "bytes_per_particle",
            "grid_bytes",
        ] {
            assert!(c[key].as_f64().unwrap() > 0.0, "{key} of {c}");
        }
    }
    // The cube holds ⌊0.8 n⌋ = 12 particles along each axis; the thermal bar fills
    // 16 × 4 × 4 cells at 2 particles per cell along each axis.
    assert_eq!(cases[0]["particles"], 12 * 12 * 12);
    assert_eq!(cases[2]["particles"], 32 * 8 * 8);
    // A quarter cylinder of radius 0.3 L and length 0.7 L at 32 particles per L: about
    // π/4 · 9.6² · 22.4 = 1,621 particles.
    let impact = cases[1]["particles"].as_f64().unwrap();
    assert!((1400.0..1900.0).contains(&impact), "{impact}");
    // The breakdown: the stages each scene runs took time, and together no more than the
    // loop; the thermal scene (mechanics off) has no transfers of momentum or stress.
    for (c, stages) in cases.iter().zip([
        &["bin", "p2g", "grid_update", "g2p", "stress"][..],
        &["bin", "p2g", "grid_update", "g2p", "stress"][..],
        &["physics"][..],
    ]) {
        let seconds = c["stage_seconds"].as_object().expect("stage_seconds");
        for stage in stages {
            assert!(seconds[*stage].as_f64().unwrap() > 0.0, "{stage} of {c}");
        }
        let total: f64 = seconds.values().map(|v| v.as_f64().unwrap()).sum();
        assert!(total <= c["wall_seconds"].as_f64().unwrap(), "{c}");
    }
    assert!(
        !cases[2]["stage_seconds"]
            .as_object()
            .unwrap()
            .contains_key("p2g")
    );
}

#[test]
fn bad_arguments_exit_2_naming_the_argument() {
    for (args, named) in [
        (&["bench", "--size", "0"][..], "--size"),
        (&["bench", "--size", "32,x"][..], "--size"),
        (&["bench", "--scene", "nope"][..], "--scene"),
        (&["bench", "--steps", "0"][..], "--steps"),
        (&["bench", "--peer", "nope"][..], "--peer"),
        (
            &["bench", "--peer", "taichi", "--scene", "impact"][..],
            "--peer",
        ),
        (&["bench", "--peer", "taichi", "--out", "x"][..], "--out"),
    ] {
        let out = mpm(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(named), "{args:?}: {stderr}");
        assert!(out.stdout.is_empty(), "{args:?}");
    }
}

/// A Python that cannot be started is an operational failure (1) naming it; the Taichi
/// comparison itself is tested in tests/python/test_bench_peer.py, in the venv that has
/// the `taichi` package.
#[test]
fn a_peer_python_that_does_not_start_exits_1_naming_it() {
    let out = mpm(&[
        "bench",
        "--peer",
        "taichi",
        "--size",
        "16",
        "--steps",
        "2",
        "--python",
        "/nonexistent/python",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("/nonexistent/python"), "{stderr}");
    assert!(out.stdout.is_empty());
}
