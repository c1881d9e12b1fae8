//! The stability suite's peer failure cases (issue 25): failure modes MPM users report,
//! reproduced as scenes, each with a physics check of its own on the finished run's
//! frames: a bar pulled apart (numerical fracture), a column settling under gravity with
//! particles crossing cells (stress noise), a surface particle row whose grid node carries
//! a millionth of its mass, and a block resting on the floor for 12,581 steps (creep).

use crate::stability_case::{Case, Expected, Frames};
use mpm_core::output::Metrics;
use serde_json::{Value, json};

fn neo_hookean(e: f64, nu: f64, rho: f64) -> Value {
    json!({"type": "neo_hookean", "density": rho, "youngs_modulus": e, "poisson_ratio": nu})
}

/// Cell size of the tension, near-zero-mass and creep scenes, m.
const DX: f64 = 0.025;
/// Gravity, m/s².
const G: f64 = 9.81;

// ---------------------------------------------------------------------------------------
// Tension: a bar pulled apart by two stick grips.

/// Speed of each grip, m/s.
const GRIP_SPEED: f64 = 1.0;
/// Length of the bar between the grips, m.
const GAUGE: f64 = 0.7;

/// A rubber bar (E 1e6 Pa, 0.8 × 0.1 m, `ppc` × `ppc` particles per cell) held at each end
/// over two cells by a stick box that moves outward at 1 m/s, for the time that stretches
/// the 0.7 m between the grips by `stretch` (1: to twice its length), with shape functions
/// `kernel`.
pub fn tension(kernel: &str, stretch: f64, ppc: u32) -> Value {
    let end_time = stretch * GAUGE / (2.0 * GRIP_SPEED);
    let grip = |min: f64, speed: f64| {
        json!({"shape": {"box": {"min": [min, 0.1], "max": [min + 0.25, 0.4]}},
               "condition": "stick", "velocity": [speed, 0.0]})
    };
    json!({
        "name": "peer-tension", "dimension": 2,
        "domain": {"min": [0, 0], "max": [3, 0.5], "cell_size": DX},
        "solver": {"end_time": end_time, "kernel": kernel},
        "materials": {"rubber": neo_hookean(1e6, 0.3, 1000.0)},
        "bodies": [{"material": "rubber", "shape": {"box": {"min": [1.1, 0.2], "max": [1.9, 0.3]}},
                    "particles_per_cell": ppc}],
        "obstacles": [grip(0.9, -GRIP_SPEED), grip(1.85, GRIP_SPEED)],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// Most the bar's particles may lie apart along it, m: two cells. A bar that stays whole
/// has its columns (1/ppc cell apart at the start) about (1 + stretch)/ppc cells apart; a
/// bar whose particles lost their grid connection breaks, and its halves recoil with the
/// grips (gaps of 0.2 to 0.7 m).
pub const MAX_GAP: f64 = 2.0 * DX;

/// The largest gap between neighbouring particles along x in the last frame, and where it
/// starts.
fn largest_gap(frames: &Frames) -> Result<(f64, f64), String> {
    let (_, x) = frames.first_and_last("x")?;
    let mut along: Vec<f64> = x.chunks_exact(2).map(|p| p[0]).collect();
    if along.iter().any(|a| !a.is_finite()) {
        return Err("a particle position is not a number".into());
    }
    along.sort_by(f64::total_cmp);
    Ok(along
        .windows(2)
        .map(|w| (w[1] - w[0], w[0]))
        .fold((0.0, f64::NAN), |a, b| if b.0 > a.0 { b } else { a }))
}

/// The bar stays whole: no gap along it wider than [`MAX_GAP`].
pub fn connected(_: &Metrics, frames: &Frames) -> Result<String, String> {
    let (gap, at) = largest_gap(frames)?;
    judge_gap(gap, at)
}

fn judge_gap(gap: f64, at: f64) -> Result<String, String> {
    if gap <= MAX_GAP {
        Ok(format!(
            "largest gap along the bar {gap:.4} m (bound {MAX_GAP} m)"
        ))
    } else {
        Err(format!(
            "the bar broke: a gap of {gap:.4} m from x = {at:.3} m (bound {MAX_GAP} m)"
        ))
    }
}

// ---------------------------------------------------------------------------------------
// Cell crossing: a soft column settling under gravity in a slip box.

/// Height of the column at rest, m.
const COLUMN: f64 = 1.0;
/// Density of the column, kg/m³.
const COLUMN_DENSITY: f64 = 1000.0;

/// A soft column (E 5e4 Pa, 0.2 × 1 m, cell 0.05 m) between slip walls settling under
/// gravity with damping 20/s for 2 s (about four periods of its lowest mode): it shortens
/// by about a cell, so its upper particles cross cells, with shape functions `kernel`.
pub fn column(kernel: &str) -> Value {
    json!({
        "name": "peer-column", "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.2, 1.2], "cell_size": 0.05,
                   "walls": [{"sides": ["x-", "x+", "y-"], "condition": "slip"}]},
        "solver": {"end_time": 2.0, "gravity": [0, -G], "damping": 20.0, "kernel": kernel},
        "materials": {"soil": neo_hookean(5e4, 0.3, COLUMN_DENSITY)},
        "bodies": [{"material": "soil", "shape": {"box": {"min": [0, 0], "max": [0.2, COLUMN]}}}],
        "output": {"frames": 1, "fields": ["x", "stress"]}
    })
}

/// Most the column's σ_yy may scatter about the weight above each particle, relative L2.
pub const MAX_STRESS_NOISE: f64 = 0.05;

/// The relative L2 difference of σ_yy in the last frame from −ρ g (H − Y), the weight of the
/// column above each particle's starting height Y (exact at rest in a slip box, at any
/// strain: what lies above a particle does not change).
fn stress_noise(frames: &Frames) -> Result<f64, String> {
    let (x0, _) = frames.first_and_last("x")?;
    let (_, stress) = frames.first_and_last("stress")?;
    let (mut diff, mut norm) = (0.0, 0.0);
    for (x, s) in x0.chunks_exact(2).zip(stress.chunks_exact(4)) {
        let reference = -COLUMN_DENSITY * G * (COLUMN - x[1]);
        diff += (s[3] - reference).powi(2);
        norm += reference * reference;
    }
    let noise = (diff / norm).sqrt();
    if noise.is_finite() {
        Ok(noise)
    } else {
        Err("the stress is not a number".into())
    }
}

/// σ_yy lies on the weight above each particle to [`MAX_STRESS_NOISE`].
pub fn hydrostatic(_: &Metrics, frames: &Frames) -> Result<String, String> {
    judge_noise(stress_noise(frames)?)
}

fn judge_noise(noise: f64) -> Result<String, String> {
    let text =
        format!("σyy off the weight above by {noise:.2e} rel. L2 (bound {MAX_STRESS_NOISE})");
    if noise <= MAX_STRESS_NOISE {
        Ok(text)
    } else {
        Err(format!("stress noise: {text}"))
    }
}

// ---------------------------------------------------------------------------------------
// Near-zero mass: a surface row just past a grid line.

/// Speed of the block when it lands, m/s.
const LANDING: f64 = 0.5;
/// Simulated time, s.
const LANDING_TIME: f64 = 0.2;

/// A rubber block (E 1e5 Pa, 0.4 × 0.2 m, 16 rows of particles half a cell apart) landing on
/// a slip floor at 0.5 m/s, placed so that its top row lies `offset` cells past the grid
/// line (linear shape functions: 1e-6 above a line gives the node above a millionth of the
/// row's weight; quadratic B-splines: 1.414e-3 past a cell's middle gives the node 1.5 cells
/// away 1e-6), at Courant number `cfl`.
pub fn near_zero_mass(kernel: &str, offset: f64, cfl: f64) -> Value {
    // Rows at bottom + (i + 1/2)·DX/2, i < 16: the top one at bottom + 7.75·DX.
    let top = if kernel == "linear" { 8.0 } else { 8.5 };
    let bottom = (top + offset - 7.75) * DX;
    json!({
        "name": "peer-near-zero-mass", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 0.5], "cell_size": DX,
                   "walls": [{"sides": ["y-"], "condition": "slip"}]},
        "solver": {"end_time": LANDING_TIME, "gravity": [0, -G], "kernel": kernel, "cfl": cfl},
        "materials": {"rubber": neo_hookean(1e5, 0.3, 1000.0)},
        "bodies": [{"material": "rubber",
                    "shape": {"box": {"min": [0.3, bottom], "max": [0.7, bottom + 8.0 * DX]}},
                    "velocity": {"uniform": [0.0, -LANDING]}}],
        "output": {"frames": 1, "fields": ["x"]}
    })
}

