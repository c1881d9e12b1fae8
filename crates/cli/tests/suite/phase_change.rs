//! Phase change end to end: Stefan problems against Neumann's solution, cure against the
//! Kamal–Sourour closed form and the adiabatic energy balance, and input errors.

use crate::common;

use common::{load_example, run};
use mpm_core::output::Outcome;

fn error_of(name: &str, overrides: &[&str]) -> f64 {
    let m = run(&load_example(name, overrides));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{name} {overrides:?}");
    m.error.expect("the scene has a reference")
}

/// One-phase Stefan problem (Stefan number 0.1), front position against Neumann's
/// solution. Measured: 2.8e-3 at cell 0.5 mm / dt 0.1 s, 7.9e-4 at 0.25 mm / 0.025 s.
/// Bounds: the error falls by at least 2x, and the fine run is within 1.5e-3.
#[test]
fn one_phase_stefan_front_converges_to_neumann() {
    let coarse = error_of(
        "stefan-one-phase.json",
        &["domain.cell_size=0.0005", "solver.dt=0.1"],
    );
    let fine = error_of(
        "stefan-one-phase.json",
        &["domain.cell_size=0.00025", "solver.dt=0.025"],
    );
    assert!(fine < 0.5 * coarse, "{coarse} -> {fine}");
    assert!(fine < 1.5e-3, "{fine}");
}

/// Two-phase Stefan problem (heat also flows into the subcooled solid). Measured: 4.5e-2
/// at cell 0.5 mm / dt 0.1 s, 2.3e-2 at 0.25 mm / 0.025 s. Bounds: the error falls by at
/// least a third, and the fine run is within 3.5e-2.
#[test]
fn two_phase_stefan_front_converges_to_neumann() {
    let coarse = error_of(
        "stefan-two-phase.json",
        &["domain.cell_size=0.0005", "solver.dt=0.1"],
    );
    let fine = error_of(
        "stefan-two-phase.json",
        &["domain.cell_size=0.00025", "solver.dt=0.025"],
    );
    assert!(fine < 0.67 * coarse, "{coarse} -> {fine}");
    assert!(fine < 3.5e-2, "{fine}");
}

/// Isothermal cure, m = n = 1: the mean degree of cure follows the closed form (measured
/// RMS error 1.4e-11 at dt = 1 s; bound 1e-6) and reaches 0.9.
#[test]
fn isothermal_cure_follows_the_closed_form() {
    let m = run(&load_example("cure-isothermal.json", &[]));
    assert!(m.error.unwrap() < 1e-6, "{:?}", m.error);
    assert!(m.measured_value.unwrap() > 0.9, "{:?}", m.measured_value);
}

/// Adiabatic cure: the heat of reaction, released through the grid, raises T by (H/c)·α
/// (measured: 2.7e-10 of H/c; bound 1e-6).
#[test]
fn adiabatic_cure_keeps_its_heat() {
    let m = run(&load_example("cure-adiabatic.json", &[]));
    assert!(m.error.unwrap() < 1e-6, "{:?}", m.error);
}

/// Bad input is named by JSON path.
#[test]
fn phase_change_input_errors_name_their_path() {
    let issues = |overrides: &[&str]| common::invalid_example("stefan-one-phase.json", overrides);
    let has = |lines: &[String], needle: &str| lines.iter().any(|l| l.contains(needle));
    let e = issues(&["physics.phase_change.materials.wax.melting.latent_heat=-1"]);
    assert!(
        has(&e, "physics.phase_change.materials.wax.melting.latent_heat"),
        "{e:?}"
    );
    let e = issues(&[r#"physics={"phase_change":{"materials":{}}}"#]);
    assert!(has(&e, "physics.phase_change"), "{e:?}");
    assert!(has(&e, "physics.thermal"), "{e:?}");
    let e = issues(&[
        r#"materials.wax={"type":"phase_mixture","density":1000,"solid":{"youngs_modulus":1e9,"poisson_ratio":0.3},"liquid":{"viscosity":1,"bulk_modulus":1e6}}"#,
        r#"physics={"thermal":{"materials":{"wax":{"conductivity":1,"specific_heat":1000,"initial_temperature":300}}}}"#,
        r#"reference=null"#,
    ]);
    assert!(has(&e, "materials.wax.type"), "{e:?}");
    assert!(has(&e, "solid_fraction"), "{e:?}");
}
