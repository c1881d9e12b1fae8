//! `mpm check-stability`: a fixed set of stiff and extreme cases, each with the outcome it
//! must have. A test runs the suite and fails when an outcome changes.

use crate::stability_case::Frames;
pub use crate::stability_case::{Case, Expected};
use mpm_core::output::{Metrics, NullSink, Outcome, OutputSink};
use mpm_core::plugin::Registry;
use mpm_core::solver::{Control, Progress, RunError, preflight, run_scene};
use serde::Serialize;
use serde_json::{Value, json};
use std::path::Path;
use std::time::Instant;

/// The result of one case.
#[derive(Debug, Serialize)]
pub struct CaseResult {
    /// Case name.
    pub name: String,
    /// Expected outcome.
    pub expected: Expected,
    /// `finished`, `stopped`, `refused` or `invalid`.
    pub outcome: String,
    /// Whether the outcome is the expected one (and no NaN was seen).
    pub pass: bool,
    /// Steps taken.
    pub steps: u64,
    /// Wall seconds (setup excluded).
    pub wall_seconds: f64,
    /// Energy drift (see the README): the method's energy error, net of the energy ledger.
    pub energy_drift: f64,
    /// Relative change of the linear momentum, where nothing acts from outside.
    pub momentum_change: Option<f64>,
    /// Relative change of the angular momentum, where nothing acts from outside and the
    /// run can measure it.
    pub angular_momentum_change: Option<f64>,
    /// Smallest det F seen.
    pub min_det_f: f64,
    /// Largest particle speed seen.
    pub max_speed: f64,
    /// The diagnostic or refusal, if any.
    pub note: String,
}

fn elastic(kind: &str, e: f64, nu: f64, rho: f64) -> Value {
    json!({"type": kind, "density": rho, "youngs_modulus": e, "poisson_ratio": nu})
}

/// A soft block on the floor with a stiff block resting on it, stiffness ratio `ratio`.
fn contrast(ratio: f64) -> Value {
    json!({
        "name": "contrast", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 1], "cell_size": 0.025,
                   "walls": [{"sides": ["x-", "x+", "y-", "y+"], "condition": "slip"}]},
        "solver": {"end_time": 0.01, "gravity": [0, -9.81]},
        "materials": {"soft": elastic("neo_hookean", 1e4, 0.3, 1000.0),
                      "stiff": elastic("neo_hookean", 1e4 * ratio, 0.3, 1000.0)},
        "bodies": [
            {"material": "soft", "shape": {"box": {"min": [0.3, 0.0], "max": [0.7, 0.2]}}},
            {"material": "stiff", "shape": {"box": {"min": [0.35, 0.2], "max": [0.65, 0.3]}}}],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// A block squeezed under gravity on the floor, Poisson ratio `nu`, with or without F-bar.
pub(crate) fn near_incompressible(nu: f64, fbar: bool) -> Value {
    let mut s = json!({
        "name": "incompressible", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 0.5], "cell_size": 0.025,
                   "walls": [{"sides": ["y-"], "condition": "stick"}]},
        "solver": {"end_time": 0.05, "gravity": [0, -9.81], "damping": 20.0},
        "materials": {"rubber": elastic("neo_hookean", 1e5, nu, 1000.0)},
        "bodies": [{"material": "rubber", "shape": {"box": {"min": [0.3, 0.0], "max": [0.7, 0.2]}}}],
        "output": {"frames": 1, "fields": ["x"]}
    });
    if fbar {
        s["solver"]["anti_locking"] = json!("fbar");
    }
    s
}

/// The vibrating bar with a fixed time step `factor` times its stable one, allowing
/// Courant number `max_cfl`. The stable step is dx / (c + max |v|) = 0.05 / 10.01 s;
/// 4.99e-3 s is that, rounded down.
pub(crate) fn bar_time_step(factor: f64, max_cfl: f64) -> Value {
    let mut s: Value = serde_json::from_str(include_str!("../../../examples/vibrating-bar.json"))
        .expect("the example is JSON");
    s["solver"]["dt"] = json!(4.99e-3 * factor);
    s["solver"]["max_cfl"] = json!(max_cfl);
    s["output"]["frames"] = json!(4);
    s
}