/// Fastest a particle of the landing block may go, m/s: its landing speed plus what gravity
/// adds over the run, doubled for the elastic rebound's waves (0.5 + 9.81 × 0.2 = 2.46, × 2).
pub const MAX_LANDING_SPEED: f64 = 2.0 * (LANDING + G * LANDING_TIME);

/// The largest particle speed over the run stays under [`MAX_LANDING_SPEED`].
pub fn bounded_speed(metrics: &Metrics, _: &Frames) -> Result<String, String> {
    judge_speed(metrics.max_speed)
}

fn judge_speed(speed: f64) -> Result<String, String> {
    if speed <= MAX_LANDING_SPEED {
        Ok(format!(
            "fastest particle {speed:.3} m/s (bound {MAX_LANDING_SPEED:.2} m/s)"
        ))
    } else {
        Err(format!(
            "a particle reached {speed:.3e} m/s (bound {MAX_LANDING_SPEED:.2} m/s)"
        ))
    }
}

// ---------------------------------------------------------------------------------------
// Creep: a block resting on the floor for 8 s, 12,581 steps.

/// A rubber block (E 1e5 Pa, ν 0.3, 0.4 × 0.2 m, 512 particles) set down stress-free on a
/// slip floor under gravity, with velocity damping 1/s, for 8 s (12,581 steps): after its
/// start-up oscillation has died away, anything that still moves its centre is creep.
pub fn resting() -> Value {
    json!({
        "name": "peer-resting", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 0.5], "cell_size": DX,
                   "walls": [{"sides": ["y-"], "condition": "slip"}]},
        "solver": {"end_time": 8.0, "gravity": [0, -G], "damping": 1.0},
        "materials": {"rubber": neo_hookean(1e5, 0.3, 1000.0)},
        "bodies": [{"material": "rubber", "shape": {"box": {"min": [0.3, 0.0], "max": [0.7, 0.2]}}}],
        "output": {"frames": 20, "fields": ["x"]}
    })
}

