//! The stability suite's liquid-particle cases (`solver.mechanics.incompressible`): a
//! collapsing column from water to a paste at one step (implicit viscosity), the column on
//! Navier-slip walls at extreme slip lengths, menisci at the extreme contact angles, a drop
//! of a single particle with surface tension, and liquid let into a closed box past what it
//! holds.

use crate::stability_case::{Case, Expected, Frames};
use mpm_core::output::Metrics;
use serde_json::{Value, json};

/// Speed of the single-particle drop, m/s.
const DRIFT: f64 = 1e-3;
/// Height of the collapsing column, m.
const COLUMN: f64 = 0.1;

/// A water-like column 0.05 m × [`COLUMN`] collapsing in a tank, viscosity `mu` Pa·s,
/// implicit viscosity at a fixed step of 1 ms (the explicit viscous limit ρdx²/(4μ) is
/// 14 ms at 1e-3 Pa·s and 14 µs at 1e3).
fn column(mu: f64) -> Value {
    json!({
        "name": "liquid-column", "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.3, 0.15], "cell_size": 0.0075,
                   "walls": [{"sides": ["x-", "x+", "y-"], "condition": "slip"}]},
        "solver": {"end_time": 0.2, "dt": 0.001, "kernel": "bspline2", "transfer": "apic",
                   "gravity": [0, -9.81],
                   "mechanics": {"incompressible": {"viscosity": "implicit"}}},
        "materials": {"liquid": {"type": "liquid", "density": 1000.0,
                                 "viscosity": {"newtonian": mu}}},
        "bodies": [{"material": "liquid",
                    "shape": {"box": {"min": [0, 0], "max": [0.05, COLUMN]}}}],
        "output": {"frames": 4, "fields": ["x", "v"]}
    })
}

/// The water column of [`column`] on Navier-slip walls of slip length `b` (m), with implicit
/// or explicit viscosity.
fn navier_column(b: f64, implicit: bool) -> Value {
    let mut scene = column(1e-3);
    scene["domain"]["walls"] = json!([{"sides": ["x-", "x+", "y-"],
                                       "condition": {"navier": {"slip_length": b}}}]);
    if !implicit {
        scene["solver"]["mechanics"] = json!({"incompressible": {}});
    }
    scene
}

/// A meniscus between walls 5 mm apart (10 cells) without gravity, contact angle `angle`
/// degrees on both walls, σ = 0.07 N/m, μ = 0.2 Pa·s, 0.2 s from a flat start.
fn meniscus(angle: f64) -> Value {
    json!({
        "name": "liquid-meniscus", "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.005, 0.01], "cell_size": 0.0005,
                   "walls": [{"sides": ["x-", "x+"], "condition": "slip", "contact_angle": angle},
                             {"sides": ["y-"], "condition": "slip"}]},
        "solver": {"end_time": 0.2, "kernel": "bspline2", "transfer": "apic", "cfl": 0.5,
                   "gravity": [0, 0], "mechanics": {"incompressible": {}}},
        "materials": {"water": {"type": "liquid", "density": 1000.0,
                                "viscosity": {"newtonian": 0.2}, "surface_tension": 0.07}},
        "bodies": [{"material": "water",
                    "shape": {"box": {"min": [0, 0], "max": [0.005, 0.005]}}}],
        "output": {"frames": 4, "fields": ["x", "v"]}
    })
}

/// One particle of water with surface tension drifting at [`DRIFT`] without gravity.
fn single_particle_drop() -> Value {
    json!({
        "name": "single-particle-drop", "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.01, 0.01], "cell_size": 0.001},
        "solver": {"end_time": 0.05, "kernel": "bspline2", "transfer": "apic",
                   "gravity": [0, 0], "mechanics": {"incompressible": {}}},
        "materials": {"water": {"type": "liquid", "density": 1000.0,
                                "viscosity": {"newtonian": 0.001}, "surface_tension": 0.07}},
        "bodies": [{"material": "water", "particles_per_cell": 1,
                    "shape": {"box": {"min": [0.0045, 0.0045], "max": [0.0055, 0.0055]}},
                    "velocity": {"uniform": [DRIFT, 0.0]}}],
        "output": {"frames": 2, "fields": ["x", "v"]}
    })
}