/// A block squeezed to 10% of its height between the floor and a descending plane.
fn compression() -> Value {
    json!({
        "name": "compression", "dimension": 2,
        "domain": {"min": [0, 0], "max": [2, 0.5], "cell_size": 0.0125,
                   "walls": [{"sides": ["y-"], "condition": "slip"}]},
        "solver": {"end_time": 0.9, "cfl": 0.3},
        "materials": {"foam": elastic("neo_hookean", 1e5, 0.2, 100.0)},
        "bodies": [{"material": "foam", "shape": {"box": {"min": [0.8, 0.0], "max": [1.2, 0.2]}}}],
        "obstacles": [{"shape": {"plane": {"point": [0, 0.2], "normal": [0, -1]}},
                       "condition": "slip", "velocity": [0, -0.2]}],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// A disk spinning freely; energy must stay.
pub(crate) fn spinning_disk() -> Value {
    json!({
        "name": "spin", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 1], "cell_size": 0.02},
        "solver": {"end_time": 1.0, "cfl": 0.3},
        "materials": {"disk": elastic("neo_hookean", 1e5, 0.3, 1000.0)},
        "bodies": [{"material": "disk", "shape": {"sphere": {"center": [0.5, 0.5], "radius": 0.3}},
                    "velocity": {"rotation": {"center": [0.5, 0.5], "angular_velocity": [2.0]}}}],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// A block thrown toward an open face of the domain.
fn leaving() -> Value {
    json!({
        "name": "leaving", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 0.5], "cell_size": 0.025},
        "solver": {"end_time": 1.0},
        "materials": {"block": elastic("neo_hookean", 1e5, 0.3, 1000.0)},
        "bodies": [{"material": "block", "shape": {"box": {"min": [0.5, 0.1], "max": [0.7, 0.3]}},
                    "velocity": {"uniform": [2.0, 0.0]}}],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// One particle per cell splashing onto the floor: nearly empty cells at free surfaces.
fn sparse_surface() -> Value {
    json!({
        "name": "sparse", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 1], "cell_size": 0.025,
                   "walls": [{"sides": ["x-", "x+", "y-"], "condition": "slip"}]},
        "solver": {"end_time": 0.3, "gravity": [0, -9.81]},
        "materials": {"jelly": elastic("neo_hookean", 1e4, 0.3, 1000.0)},
        "bodies": [{"material": "jelly", "shape": {"sphere": {"center": [0.5, 0.5], "radius": 0.15}},
                    "particles_per_cell": 1, "velocity": {"uniform": [0.0, -2.0]}}],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// A plane-strain 4340 steel block (Johnson–Cook with damage, Mie–Grüneisen) hitting a rigid
/// wall at `speed` m/s: plasticity, shocks, failure and heating at once.
pub(crate) fn impact(speed: f64) -> Value {
    json!({
        "name": format!("impact-{speed}"), "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.1, 0.012], "cell_size": 0.0005,
                   "walls": [{"sides": ["y-"], "condition": "slip"}]},
        "solver": {"end_time": 2e-5, "cfl": 0.3},
        "materials": {"steel": {
            "type": "johnson_cook", "density": 7830.0, "youngs_modulus": 200e9,
            "poisson_ratio": 0.29, "specific_heat": 477.0,
            "flow_stress": {"yield_stress": 792e6, "hardening_modulus": 510e6,
                            "hardening_exponent": 0.26, "strain_rate_sensitivity": 0.014,
                            "thermal_softening_exponent": 1.03, "room_temperature": 293.0,
                            "melt_temperature": 1793.0},
            "equation_of_state": {"type": "mie_gruneisen", "sound_speed": 4569.0,
                                  "slope": 1.49, "gruneisen": 2.17},
            "damage": {"d1": 0.05, "d2": 3.44, "d3": -2.12, "d4": 0.002, "d5": 0.61}}},
        "bodies": [{"material": "steel",
                    "shape": {"box": {"min": [0.045, 0.0], "max": [0.055, 0.005]}},
                    "velocity": {"uniform": [0.0, -speed]}}],
        "output": {"frames": 1, "fields": ["x", "damage"]}
    })
}

/// A 2D bar of wax-like material along x conducting heat; `thermal` is merged into its
/// `physics.thermal` section and `extra` into the scene.
fn heat_bar(name: &str, thermal: Value, extra: Value) -> Value {
    let mut s = json!({
        "name": name, "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.02, 0.001], "cell_size": 0.0005},
        "solver": {"end_time": 20.0, "kernel": "linear", "mechanics": "off"},
        "materials": {"wax": elastic("linear_elastic", 1e9, 0.3, 1000.0)},
        "physics": {"thermal": {
            "materials": {"wax": {"conductivity": 1.0, "specific_heat": 1000.0,
                                  "initial_temperature": 300.0}},
            "boundaries": [{"sides": ["x-"], "temperature": 600.0}]}},
        "bodies": [{"material": "wax", "shape": {"box": {"min": [0, 0], "max": [0.02, 0.001]}}}],
        "output": {"frames": 1, "fields": ["temperature"]}
    });
    merge(&mut s["physics"]["thermal"], thermal);
    merge(&mut s, extra);
    s
}

/// Recursively overwrites `base` with the keys of `patch`.
fn merge(base: &mut Value, patch: Value) {
    match (base, patch) {
        (Value::Object(b), Value::Object(p)) => {
            for (k, v) in p {
                merge(b.entry(k).or_insert(Value::Null), v);
            }
        }
        (b, p) => *b = p,
    }
}

/// Melting with latent heat `ratio` times the sensible heat c·(T_surface − T_melt).
fn latent(ratio: f64) -> Value {
    let phase = json!({"conductivity": 1.0, "specific_heat": 1000.0, "density": 1000.0});
    heat_bar(
        "latent",
        json!({"integrator": "implicit"}),
        json!({"solver": {"dt": 0.1},
               "physics": {"phase_change": {"materials": {"wax": {"melting": {
                   "melt_temperature": 310.0, "latent_heat": ratio * 1000.0 * 290.0,
                   "solid": phase, "liquid": phase}}}}}}),
    )
}

/// A block whose lower half is solid (E = 1e10 Pa) and upper half liquid (bulk modulus
/// 1e4 Pa): one `phase_mixture` material, two starting temperatures around the melting
/// point, falling onto the floor.
fn phase_contrast() -> Value {
    let mixture = json!({"type": "phase_mixture", "density": 1000.0,
        "solid": {"youngs_modulus": 1e10, "poisson_ratio": 0.3},
        "liquid": {"viscosity": 1.0, "bulk_modulus": 1e4}});
    let thermal =
        |t: f64| json!({"conductivity": 1.0, "specific_heat": 1000.0, "initial_temperature": t});
    let phase = json!({"conductivity": 1.0, "specific_heat": 1000.0, "density": 1000.0});
    let melting = json!({"melting": {"melt_temperature": 300.0, "latent_heat": 1e5,
                                     "solid": phase, "liquid": phase}});
    json!({
        "name": "phase-contrast", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 1], "cell_size": 0.025,
                   "walls": [{"sides": ["x-", "x+", "y-", "y+"], "condition": "slip"}]},
        "solver": {"end_time": 0.002, "gravity": [0, -9.81]},
        "materials": {"cold": mixture.clone(), "hot": mixture},
        "physics": {
            "thermal": {"materials": {"cold": thermal(250.0), "hot": thermal(350.0)}},
            "phase_change": {"materials": {"cold": melting.clone(), "hot": melting}}},
        "bodies": [
            {"material": "cold", "shape": {"box": {"min": [0.3, 0.0], "max": [0.7, 0.2]}}},
            {"material": "hot", "shape": {"box": {"min": [0.3, 0.2], "max": [0.7, 0.4]}}}],
        "output": {"frames": 1, "fields": ["x", "solid_fraction"]}
    })
}

/// `contrast(ratio)` with frictionless contact between the two blocks.
fn contact_contrast(ratio: f64) -> Value {
    let mut s = contrast(ratio);
    s["bodies"][0]["name"] = json!("soft");
    s["bodies"][1]["name"] = json!("stiff");
    s["contact"] = json!({"pairs": [{"bodies": ["soft", "stiff"], "law": "frictionless"}]});
    s
}

/// Two steel-like elastic blocks meeting head-on at `speed` m/s relative speed, with
/// frictionless contact between them.
fn contact_impact(speed: f64) -> Value {
    json!({
        "name": "contact-impact", "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.1, 0.04], "cell_size": 0.001},
        "solver": {"end_time": 2e-5, "cfl": 0.3},
        "materials": {"steel": elastic("neo_hookean", 200e9, 0.29, 7830.0)},
        "bodies": [
            {"name": "left", "material": "steel",
             "shape": {"box": {"min": [0.03, 0.01], "max": [0.049, 0.03]}},
             "velocity": {"uniform": [0.5 * speed, 0.0]}},
            {"name": "right", "material": "steel",
             "shape": {"box": {"min": [0.051, 0.01], "max": [0.07, 0.03]}},
             "velocity": {"uniform": [-0.5 * speed, 0.0]}}],
        "contact": {"pairs": [{"bodies": ["left", "right"], "law": "frictionless"}]},
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// A block thrown along an elastic slab under gravity with Coulomb friction `mu`.
fn contact_sliding(mu: f64) -> Value {
    json!({
        "name": "contact-sliding", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1.6, 0.3], "cell_size": 0.02,
                   "walls": [{"sides": ["y-"], "condition": "stick"}]},
        "solver": {"end_time": 0.3, "gravity": [0, -9.81]},
        "materials": {"slab": elastic("linear_elastic", 2e6, 0.3, 2000.0),
                      "block": elastic("linear_elastic", 1e6, 0.3, 1000.0)},
        "bodies": [
            {"name": "slab", "material": "slab", "shape": {"box": {"min": [0, 0], "max": [1.6, 0.1]}}},
            {"name": "block", "material": "block",
             "shape": {"box": {"min": [0.2, 0.1], "max": [0.4, 0.18]}},
             "velocity": {"uniform": [2.0, 0.0]}}],
        "contact": {"pairs": [{"bodies": ["slab", "block"],
                               "law": {"friction": {"coefficient": mu}}}]},
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// Every case of the suite.
pub fn cases() -> Vec<Case> {
    let mut cases = vec![
        Case {
            name: "impact-50",
            what: "Johnson-Cook steel block on a rigid wall at 50 m/s",
            scene: impact(50.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "impact-200",
            what: "Johnson-Cook steel block on a rigid wall at 200 m/s",
            scene: impact(200.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "impact-500",
            what: "Johnson-Cook steel block on a rigid wall at 500 m/s (failure at the foot)",
            scene: impact(500.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "impact-1000",
            what: "Johnson-Cook steel block on a rigid wall at 1000 m/s (shock, melting, failure)",
            scene: impact(1000.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "contrast-1e4",
            what: "stiff block on a soft one, E ratio 1e4",
            scene: contrast(1e4),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "contrast-1e6",
            what: "stiff block on a soft one, E ratio 1e6",
            scene: contrast(1e6),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "contact-contrast-1e6",
            what: "stiff block on a soft one, E ratio 1e6, frictionless contact between them",
            scene: contact_contrast(1e6),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "contact-impact-1000",
            what: "two elastic steel blocks meeting at 1000 m/s across frictionless contact",
            scene: contact_impact(1000.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "contact-mu-0",
            what: "block thrown along an elastic slab at 2 m/s, frictionless contact",
            scene: contact_sliding(0.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "contact-mu-1",
            what: "block thrown along an elastic slab at 2 m/s, Coulomb friction mu = 1",
            scene: contact_sliding(1.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "phase-contrast-1e6",
            what: "solid (E 1e10 Pa) and liquid (bulk 1e4 Pa) halves of one phase-mixture block",
            scene: phase_contrast(),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "heat-jump-300K",
            what: "face of a 300 K bar stepped to 600 K, explicit conduction at its own step",
            scene: heat_bar("jump", json!({"integrator": "explicit"}), json!({})),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "heat-jump-300K-implicit",
            what: "the same jump, implicit conduction with 10 s steps (160x the explicit limit)",
            scene: heat_bar(
                "jump",
                json!({"integrator": "implicit"}),
                json!({"solver": {"dt": 10.0}}),
            ),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "heat-explicit-10x",
            what: "explicit conduction forced to 10x its stable step",
            scene: heat_bar(
                "jump",
                json!({"integrator": "explicit"}),
                json!({"solver": {"dt": 0.625, "max_cfl": 100.0}}),
            ),
            expected: Expected::Stopped,
            check: None,
        },
        Case {
            name: "latent-100x",
            what: "melting with latent heat 100x the sensible heat",
            scene: latent(100.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "nu-0.49",
            what: "block under gravity, nu = 0.49",
            scene: near_incompressible(0.49, false),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "nu-0.49-fbar",
            what: "block under gravity, nu = 0.49, F-bar",
            scene: near_incompressible(0.49, true),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "nu-0.499",
            what: "block under gravity, nu = 0.499",
            scene: near_incompressible(0.499, false),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "nu-0.499-fbar",
            what: "block under gravity, nu = 0.499, F-bar",
            scene: near_incompressible(0.499, true),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "dt-0.5x",
            what: "bar, fixed dt at 0.5x the stable step",
            scene: bar_time_step(0.5, 1.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "dt-1x",
            what: "bar, fixed dt at the stable step",
            scene: bar_time_step(1.0, 1.0),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "dt-2x",
            what: "bar, fixed dt at 2x the stable step",
            scene: bar_time_step(2.0, 1.0),
            expected: Expected::Refused,
            check: None,
        },
        Case {
            name: "dt-10x",
            what: "bar, fixed dt at 10x the stable step",
            scene: bar_time_step(10.0, 1.0),
            expected: Expected::Refused,
            check: None,
        },
        Case {
            name: "dt-10x-forced",
            what: "bar, 10x the stable step with max_cfl raised to allow it",
            scene: bar_time_step(10.0, 20.0),
            expected: Expected::Stopped,
            check: None,
        },
        Case {
            name: "compress-10%",
            what: "block squeezed to 10% of its height by a plane",
            scene: compression(),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "spinning-disk",
            what: "free disk spinning at 2 rad/s for 1 s",
            scene: spinning_disk(),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "leaving",
            what: "block thrown out of an open face",
            scene: leaving(),
            expected: Expected::Stopped,
            check: None,
        },
        Case {
            name: "sparse-surface",
            what: "1 particle per cell splashing onto the floor",
            scene: sparse_surface(),
            expected: Expected::Finished,
            check: None,
        },
    ];
    cases.extend(crate::stability_cohesive::cases());
    cases.extend(crate::stability_implicit::cases());
    cases.extend(crate::stability_liquid::cases());
    cases.extend(crate::stability_peer::cases());
    cases
}

/// The cases whose name contains `only` (every case without it), or an input error naming
/// the cases when none does; `kind` names the list in the message ("stability case", "map
/// case", "long case"). The suite, the map and the long runs choose their cases with it.
pub(crate) fn choose_cases<'a, T>(
    all: &'a [T],
    name: impl Fn(&T) -> &str,
    only: Option<&str>,
    kind: &str,
) -> anyhow::Result<Vec<&'a T>> {
    let chosen: Vec<&T> = all
        .iter()
        .filter(|c| only.is_none_or(|o| name(c).contains(o)))
        .collect();
    if chosen.is_empty() {
        let names: Vec<&str> = all.iter().map(&name).collect();
        return Err(crate::exit_status::input_error!(
            "--only {}: no {kind} has that in its name; the {kind}s are {}",
            only.unwrap_or(""),
            names.join(", ")
        ));
    }
    Ok(chosen)
}

/// How a scene's run ended, before anyone judges it: what the suite and the stability map
/// (`stability_map`) share.
pub(crate) enum Ran {
    /// The scene failed validation (the message lists the issues).
    Invalid(String),
    /// Refused before the first step (`path: message`).
    Refused(String),
    /// The run failed otherwise than by stopping on its own checks (output, I/O).
    Error(String),
    /// It ran to its end time, or until it stopped itself.
    Done {
        /// The run's metrics.
        metrics: Box<Metrics>,
        /// Wall seconds of the run (setup excluded).
        wall_seconds: f64,
    },
}

/// Validates `scene`, checks it before the first step and runs it without writing results.
pub(crate) fn run_value(scene: &Value, registry: &Registry) -> Ran {
    run_value_into(scene, registry, &mut NullSink)
}

/// [`run_value`] with the frames going to `sink`.
fn run_value_into(scene: &Value, registry: &Registry, sink: &mut dyn OutputSink) -> Ran {
    let scene = match mpm_core::scene::parse_scene_value(scene.clone(), registry, Path::new(".")) {
        Ok(s) => s,
        Err(e) => return Ran::Invalid(e.to_string()),
    };
    if let Err(RunError::Refused { path, message }) = preflight(&scene) {
        return Ran::Refused(format!("{path}: {message}"));
    }
    let start = Instant::now();
    match run_scene(&scene, sink, &mut |_: &Progress| Control::Continue) {
        Ok(m) => Ran::Done {
            metrics: Box::new(m),
            wall_seconds: start.elapsed().as_secs_f64(),
        },
        Err(e) => Ran::Error(e.to_string()),
    }
}

/// `finished`, `stopped` or `cancelled`: how a run that ran ended.
pub(crate) fn outcome_name(metrics: &Metrics) -> &'static str {
    match metrics.outcome {
        Some(Outcome::Finished) => "finished",
        Some(Outcome::Stopped) => "stopped",
        _ => "cancelled",
    }
}

/// The run's stop diagnostic as one line (`step N: field = value: message`), or "".
pub(crate) fn diagnostic_note(metrics: &Metrics) -> String {
    metrics.diagnostic.as_ref().map_or_else(String::new, |d| {
        format!(
            "step {}: {} = {:.3e}: {}",
            d.step, d.field, d.value, d.message
        )
    })
}

/// The relative changes of momentum and angular momentum where nothing acts from outside
/// (`None` where something does, or where the run cannot measure them).
pub(crate) fn momentum_changes(metrics: &Metrics) -> (Option<f64>, Option<f64>) {
    let kept = &metrics.conservation;
    if kept.external_forces {
        (None, None)
    } else {
        (Some(kept.momentum_change), kept.angular_momentum_change)
    }
}

/// Runs one case.
pub fn run_case(case: &Case, registry: &Registry) -> CaseResult {
    let mut result = CaseResult {
        name: case.name.to_string(),
        expected: case.expected,
        outcome: String::new(),
        pass: false,
        steps: 0,
        wall_seconds: 0.0,
        energy_drift: 0.0,
        momentum_change: None,
        angular_momentum_change: None,
        min_det_f: f64::NAN,
        max_speed: f64::NAN,
        note: String::new(),
    };
    let mut frames = Frames::default();
    let (metrics, wall_seconds) = match run_value_into(&case.scene, registry, &mut frames) {
        Ran::Invalid(note) => {
            result.outcome = "invalid".into();
            result.note = note;
            return result;
        }
        Ran::Refused(note) => {
            result.outcome = "refused".into();
            result.note = note;
            result.pass = case.expected == Expected::Refused;
            return result;
        }
        Ran::Error(note) => {
            result.outcome = "error".into();
            result.note = note;
            return result;
        }
        Ran::Done {
            metrics,
            wall_seconds,
        } => (metrics, wall_seconds),
    };
    result.wall_seconds = wall_seconds;
    result.steps = metrics.steps;
    result.energy_drift = metrics.energy_drift;
    (result.momentum_change, result.angular_momentum_change) = momentum_changes(&metrics);
    result.min_det_f = metrics.min_det_f;
    result.max_speed = metrics.max_speed;
    result.outcome = outcome_name(&metrics).into();
    result.note = diagnostic_note(&metrics);
    let expected = match case.expected {
        Expected::Finished => "finished",
        Expected::Stopped => "stopped",
        Expected::Refused => "refused",
    };
    result.pass = result.outcome == expected;
    if result.outcome == "finished" {
        let mut wrong = physics_failures(
            result.energy_drift,
            result.momentum_change,
            result.angular_momentum_change,
            case.keeps_angular_momentum(),
        );
        match case.check.map(|check| check(&metrics, &frames)) {
            Some(Ok(figure)) => result.note = figure,
            Some(Err(e)) => wrong.push(e),
            None => {}
        }
        if !wrong.is_empty() {
            result.pass = false;
            result.note = wrong.join("; ");
        }
    } else if result.outcome == "stopped" && result.pass {
        // A case that must stop may also say why it must (its own diagnostic, not another).
        match case.check.map(|check| check(&metrics, &frames)) {
            Some(Ok(figure)) => result.note = figure,
            Some(Err(e)) => {
                result.pass = false;
                result.note = e;
            }
            None => {}
        }
    }
    result
}

/// Most a finished case's energy may grow (net of the ledger), relative to its largest
/// mechanical energy: the method may lose energy, but growth is the sign of instability.
pub const MAX_ENERGY_GROWTH: f64 = 0.02;
/// Most a finished case's momentum may change where nothing acts from outside: round-off.
pub const MAX_MOMENTUM_CHANGE: f64 = 1e-10;

/// What a finished case got wrong physically: energy growth (or an energy drift that is not
/// a number), or momentum (and, where the transfer keeps it, angular momentum) not kept
/// where nothing acts from outside.
pub(crate) fn physics_failures(
    energy_drift: f64,
    momentum_change: Option<f64>,
    angular_momentum_change: Option<f64>,
    keeps_angular: bool,
) -> Vec<String> {
    let mut wrong = Vec::new();
    if energy_drift.is_nan() || energy_drift > MAX_ENERGY_GROWTH {
        wrong.push(format!(
            "energy grew by {energy_drift:.2e} of the largest mechanical energy (bound {MAX_ENERGY_GROWTH})"
        ));
    }
    if let Some(change) = momentum_change.filter(|c| c.is_nan() || *c > MAX_MOMENTUM_CHANGE) {
        wrong.push(format!(
            "momentum changed by {change:.2e} (bound {MAX_MOMENTUM_CHANGE:e})"
        ));
    }
    if keeps_angular
        && let Some(change) =
            angular_momentum_change.filter(|c| c.is_nan() || *c > MAX_MOMENTUM_CHANGE)
    {
        wrong.push(format!(
            "angular momentum changed by {change:.2e} (bound {MAX_MOMENTUM_CHANGE:e})"
        ));
    }
    wrong
}

/// The results as a Markdown table.
pub fn table(results: &[CaseResult]) -> String {
    let mut out = String::from(
        "| case | expected | outcome | steps | wall s | energy drift | momentum change | angular momentum change | worst det F | max speed | note |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        out += &format!(
            "| {} | {:?} | {}{} | {} | {:.2} | {:+.2e} | {} | {} | {:.3} | {:.3} | {} |\n",
            r.name,
            r.expected,
            r.outcome,
            if r.pass { "" } else { " **(unexpected)**" },
            r.steps,
            r.wall_seconds,
            r.energy_drift,
            r.momentum_change.map_or("—".into(), |c| format!("{c:.1e}")),
            r.angular_momentum_change
                .map_or("—".into(), |c| format!("{c:.1e}")),
            r.min_det_f,
            r.max_speed,
            r.note.chars().take(90).collect::<String>()
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn failures(drift: f64, momentum: Option<f64>, angular: Option<f64>, keeps: bool) -> usize {
        physics_failures(drift, momentum, angular, keeps).len()
    }

    #[test]
    fn a_finished_case_with_wrong_physics_fails() {
        assert_eq!(failures(-0.5, Some(1e-15), Some(1e-15), true), 0);
        assert_eq!(failures(0.05, None, None, true), 1);
        assert_eq!(failures(f64::NAN, None, None, true), 1);
        assert_eq!(failures(0.0, Some(1e-6), None, true), 1);
        assert_eq!(failures(0.0, Some(0.0), Some(1e-3), true), 1);
        // PIC or FLIP need not keep angular momentum.
        assert_eq!(failures(0.0, Some(0.0), Some(1e-3), false), 0);
        assert_eq!(failures(0.0, Some(f64::NAN), None, true), 1);
    }
}