/// Most the block's centre of mass may move over the second half of the run, m (1/250 of a
/// cell): by then it has settled, so anything more is creep.
pub const MAX_CREEP: f64 = 1e-4;
/// Most kinetic energy the block may keep at the end, relative to its strain energy.
pub const MAX_RESTING_KINETIC: f64 = 1e-3;

/// The centre of a frame's particles (equal masses: one material, one lattice).
fn centre(x: &[f64]) -> [f64; 2] {
    let n = (x.len() / 2).max(1) as f64;
    let (sx, sy) = x
        .chunks_exact(2)
        .fold((0.0, 0.0), |(a, b), p| (a + p[0], b + p[1]));
    [sx / n, sy / n]
}

/// The block's creep (how far its centre moved over the second half of the run) and its
/// kinetic energy at the end relative to its strain energy.
fn creep(frames: &Frames) -> Result<(f64, f64), String> {
    let n = frames.frames.len();
    let positions = |i: usize| frames.field(i, "x").ok_or("the run kept no `x` frames");
    if n < 3 {
        return Err("the run kept fewer than three frames".into());
    }
    let half = centre(positions(n / 2)?);
    let mut drift: f64 = 0.0;
    for i in n / 2..n {
        let c = centre(positions(i)?);
        let moved = (c[0] - half[0]).hypot(c[1] - half[1]);
        if moved.is_nan() {
            return Err("a particle position is not a number".into());
        }
        drift = drift.max(moved);
    }
    let kinetic = frames.diagnostic(n - 1, "kinetic_energy");
    let strain = frames.diagnostic(n - 1, "strain_energy");
    let ratio = match (kinetic, strain) {
        (Some(k), Some(s)) if s > 0.0 => k / s,
        _ => f64::NAN,
    };
    Ok((drift, ratio))
}

/// The resting block does not creep and keeps next to no kinetic energy.
pub fn no_creep(_: &Metrics, frames: &Frames) -> Result<String, String> {
    let (drift, kinetic) = creep(frames)?;
    judge_creep(drift, kinetic)
}

fn judge_creep(drift: f64, kinetic: f64) -> Result<String, String> {
    let text = format!(
        "centre moved {drift:.2e} m over the 2nd half (bound {MAX_CREEP:e}), KE/SE {kinetic:.1e} (bound {MAX_RESTING_KINETIC:e})"
    );
    if drift <= MAX_CREEP && kinetic <= MAX_RESTING_KINETIC {
        Ok(text)
    } else {
        Err(format!("creep: {text}"))
    }
}