/// A closed box 10 mm square (1 mm cells, slip walls, gravity) that water enters through a
/// 2 mm inlet by its left wall at 5e-4 m²/s for 0.4 s: the box holds 1e-4 m², full at
/// 0.2 s. The inlet's face stands half a cell in front of the wall: on the wall's plane
/// (a velocity condition there, incompressible/wall_inlet.rs) two particles at the
/// corner below the inlet sank 0.2 mm through the floor by 0.1 s (stop 86).
fn full_box() -> Value {
    json!({
        "name": "liquid-inflow-full-box", "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.01, 0.01], "cell_size": 0.001,
                   "walls": [{"sides": ["x-", "x+", "y-", "y+"], "condition": "slip"}]},
        "solver": {"end_time": 0.4, "kernel": "bspline2", "transfer": "apic", "cfl": 0.5,
                   "gravity": [0, -9.81], "mechanics": {"incompressible": {}}},
        "materials": {"water": {"type": "liquid", "density": 1000.0,
                                "viscosity": {"newtonian": 0.001}}},
        "bodies": [{"name": "inlet", "material": "water",
                    "shape": {"inflow": {"center": [0.0005, 0.002], "direction": [1, 0],
                                         "width": 0.002, "rate": 5e-4}}}],
        "output": {"frames": 8, "fields": ["x", "v", "injected"]}
    })
}

/// The full box: the run stopped because the inflow had nowhere to go (not for a failed
/// solve), in the step the first layer that does not fit is due (between 0.19 and 0.21 s;
/// a step is a few ms), with no particle out of the box.
fn full_box_check(m: &Metrics, frames: &Frames) -> Result<String, String> {
    let message = m
        .diagnostic
        .as_ref()
        .map(|d| d.message.clone())
        .unwrap_or_default();
    if !message.contains("nowhere to go") {
        return Err(format!("stopped for another reason: {message}"));
    }
    if !(0.19..=0.21).contains(&m.simulated_time) {
        return Err(format!(
            "stopped at {:.4} s; the box is full at 0.2 s",
            m.simulated_time
        ));
    }
    let (_, inside) = largest_speed(frames, [0.01, 0.01])?;
    if !inside {
        return Err("a particle left the box".into());
    }
    Ok(format!(
        "stopped at {:.4} s (full at 0.2 s): the inflow has nowhere to go",
        m.simulated_time
    ))
}

/// The same box fed by a reservoir at 100 Pa holding twice what the box holds.
fn pressure_full_box() -> Value {
    let mut scene = full_box();
    scene["name"] = json!("liquid-pressure-inlet-full-box");
    scene["bodies"][0]["shape"]["inflow"] = json!({
        "center": [0.0005, 0.002], "direction": [1, 0], "width": 0.002,
        "pressure": 100.0, "volume": 2e-4
    });
    scene
}

/// The pressure-fed box: the run stopped because the inflow had nowhere to go (not for a
/// failed solve, nor by a particle pushed out of the box), before its end.
fn pressure_full_box_check(m: &Metrics, frames: &Frames) -> Result<String, String> {
    let message = m
        .diagnostic
        .as_ref()
        .map(|d| d.message.clone())
        .unwrap_or_default();
    if !message.contains("nowhere to go") || !message.contains("smaller `volume`") {
        return Err(format!("stopped for another reason: {message}"));
    }
    let (_, inside) = largest_speed(frames, [0.01, 0.01])?;
    if !inside {
        return Err("a particle left the box".into());
    }
    Ok(format!(
        "stopped at {:.4} s, the box full: the reservoir's liquid has nowhere to go",
        m.simulated_time
    ))
}

