//! The energy ledger (`metrics.energy_ledger`, the store's `diagnostics/dissipated_energy`
//! and `diagnostics/energy_error`): work and dissipation by cause, so that the energy
//! drift left over is the method's own error.

use crate::common;

use common::*;
use mpm_core::output::Outcome;

#[test]
fn damping_is_booked_not_counted_as_error() {
    // The vibrating bar with grid damping: most of its energy is damped away, and the
    // ledger must say so, leaving the method's error of the undamped bar (3e-3 below).
    let undamped = run(&load_example("vibrating-bar.json", &[]));
    let m = run(&load_example("vibrating-bar.json", &["solver.damping=2"]));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let ledger = m.energy_ledger;
    println!(
        "damped {:.4e} J, drift {:.3e} (undamped {:.3e})",
        ledger.damping, m.energy_drift, undamped.energy_drift
    );
    assert!(ledger.damping > 0.0);
    assert_eq!(ledger.plastic, 0.0);
    // Measured −2.0e-4 (undamped −3.6e-3) with 2.75e-6 J damped, 55% of the bar's 5e-6 J:
    // unbooked, the drift would be about −0.55.
    assert!(
        m.energy_drift.abs() < 0.01,
        "drift {} with damping booked",
        m.energy_drift
    );
}

#[test]
fn plastic_work_is_booked_and_the_store_keeps_the_ledger_over_time() {
    // The holed plate pulled by its grip for 30 µs: the grip works on the plate, plasticity
    // dissipates most of it.
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("plate.zarr");
    let m = run_to_store(
        &load_example(
            "holed-plate.json",
            &["solver.end_time=3e-5", "output.frames=3"],
        ),
        &store,
    );
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let ledger = m.energy_ledger;
    println!(
        "grip work {:.4e}, plastic {:.4e}, drift {:.3e}",
        ledger.boundaries, ledger.plastic, m.energy_drift
    );
    assert!(ledger.boundaries > 0.0);
    assert!(ledger.plastic > 0.1 * ledger.boundaries);
    // Measured −7.4% left over: the grip starts impulsively (its nodes jump to 40 m/s, an
    // inelastic start that loses half the work it does there) and holds its nodes stuck.
    // Plastic work alone is 80% of the grip's work: unbooked, the drift would be far larger.
    assert!(m.energy_drift.abs() < 0.1, "drift {}", m.energy_drift);
    let r = mpm_io::ResultStore::open(&store).unwrap();
    let dissipated = r.diagnostic("dissipated_energy").unwrap();
    let error = r.diagnostic("energy_error").unwrap();
    assert_eq!(dissipated.len(), 4);
    assert!((dissipated[3] - ledger.dissipated()).abs() <= 1e-9 * ledger.dissipated());
    assert!(error.iter().all(|e| e.is_finite()));
}

#[test]
fn wall_friction_is_booked() {
    // A soft block thrown at 2 m/s along a floor wall with Coulomb friction μ = 0.3 stops
    // after about 0.68 s (2 m/s over μg): friction takes its kinetic energy, and the ledger
    // must book it (unbooked, the drift would be about −1).
    let scene = serde_json::json!({
        "name": "wall-friction", "dimension": 2,
        "domain": {"min": [0, 0], "max": [2.0, 0.3], "cell_size": 0.02,
                   "walls": [{"sides": ["y-"], "condition": {"friction": {"coefficient": 0.3}}}]},
        "solver": {"end_time": 1.0, "gravity": [0, -9.81], "cfl": 0.3},
        "materials": {"block": {"type": "linear_elastic", "density": 1000.0,
                                "youngs_modulus": 1e6, "poisson_ratio": 0.3}},
        "bodies": [{"name": "block", "material": "block",
                    "shape": {"box": {"min": [0.2, 0.0], "max": [0.4, 0.08]}},
                    "velocity": {"uniform": [2.0, 0.0]}}],
        "output": {"frames": 10, "fields": ["x", "v"]}
    });
    let dir = tempfile::tempdir().unwrap();
    let m = run(&load(
        &write_scene(dir.path(), "friction.json", &scene),
        &[],
    ));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let kinetic = 0.5 * 1000.0 * 0.2 * 0.08 * 2.0 * 2.0;
    let ledger = m.energy_ledger;
    println!(
        "friction {:.4e} J/m of {kinetic:.4e}, drift {:.3e}, max speed {:.3e}",
        ledger.friction, m.energy_drift, m.max_speed
    );
    assert!(
        ledger.friction > 0.8 * kinetic && ledger.friction < 1.2 * kinetic,
        "friction booked {} of {kinetic}",
        ledger.friction
    );
    assert!(m.energy_drift.abs() < 0.1, "drift {}", m.energy_drift);
}