/// The peer cases, appended to the suite.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "peer-tension-separation",
            what: "rubber bar pulled by stick grips to twice its length, 3x3 particles per cell (2x2 break it): no gap over 2 cells",
            scene: tension("bspline2", 1.0, 3),
            expected: Expected::Finished,
            check: Some(connected),
        },
        Case {
            name: "peer-cell-crossing-linear",
            what: "soft column settling a cell under gravity, GIMP (linear scatters 25%): sigma_yy on the weight above to 5%",
            scene: column("gimp"),
            expected: Expected::Finished,
            check: Some(hydrostatic),
        },
        Case {
            name: "peer-near-zero-mass",
            what: "block landing, linear shape functions, its top row 1e-6 cell above a grid line (a node with 1e-6 of its mass): speeds stay bounded",
            scene: near_zero_mass("linear", 1e-6, 0.03),
            expected: Expected::Finished,
            check: Some(bounded_speed),
        },
        Case {
            name: "peer-resting-creep",
            what: "block resting on a slip floor for 8 s (12,600 steps): its centre must not creep",
            scene: resting(),
            expected: Expected::Finished,
            check: Some(no_creep),
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stability::run_case;
    use crate::stability_case::Check;
    use mpm_core::output::FieldInfo;

    #[test]
    fn the_checks_fail_on_wrong_physics() {
        assert!(judge_gap(0.03, 1.0).is_ok());
        assert!(judge_gap(0.3, 1.0).is_err());
        assert!(judge_gap(f64::NAN, 1.0).is_err());
        assert!(judge_noise(0.01).is_ok());
        assert!(judge_noise(0.2).is_err());
        assert!(judge_noise(f64::NAN).is_err());
        assert!(judge_speed(1.0).is_ok());
        assert!(judge_speed(1e3).is_err());
        assert!(judge_speed(f64::NAN).is_err());
        assert!(judge_creep(1e-6, 1e-6).is_ok());
        assert!(judge_creep(1e-2, 1e-6).is_err());
        assert!(judge_creep(1e-6, 0.5).is_err());
        assert!(judge_creep(f64::NAN, 0.0).is_err());
    }

    #[test]
    fn a_broken_bar_fails_its_check() {
        // Two halves of a bar, 0.2 m apart.
        let mut frames = Frames {
            fields: vec![FieldInfo {
                name: "x".into(),
                shape: vec![2],
            }],
            frames: Vec::new(),
        };
        let whole: Vec<f64> = (0..20).flat_map(|i| [i as f64 * 0.01, 0.0]).collect();
        let broken: Vec<f64> = (0..20)
            .flat_map(|i| [i as f64 * 0.01 + if i < 10 { 0.0 } else { 0.2 }, 0.0])
            .collect();
        frames.frames.push((0.0, vec![whole.clone()], vec![]));
        frames.frames.push((1.0, vec![whole], vec![]));
        let metrics = Metrics::default();
        assert!(connected(&metrics, &frames).is_ok());
        frames.frames[1].1[0] = broken;
        assert!(connected(&metrics, &frames).unwrap_err().contains("broke"));
        // No frames at all: an error, not a panic.
        assert!(connected(&metrics, &Frames::default()).is_err());
        assert!(no_creep(&metrics, &Frames::default()).is_err());
        assert!(hydrostatic(&metrics, &Frames::default()).is_err());
    }

    /// The peer scenes with other shape functions, stretches, particle counts and steps:
    /// the figures the README quotes beside the suite's. `cargo test -p mpm-cli --profile
    /// test --lib peer_variants -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn peer_variants() {
        let registry = crate::default_registry();
        let set = |mut s: Value, path: &[&str], v: Value| {
            let mut at = &mut s;
            for p in path {
                at = &mut at[*p];
            }
            *at = v;
            s
        };
        let mut variants: Vec<(String, Value, Check)> = Vec::new();
        for kernel in ["linear", "gimp", "bspline2", "bspline3", "cpdi2"] {
            for stretch in [0.5, 0.75, 1.0, 1.5, 2.0] {
                for ppc in [2, 3, 4] {
                    let s = tension(kernel, stretch, ppc);
                    variants.push((
                        format!("tension {kernel} stretch {stretch} ppc {ppc}"),
                        s,
                        connected,
                    ));
                }
            }
            for end in [2.0, 4.0] {
                let s = set(column(kernel), &["solver", "end_time"], json!(end));
                variants.push((format!("column {kernel} end {end}"), s, hydrostatic));
            }
        }
        for (kernel, offset) in [
            ("linear", 1e-6),
            ("linear", 0.25),
            ("bspline2", 1.414e-3),
            ("bspline2", 0.25),
        ] {
            for cfl in [0.3, 0.1, 0.03] {
                for transfer in ["apic", "flip"] {
                    let s = set(
                        near_zero_mass(kernel, offset, cfl),
                        &["solver", "transfer"],
                        json!(transfer),
                    );
                    variants.push((
                        format!("near-zero-mass {kernel} offset {offset} cfl {cfl} {transfer}"),
                        s,
                        bounded_speed,
                    ));
                }
            }
        }
        for (damping, end) in [(0.0, 8.0), (1.0, 8.0), (1.0, 16.0)] {
            let s = set(resting(), &["solver", "damping"], json!(damping));
            let s = set(s, &["solver", "end_time"], json!(end));
            variants.push((format!("resting damping {damping} end {end}"), s, no_creep));
        }
        for (name, scene, check) in variants {
            let case = Case {
                name: "variant",
                what: "",
                scene,
                expected: Expected::Finished,
                check: Some(check),
            };
            let r = run_case(&case, &registry);
            println!(
                "{name}: {} pass {} steps {} wall {:.2} drift {:+.2e} det F {:.3} max speed {:.3} | {}",
                r.outcome,
                r.pass,
                r.steps,
                r.wall_seconds,
                r.energy_drift,
                r.min_det_f,
                r.max_speed,
                r.note
            );
        }
    }
}
