//! Particles a stage removes as it takes over (`stages[i].remove`): what is left runs on as
//! a scene whose bodies never had the removed particles.

use crate::common;

use common::{mpm, resume_staged_copy, run_scene_json, text, write_scene};
use mpm_io::ResultStore;
use serde_json::{Value, json};

/// Two rubber blocks and, between them, a cold block; thermal physics writes `temperature`.
/// Stage `hold` (mechanics off) keeps everything in place; stage `fall` drops the blocks
/// under gravity onto the floor. `cold`: whether the cold block is in the scene at all.
fn blocks(cold: bool) -> Value {
    let block = |name: &str, material: &str, x0: f64| {
        json!({
            "name": name,
            "material": material,
            "shape": {"box": {"min": [x0, 0.03], "max": [x0 + 0.02, 0.05]}},
            "particles_per_cell": 2
        })
    };
    let mut bodies = vec![block("left", "rubber", 0.01)];
    if cold {
        bodies.push(block("middle", "cold", 0.04));
    }
    bodies.push(block("right", "rubber", 0.07));
    let thermal =
        |t: f64| json!({"conductivity": 0.2, "specific_heat": 1500.0, "initial_temperature": t});
    json!({
        "name": "blocks",
        "dimension": 2,
        "domain": {"min": [0.0, 0.0], "max": [0.1, 0.08], "cell_size": 0.0025,
                   "walls": [{"sides": ["y-"], "condition": "slip"}]},
        "solver": {"end_time": 0.002, "kernel": "bspline2", "gravity": [0.0, -9.81], "cfl": 0.4},
        "materials": {
            "rubber": {"type": "neo_hookean", "density": 1100.0, "youngs_modulus": 1e6, "poisson_ratio": 0.3},
            "cold": {"type": "neo_hookean", "density": 1100.0, "youngs_modulus": 1e6, "poisson_ratio": 0.3}
        },
        "physics": {"thermal": {"materials": {"rubber": thermal(300.0), "cold": thermal(250.0)}}},
        "bodies": bodies,
        "output": {"frames": 4, "fields": ["x", "v", "stress", "temperature"]},
        "stages": [
            {"name": "hold", "changes": {"solver": {"end_time": 0.002, "mechanics": "off", "dt": 0.0005}}},
            {"name": "fall", "changes": {"solver": {"end_time": 0.06, "mechanics": null, "dt": null}}}
        ]
    })
}

#[test]
fn removed_particles_leave_the_run_as_if_never_there() {
    let dir = tempfile::tempdir().unwrap();
    let mut with_rule = blocks(true);
    with_rule["stages"][1]["remove"] =
        json!({"field": "temperature", "below": 275.0, "materials": ["cold"]});
    let removed = run_scene_json(dir.path(), "removed", &with_rule);
    let never = run_scene_json(dir.path(), "never", &blocks(false));
    let per_block = never["particles"].as_u64().unwrap() / 2;
    assert_eq!(removed["particles"], never["particles"]);
    assert_eq!(removed["stages"][1]["name"], "fall");
    let open = |name: &str, stage: &str| {
        ResultStore::open(dir.path().join(name).join("blocks.zarr"))
            .unwrap()
            .stage(stage)
            .unwrap()
    };
    let (hold_a, fall_a, fall_b) = (
        open("removed", "hold"),
        open("removed", "fall"),
        open("never", "fall"),
    );
    let field =
        |store: &ResultStore, name: &str, frame: usize| store.frame(name, frame as u64).unwrap().1;
    // The hold stage has all three blocks; the fall stage only the two rubber ones.
    assert_eq!(field(&hold_a, "x", 0).len(), 3 * per_block as usize * 2);
    let frames = fall_b.times().unwrap().len();
    assert_eq!(fall_a.times().unwrap(), fall_b.times().unwrap());
    for frame in 0..frames {
        for name in ["x", "v", "stress"] {
            let (a, b) = (field(&fall_a, name, frame), field(&fall_b, name, frame));
            // Mechanics never saw the cold block in either run (it was off while the block
            // was there): the same particles, numbered alike, move to the bit.
            assert_eq!(a, b, "{name} differs at frame {frame}");
        }
        let (a, b) = (
            field(&fall_a, "temperature", frame),
            field(&fall_b, "temperature", frame),
        );
        for (p, q) in a.iter().zip(&b) {
            // The hold stage's heat solve had the cold block in one run only (a different
            // linear system, converged to its tolerance); the blocks are 10 cells apart.
            assert!((p - q).abs() < 1e-6, "temperature {p} against {q}");
        }
    }
    // The blocks fell: the hand-over did not freeze them.
    let y0 = field(&fall_a, "x", 0);
    let y1 = field(&fall_a, "x", frames - 1);
    assert!(y1[1] < y0[1] - 1e-3, "{} {}", y0[1], y1[1]);
}

#[test]
fn removal_rules_are_checked_with_their_paths() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            0,
            json!({"field": "temperature", "below": 1.0}),
            "stages[0].remove: the first stage has no stage before it",
        ),
        (
            1,
            json!({"field": "fill", "below": 0.5}),
            "stages[1].remove.field: no physics of the stage before writes a particle field `fill`",
        ),
        (
            1,
            json!({"field": "temperature", "below": 1.0, "materials": ["glass"]}),
            "stages[1].remove.materials[0]: no material `glass`",
        ),
        (
            1,
            json!({"field": "temperature", "below": 1.0, "colour": 1}),
            "colour",
        ),
    ];
    for (stage, rule, expected) in cases {
        let mut s = blocks(true);
        s["stages"][stage]["remove"] = rule.clone();
        let path = write_scene(dir.path(), "bad.json", &s);
        let out = mpm(&["validate", path.to_str().unwrap()], dir.path());
        assert_eq!(out.status.code(), Some(2), "{rule}: {}", text(&out));
        assert!(text(&out).contains(expected), "{rule}: {}", text(&out));
    }
    // A rule that would leave nothing is refused when the stage starts, with its path.
    let mut s = blocks(true);
    s["stages"][1]["remove"] = json!({"field": "temperature", "below": 1000.0});
    let path = write_scene(dir.path(), "all.json", &s);
    let out = mpm(
        &["run", path.to_str().unwrap(), "--out", "all", "-q"],
        dir.path(),
    );
    assert!(!out.status.success());
    assert!(
        text(&out).contains("stages[1].remove") && text(&out).contains("nothing would be left"),
        "{}",
        text(&out)
    );
}

#[test]
fn a_run_resumed_after_a_removal_continues_bit_for_bit() {
    // The checkpoint is written in the stage after the removal: the resumed run must leave
    // out the same particles (the checkpoint's stage tag lists them) and report the same
    // stage summaries.
    let dir = tempfile::tempdir().unwrap();
    let mut s = blocks(true);
    s["stages"][1]["remove"] = json!({"field": "temperature", "below": 275.0});
    s["output"]["checkpoint"] = json!({"steps": 40});
    let (whole, resumed) =
        resume_staged_copy(dir.path(), &s, "fall", &["x", "v", "stress", "temperature"]);
    let strip = |m: &Value| {
        let mut stages = m["stages"].clone();
        for stage in stages.as_array_mut().unwrap() {
            stage.as_object_mut().unwrap().remove("wall_seconds");
        }
        stages
    };
    assert_eq!(strip(&resumed), strip(&whole));
    assert_eq!(
        resumed["stages"][1]["removed_particles"],
        json!(per_block_particles())
    );
}

/// Particles of one 20 mm block at two particles per 2.5 mm cell and direction.
fn per_block_particles() -> usize {
    (8 * 2) * (8 * 2)
}