/// The diagnostic `name` of every frame.
fn diagnostic(frames: &FieldFrames, name: &str) -> Vec<f64> {
    let d = mpm_core::output::FRAME_DIAGNOSTICS
        .iter()
        .position(|n| *n == name)
        .unwrap();
    frames.diagnostics.iter().map(|f| f[d]).collect()
}

/// Energy the series solution of plane Poiseuille start-up (body force `g` along a channel
/// of gap `h` and length `length`, liquid at rest at t = 0) has dissipated by time `t`:
/// ∫∫ μ (∂u/∂y)² dy dt, J/m. With u = Σ_n odd a_n sin(nπy/h)(1 − e^{−λ_n t}),
/// a_n = 4gh²/(ν n³ π³), λ_n = ν n²π²/h², the modes are orthogonal in ∂u/∂y and each
/// contributes μ (nπ/h)² a_n² (h/2) ∫ (1 − e^{−λ_n t})² dt.
fn poiseuille_dissipation(rho: f64, mu: f64, g: f64, h: f64, length: f64, t: f64) -> f64 {
    let nu = mu / rho;
    let pi = std::f64::consts::PI;
    (1..2000)
        .step_by(2)
        .map(|n| {
            let n = n as f64;
            let a = 4.0 * g * h * h / (nu * n.powi(3) * pi.powi(3));
            let lambda = nu * n * n * pi * pi / (h * h);
            let e = (-lambda * t).exp();
            // ∫0^t (1 − e^{−λs})² ds
            let time = t - 2.0 * (1.0 - e) / lambda + (1.0 - e * e) / (2.0 * lambda);
            mu * (n * pi / h).powi(2) * a * a * 0.5 * h * time
        })
        .sum::<f64>()
        * length
}

#[test]
fn liquid_viscous_dissipation_follows_the_poiseuille_start_up() {
    // The liquid Poiseuille channel (μ = 1 Pa·s, body force 0.8 m/s², 10 mm gap, 80 mm
    // long, 10 cells across) for 0.03 s, three decay times: the series solution has
    // dissipated 6.835e-5 J/m. Measured: 6.554e-5 booked (−4.1%), drift −0.117 of the
    // largest kinetic energy (unbooked it would be about −3.6); at 20 cells across −0.53%
    // and −0.0057. Bounds: 6% and 0.15.
    let m = run(&load_example("liquid-poiseuille.json", &[]));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let reference = poiseuille_dissipation(1000.0, 1.0, 0.8, 0.01, 0.08, 0.03);
    let booked = m.energy_ledger.viscous;
    println!(
        "viscous {booked:.4e} J/m of {reference:.4e} ({:+.2}%), drift {:.3e}",
        100.0 * (booked / reference - 1.0),
        m.energy_drift
    );
    assert!((reference - 6.835e-5).abs() < 1e-8, "series {reference}");
    assert!(
        (booked / reference - 1.0).abs() < 0.06,
        "booked {booked} of {reference}"
    );
    assert!(m.energy_drift.abs() < 0.15, "drift {}", m.energy_drift);
}