/// A tank 20 mm × 10 mm walled all round (0.5 mm cells, slip walls, gravity) holding
/// water 4 mm deep and 1.2e-4 m² of air, which the liquid encloses as a gas; an inlet in
/// its left wall (since stop 86 on the wall's plane, a velocity condition there) adds
/// 4e-5 m² by 0.2 s, with implicit viscosity: Boyle leaves the air 8e-5 m² at 50.7 kPa
/// gauge.
fn sealed_air() -> Value {
    json!({
        "name": "liquid-inflow-sealed-air", "dimension": 2,
        "domain": {"min": [0, 0], "max": [0.02, 0.01], "cell_size": 0.0005,
                   "walls": [{"sides": ["x-", "x+", "y-", "y+"], "condition": "slip"}]},
        "solver": {"end_time": 0.3, "kernel": "bspline2", "transfer": "apic", "cfl": 0.5,
                   "gravity": [0, -9.81],
                   "mechanics": {"incompressible": {"enclosed_air": {}, "viscosity": "implicit"}}},
        "materials": {"water": {"type": "liquid", "density": 1000.0,
                                "viscosity": {"newtonian": 0.001}}},
        "bodies": [
            {"name": "pool", "material": "water", "particles_per_cell": 2,
             "shape": {"box": {"min": [0, 0], "max": [0.02, 0.004]}}},
            {"name": "inlet", "material": "water", "particles_per_cell": 2,
             "shape": {"inflow": {"center": [0.0, 0.002], "direction": [1, 0],
                                  "width": 0.004, "rate": 2e-4, "end": 0.2}}}
        ],
        "output": {"frames": 6, "fields": ["x", "v"]}
    })
}

/// The sealed tank: it finishes, its air's largest gauge pressure within 5% of Boyle's
/// 50.7 kPa, and no particle more than a quarter cell (0.125 mm) outside the box.
fn sealed_air_check(m: &Metrics, frames: &Frames) -> Result<String, String> {
    let boyle = 101325.0 * 1.2e-4 / 8e-5 - 101325.0;
    let air = m
        .physics
        .get("incompressible.air_pressure")
        .copied()
        .unwrap_or(0.0);
    if (air / boyle - 1.0).abs() > 0.05 {
        return Err(format!("air at {air:.0} Pa, Boyle {boyle:.0} Pa"));
    }
    let mut strayed: f64 = 0.0;
    for k in 0..frames.frames.len() {
        let Some(x) = frames.field(k, "x") else {
            return Err("the run kept no `x` frames to check".into());
        };
        for p in x.chunks_exact(2) {
            for (d, hi) in [0.02, 0.01].iter().enumerate() {
                strayed = strayed.max(-p[d]).max(p[d] - hi);
            }
        }
    }
    if strayed > 1.25e-4 {
        return Err(format!("a particle {strayed:.2e} m outside the box"));
    }
    Ok(format!(
        "air at {air:.0} Pa against Boyle's {boyle:.0} Pa; farthest particle {:.1e} m past a wall",
        strayed.max(0.0)
    ))
}

/// The largest particle speed over the frames, and whether every particle stayed inside
/// `[0, hi]` per axis (2D).
fn largest_speed(frames: &Frames, hi: [f64; 2]) -> Result<(f64, bool), String> {
    let mut speed: f64 = 0.0;
    let mut inside = true;
    for k in 0..frames.frames.len() {
        let (Some(x), Some(v)) = (frames.field(k, "x"), frames.field(k, "v")) else {
            return Err("the run kept no `x` and `v` frames to check".into());
        };
        for (p, u) in x.chunks_exact(2).zip(v.chunks_exact(2)) {
            speed = speed.max(u[0].hypot(u[1]));
            inside &= (0..2).all(|d| p[d] >= -1e-9 && p[d] <= hi[d] + 1e-9);
        }
    }
    Ok((speed, inside))
}

/// No particle faster than `bound` m/s (named `what`) over the frames, and none out of
/// `[0, hi]`.
fn speed_within(frames: &Frames, hi: [f64; 2], bound: f64, what: &str) -> Result<String, String> {
    let (speed, inside) = largest_speed(frames, hi)?;
    if !inside {
        return Err("a particle left the domain".into());
    }
    if speed > bound {
        return Err(format!(
            "largest speed {speed:.3e} m/s exceeds {what}, {bound:.3e} m/s"
        ));
    }
    Ok(format!(
        "largest speed {speed:.3e} m/s ({what} {bound:.3e} m/s)"
    ))
}

/// The collapsing column: no particle faster than the front of Ritter's dam break,
/// 2·√(g·H) (the shallow-water bound, above free fall from the top, √(2·g·H)), and none
/// out of the tank.
fn column_check(_: &Metrics, frames: &Frames) -> Result<String, String> {
    let bound = 2.0 * (9.81 * COLUMN).sqrt();
    speed_within(frames, [0.3, 0.15 + COLUMN], bound, "Ritter's front speed")
}

/// The meniscus: its largest speed stays below a tenth of the capillary speed σ/μ =
/// 0.35 m/s, and the liquid stays between the walls.
fn meniscus_check(_: &Metrics, frames: &Frames) -> Result<String, String> {
    speed_within(
        frames,
        [0.005, 0.01],
        0.1 * 0.07 / 0.2,
        "a tenth of sigma/mu",
    )
}

