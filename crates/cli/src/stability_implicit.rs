//! The stability suite's implicit-mechanics cases (`solver.mechanics.implicit`): steps far
//! beyond the explicit stable one, stiffness contrast, near incompressibility, a load step
//! too large for Newton, and a body nothing holds.

use crate::stability_case::{Case, Expected};
use serde_json::{Value, json};

fn neo_hookean(e: f64, nu: f64) -> Value {
    json!({"type": "neo_hookean", "density": 1000.0, "youngs_modulus": e, "poisson_ratio": nu})
}

/// A soft block (E 1e4 Pa) on the floor under a stiff one (E 1e10 Pa), two implicit static
/// steps of 7.9e-3 s: 1000 times the stiff block's explicit stable step (dx / c).
fn contrast() -> Value {
    json!({
        "name": "implicit-contrast", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 1], "cell_size": 0.025,
                   "walls": [{"sides": ["x-", "x+", "y-", "y+"], "condition": "slip"}]},
        "solver": {"end_time": 0.0158, "dt": 0.0079, "gravity": [0, -9.81],
                   "mechanics": {"implicit": {}}},
        "materials": {"soft": neo_hookean(1e4, 0.3), "stiff": neo_hookean(1e10, 0.3)},
        "bodies": [
            {"material": "soft", "shape": {"box": {"min": [0.3, 0.0], "max": [0.7, 0.2]}}},
            {"material": "stiff", "shape": {"box": {"min": [0.35, 0.2], "max": [0.65, 0.3]}}}],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// A rubber block on a stick floor under gravity ramped over 1 s, in steps of `dt`, with
/// Young's modulus `e`, Poisson's ratio `nu` and the implicit settings `implicit`.
fn block(e: f64, nu: f64, dt: f64, walls: Value, implicit: Value) -> Value {
    json!({
        "name": "implicit-block", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 0.5], "cell_size": 0.025, "walls": walls},
        "solver": {"end_time": 1.0, "dt": dt, "gravity": [0, -9.81],
                   "mechanics": {"implicit": implicit}},
        "materials": {"rubber": neo_hookean(e, nu)},
        "bodies": [{"material": "rubber", "shape": {"box": {"min": [0.3, 0.0], "max": [0.7, 0.2]}}}],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// `scene` with `solver.anti_locking: "fbar"`.
fn with_fbar(mut scene: Value) -> Value {
    scene["solver"]["anti_locking"] = json!("fbar");
    scene
}

fn floor() -> Value {
    json!([{"sides": ["y-"], "condition": "stick"}])
}

/// The implicit cases, appended to the suite.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "implicit-contrast-1e6",
            what: "implicit static, stiff block on a soft one, E ratio 1e6, 1000x the explicit step",
            scene: contrast(),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "implicit-nu-0.4999",
            what: "implicit static, block under gravity, nu 0.4999 (no anti-locking: it locks)",
            scene: block(1e5, 0.4999, 0.25, floor(), json!({"gravity_ramp": 1.0})),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "implicit-nu-0.4999-fbar",
            what: "implicit static, the same block with F-bar over stencil patches",
            scene: with_fbar(block(
                1e5,
                0.4999,
                0.25,
                floor(),
                json!({"gravity_ramp": 1.0}),
            )),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "implicit-cut-and-recover",
            what: "implicit static, soft block squashed by half in one load step; Newton needs more than its 4 iterations, so the step is halved and recovers",
            scene: block(
                2500.0,
                0.3,
                1.0,
                floor(),
                json!({"gravity_ramp": 1.0, "max_newton_iterations": 4}),
            ),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "implicit-unsupported",
            what: "implicit static, block under gravity with no wall: a singular system, a clear stop",
            scene: block(1e5, 0.3, 0.25, json!([]), json!({"gravity_ramp": 1.0})),
            expected: Expected::Stopped,
            check: None,
        },
    ]
}