#[test]
fn an_oscillating_drop_books_its_viscous_damping_and_keeps_its_surface_energy() {
    // The 2D drop (R = 5 mm, σ = 0.07 N/m, μ = 1 mPa·s, 10 cells across its radius) set
    // oscillating in its second mode, for 0.1 s. At rest its surface energy is 2πRσ =
    // 2.199e-3 J/m. Potential flow v = a(t)(x, −y) dissipates 4μa²πR² while its kinetic
    // energy is ρa²πR⁴/4, so with a(t) = a₀ cos(ωt) e^{−4νt/R²} (Lamb's ω² = 6σ/(ρR³),
    // and the damping 2ν n(n−1)/R² of the amplitude, n = 2) the energy dissipated by t is
    // E₀ (16ν/R²) ∫₀ᵗ cos²(ωs) e^{−8νs/R²} ds, E₀ the initial kinetic energy.
    // Measured: surface energy 2.1902e-3 at the start (−0.40%); viscous dissipation
    // 1.222e-7 of 1.308e-7 (−6.6%; the drop's period is 8% longer than Lamb's, so at
    // 0.1 s it is earlier in its swing; −2.6% over 0.25 s). The method damps the drop as
    // well (the transfer and the projection): that is left in the drift, not hidden.
    // Bounds: 1% and 10%.
    let (m, frames) = run_fields(
        &load_example("liquid-drop-oscillation.json", &["solver.end_time=0.1"]),
        &["x"],
    );
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let (radius, sigma, nu, rho, end) = (0.005, 0.07, 1e-6, 1000.0, 0.1);
    let surface = diagnostic(&frames, "surface_energy");
    let kinetic = diagnostic(&frames, "kinetic_energy");
    let at_rest = 2.0 * std::f64::consts::PI * radius * sigma;
    let omega = (6.0 * sigma / (rho * radius.powi(3))).sqrt();
    let decay = 8.0 * nu / (radius * radius);
    let n = 100_000;
    let ds = end / n as f64;
    let integral: f64 = (0..n)
        .map(|k| {
            let s = (k as f64 + 0.5) * ds;
            (omega * s).cos().powi(2) * (-decay * s).exp() * ds
        })
        .sum();
    let lost = kinetic[0] * 2.0 * decay * integral;
    let booked = m.energy_ledger.viscous;
    println!(
        "surface {:.4e} J/m at the start ({:+.2}% of 2πRσ), viscous {booked:.4e} of \
         {lost:.4e} ({:+.2}%), drift {:.3e}",
        surface[0],
        100.0 * (surface[0] / at_rest - 1.0),
        100.0 * (booked / lost - 1.0),
        m.energy_drift
    );
    assert!(
        (surface[0] / at_rest - 1.0).abs() < 0.01,
        "surface energy {}",
        surface[0]
    );
    assert!(
        (booked / lost - 1.0).abs() < 0.1,
        "booked {booked} of {lost}"
    );
}