/// The single-particle drop: it keeps its speed within a tenth, and stays in the domain.
/// One particle's colour is a blob under two cells wide: its nodes' Laplace pressures
/// differ as it moves across cells, and it lost 3.1e-5 m/s of 1e-3 (an acceleration
/// 2e-6 of the capillary scale σ/(ρR²)) in 0.05 s; at rest it stays at rest to 3e-16 m/s.
fn drop_check(_: &Metrics, frames: &Frames) -> Result<String, String> {
    let (speed, inside) = largest_speed(frames, [0.01, 0.01])?;
    let last = frames.frames.len().saturating_sub(1);
    let v = frames.field(last, "v").unwrap_or(&[]);
    let change = v
        .chunks_exact(2)
        .map(|u| (u[0] - DRIFT).hypot(u[1]))
        .fold(0.0, f64::max);
    if !inside || speed > 1.1 * DRIFT || change > 0.1 * DRIFT {
        return Err(format!(
            "the drop's speed changed by {change:.3e} m/s (largest {speed:.3e} m/s, inside {inside})"
        ));
    }
    Ok(format!("velocity changed by {change:.3e} m/s of {DRIFT:e}"))
}

/// The liquid cases, appended to the suite.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "liquid-viscosity-1e-3",
            what: "liquid column collapsing, 1e-3 Pa s, implicit viscosity at 1 ms",
            scene: column(1e-3),
            expected: Expected::Finished,
            check: Some(column_check),
        },
        Case {
            name: "liquid-viscosity-1e3",
            what: "the same column at 1e3 Pa s and the same 1 ms step (1/70 of it would be the explicit viscous limit)",
            scene: column(1e3),
            expected: Expected::Finished,
            check: Some(column_check),
        },
        Case {
            name: "liquid-navier-slip-1e-9",
            what: "the 1e-3 Pa s column on Navier walls of slip length 1 nm (a wall drag 7.5e6 times a cell's viscous coupling), implicit viscosity at 1 ms",
            scene: navier_column(1e-9, true),
            expected: Expected::Finished,
            check: Some(column_check),
        },
        Case {
            name: "liquid-navier-slip-1e-9-explicit",
            what: "the same with explicit viscosity (the drag by backward Euler on its own)",
            scene: navier_column(1e-9, false),
            expected: Expected::Finished,
            check: Some(column_check),
        },
        Case {
            name: "liquid-navier-slip-1e3",
            what: "the same column on Navier walls of slip length 1 km (slip), implicit viscosity",
            scene: navier_column(1e3, true),
            expected: Expected::Finished,
            check: Some(column_check),
        },
        Case {
            name: "liquid-contact-angle-1",
            what: "meniscus between walls 10 cells apart, contact angle 1 degree (0 is refused: complete wetting has no static meniscus)",
            scene: meniscus(1.0),
            expected: Expected::Finished,
            check: Some(meniscus_check),
        },
        Case {
            name: "liquid-contact-angle-150",
            what: "the same meniscus at 150 degrees (non-wetting, bulging)",
            scene: meniscus(150.0),
            expected: Expected::Finished,
            check: Some(meniscus_check),
        },
        Case {
            name: "liquid-single-particle-drop",
            what: "a drop of one particle with surface tension drifting at 1 mm/s, no gravity",
            scene: single_particle_drop(),
            expected: Expected::Finished,
            check: Some(drop_check),
        },
        Case {
            name: "liquid-inflow-full-box",
            what: "water let into a closed box past what it holds (full at 0.2 s of 0.4 s)",
            scene: full_box(),
            expected: Expected::Stopped,
            check: Some(full_box_check),
        },
        Case {
            name: "liquid-inflow-sealed-air",
            what: "water let into a tank walled all round whose air it compresses, implicit viscosity",
            scene: sealed_air(),
            expected: Expected::Finished,
            check: Some(sealed_air_check),
        },
        Case {
            name: "liquid-pressure-inlet-full-box",
            what: "the same box fed by a reservoir at 100 Pa that holds twice the box",
            scene: pressure_full_box(),
            expected: Expected::Stopped,
            check: Some(pressure_full_box_check),
        },
    ]
}