#[test]
fn a_meniscus_books_the_wetting_energy_that_draws_it_up() {
    // The meniscus between two walls 10 mm apart with a contact angle of 30°, liquid 10 mm
    // deep and flat at the start: its surface energy is σw − 2σ cos θ h₀ = −5.124e-4 J/m
    // (Young: each wetted wall counts (γ_SL − γ_SV) = −σ cos θ). The arc it relaxes to
    // (radius w/(2 cos θ), 60° half-angle) is 2.09 mm longer and the contact lines climb
    // 2.05 mm (the area between chord and arc): −6.142e-4 J/m, 1.018e-4 released, which
    // viscosity dissipates. Measured at 20 cells across: −5.262e-4 at the start (+2.7%,
    // the colour's kink where the flat surface meets a 30° wall; +1.35% at 40 cells),
    // −5.983e-4 at the end (−2.6%; −2.8% at 40 cells), so 7.21e-5 released (7.79e-5 at 40
    // cells: the difference of two nearly equal sums, 23–29% short of the theory), drift
    // −0.0155 of the largest mechanical energy. Bounds: 5%, 5%, 0.05.
    let (m, frames) = run_fields(&load_example("liquid-meniscus.json", &[]), &["x"]);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let (sigma, cos, w, h0) = (0.07, 30f64.to_radians().cos(), 0.01, 0.01);
    let surface = diagnostic(&frames, "surface_energy");
    let flat = sigma * w - 2.0 * sigma * cos * h0;
    let radius = w / (2.0 * cos);
    let half_angle = (0.5 * w / radius).asin();
    let arc = 2.0 * radius * half_angle;
    let segment = 0.5 * radius * radius * (2.0 * half_angle - (2.0 * half_angle).sin());
    let climbed = h0 + segment / w;
    let curved = sigma * arc - 2.0 * sigma * cos * climbed;
    let last = surface[surface.len() - 1];
    println!(
        "surface {:.4e} J/m at the start ({:+.2}% of {flat:.4e}), {last:.4e} at the end \
         ({:+.2}% of {curved:.4e}), viscous {:.4e}, drift {:.3e}",
        surface[0],
        100.0 * (surface[0] / flat - 1.0),
        100.0 * (last / curved - 1.0),
        m.energy_ledger.viscous,
        m.energy_drift
    );
    assert!((curved + 6.142e-4).abs() < 1e-7, "arc {curved}");
    assert!(
        (surface[0] / flat - 1.0).abs() < 0.05,
        "surface energy {} at the start",
        surface[0]
    );
    assert!(
        (last / curved - 1.0).abs() < 0.05,
        "surface energy {last} at the end"
    );
    assert!(m.energy_drift.abs() < 0.05, "drift {}", m.energy_drift);
}

#[test]
fn the_volume_source_work_is_reported_and_kept_out_of_the_balance() {
    // The inflow tank (an inlet adds water to a tank, the volume source moves misplaced
    // particle volume back): the balance left +1.70 of its largest mechanical energy
    // unexplained (7.1e-4 J/m), which had been put down to the source's work. Measured,
    // that work Σ p ΔV is 1.67e-2 J/m, 23 times as much, and 7.8e-2 at `cfl` 0.1: most of
    // what the correction puts in the method takes back within the step, so it is
    // reported in the ledger and kept out of the drift. Bounds: the work within a factor
    // of two; the drift as it was measured (+1.697 before the work was measured; +2.413
    // since particles that stray a hair behind a wall count in the cell in front of it,
    // stop 80: the level at rest rose from 7.78 to 7.86 mm, and the balance moved with it;
    // +4.183 since the source counts particles with tent weights, stop 83: the level at
    // rest 7.78 mm, 333 steps instead of 367, and more of the gain unexplained, an open
    // item of issue 19; the source's work 8.02e-3 J/m, half what it was, so the work's
    // bounds are a factor of two about that since stop 84, where they were about 1.67e-2;
    // +2.949 since particles without mass no longer count in G2P's statistics, stop 85:
    // their spurious speeds had set some steps, 335 steps instead of 333, level at
    // rest 7.66 mm, the source's work 9.27e-3 J/m). Until then the drift was pinned as
    // measured, a regression marker of a balance that did not close. Since stop 86 the
    // inlet lies in the wall and pushes the liquid in through its face (wall_inlet.rs),
    // whose pumping work Σ p U a dt is booked, with the kinetic energy its face's speed
    // gives the nodes: measured +0.0008 (324 steps), the source's work 1.04e-2 J/m;
    // the bound is now a balance check, |drift| < 0.3.
    let m = run(&load_example("liquid-inflow-tank.json", &[]));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let work = m.energy_ledger.volume_source;
    println!("volume source {work:.4e} J/m, drift {:.4}", m.energy_drift);
    assert!(work > 4e-3 && work < 1.6e-2, "volume source work {work}");
    assert!(m.energy_drift.abs() < 0.3, "drift {}", m.energy_drift);
}
