//! Implicit mechanics (`solver.mechanics.implicit`): verification against closed forms,
//! step cutting and its diagnostic, the unsupported body, and the settings' checks.

use crate::common;

use common::*;
use mpm_core::output::{Frame, Metrics, Outcome, OutputError, OutputSink, RunInfo};
use mpm_core::reference::bimaterial_curvature;
use mpm_core::solver::{Control, Progress, run_scene};

#[test]
fn bimaterial_strip_bends_to_timoshenkos_curvature() {
    // The example: 2D plane strain (`solver.free_strain_2d: plane_strain`, expansions
    // (1 + ν) α), 8 cells through the 1 mm strip, one load step: measured 0.57% from
    // Timoshenko's closed form. The in-plane-only model (the 2D default, expansions α)
    // against its own closed form: measured 0.57% too. Each run compares with the other
    // model's closed form, which must differ by tens of percent, not hide it.
    for (mode, other_sign) in [("plane_strain", 1.0), ("in_plane", -1.0)] {
        let physical = mode == "plane_strain";
        let m = run(&load_example(
            "bimaterial-strip.json",
            &[
                &format!("solver.free_strain_2d={mode}"),
                &format!("reference.out_of_plane_free_strain={physical}"),
            ],
        ));
        assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
        let error = m.error.expect("the strip has a reference");
        println!(
            "{mode}: curvature error {error:.3e}, comparisons {:?}",
            m.comparisons
        );
        assert!(error < 0.02, "{mode}: curvature error {error}");
        let other = m
            .comparisons
            .iter()
            .find(|c| c.quantity.contains("out_of_plane") != physical)
            .expect("both closed forms are compared");
        assert!(
            other_sign * other.relative_difference > 0.2,
            "{mode}: the other model's closed form should differ by about 27-37%, got {}",
            other.relative_difference
        );
    }
}

#[test]
fn implicit_fbar_removes_volumetric_locking_of_a_near_incompressible_beam() {
    // The short cantilever of the explicit F-bar test (L = 0.5 m, h = 0.1 m, 4 cells thick,
    // small load), solved in one implicit static step with ν = 0.4999. Measured: 16.6% too
    // stiff without anti-locking (51 GMRES iterations), 1.15% with F-bar over stencil
    // patches (8); with ν = 0.3, 4.4% and 5.8% (F-bar softens a little, as it does in the
    // explicit mode; the beam-theory reference leaves out shear, a few % at L/h = 5).
    let tip = |anti_locking: &str, nu: f64| {
        let m = run(&short_cantilever(
            nu,
            &[
                "solver.end_time=1",
                "solver.dt=1",
                "solver.damping=0",
                "output.frames=1",
                r#"solver.mechanics={"implicit":{}}"#,
                &format!("solver.anti_locking={anti_locking}"),
            ],
        ));
        assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
        (
            m.error.unwrap(),
            m.measured_value.unwrap() < m.reference_value.unwrap(),
        )
    };
    let (locked, stiff) = tip("none", 0.4999);
    assert!(locked > 0.1 && stiff, "expected locking: {locked}");
    let (fbar, _) = tip("fbar", 0.4999);
    assert!(fbar < 0.02, "F-bar error {fbar}");
    let (compressible, _) = tip("fbar", 0.3);
    assert!(
        compressible < 0.08,
        "F-bar error at ν = 0.3: {compressible}"
    );
}

#[test]
fn bimaterial_strip_in_3d_bends_to_the_biaxial_closed_form() {
    // Quarter model, 4 cells through the thickness: measured 1.9%.
    let m = run(&load_example("bimaterial-strip-3d.json", &[]));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let error = m.error.expect("the strip has a reference");
    println!("3D curvature error {error:.3e}");
    assert!(error < 0.04, "curvature error {error}");
}

#[test]
fn timoshenko_closed_form_matches_a_hand_value() {
    // Equal layers (m = n = 1): κ = 3 Δε / (2 h) = 1.5 · 2e-3 / 2e-3 = 1.5 /m.
    let k = bimaterial_curvature([1e-3, 1e-3], [70e9, 70e9], [1e-5, 3e-5], 100.0);
    assert!((k - 1.5).abs() < 1e-12, "{k}");
}

#[test]
fn implicit_dynamics_reproduces_the_vibrating_bar_beyond_the_explicit_step() {
    // Stable explicit step at cell 0.05: dx / c = 5e-3 s. Newmark average acceleration at
    // 1x and 2x of it; measured errors 5.0e-3 and 1.1e-2 (explicit at CFL 0.2: 3.1e-3).
    for (dt, frames, bound) in [(0.005, 80, 0.01), (0.01, 40, 0.02)] {
        let m = run(&load_example(
            "vibrating-bar.json",
            &[
                r#"solver.mechanics={"implicit":{"form":"dynamic"}}"#,
                &format!("solver.dt={dt}"),
                &format!("output.frames={frames}"),
            ],
        ));
        assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
        let error = m.error.unwrap();
        println!("dt {dt}: error {error:.3e}, steps {}", m.steps);
        assert!(error < bound, "dt {dt}: error {error} >= {bound}");
    }
}

#[test]
fn a_step_that_does_not_converge_is_cut_then_stops_with_a_diagnostic() {
    // One Newton iteration is not enough for the strip's geometric nonlinearity, and
    // halving the step does not change that (the whole free strain is there at t = 0).
    let m = run(&load_example(
        "bimaterial-strip.json",
        &[r#"solver.mechanics={"implicit":{"max_newton_iterations":1,"max_cuts":2}}"#],
    ));
    assert_eq!(m.outcome, Some(Outcome::Stopped));
    let d = m.diagnostic.expect("a diagnostic");
    assert_eq!(d.field, "implicit");
    assert_eq!(d.step, 1);
    for needle in ["after 2 cuts", "Newton iteration", "residual", "node at"] {
        assert!(
            d.message.contains(needle),
            "{needle:?} not in {}",
            d.message
        );
    }
    assert_eq!(m.physics.get("implicit.cuts"), Some(&3.0));
}

#[test]
fn a_body_nothing_holds_stops_with_a_clear_diagnostic_not_a_hang() {
    let m = run(&load_example(
        "bimaterial-strip.json",
        &["domain.walls=[]", "solver.gravity=[0, -9.81]"],
    ));
    assert_eq!(m.outcome, Some(Outcome::Stopped));
    let d = m.diagnostic.expect("a diagnostic");
    assert!(
        d.message.contains("nothing holds the body"),
        "{}",
        d.message
    );
}

#[test]
fn implicit_settings_are_checked_with_their_paths() {
    let issues = invalid_example(
        "bimaterial-strip.json",
        &[
            r#"solver.mechanics={"implicit":{"form":"dynamic","beta":0.1,"gamma":0.5,"force_tolerance":2,"max_newton_iterations":0}}"#,
        ],
    );
    let text = issues.join("\n");
    for path in [
        "solver.mechanics.implicit.beta",
        "solver.mechanics.implicit.force_tolerance",
        "solver.mechanics.implicit.max_newton_iterations",
    ] {
        assert!(text.contains(path), "{path} not in {text}");
    }
    let issues = invalid_example(
        "bimaterial-strip-3d.json",
        &["solver.free_strain_2d=plane_strain"],
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("solver.free_strain_2d")),
        "{issues:?}"
    );
    let issues = invalid_example(
        "bimaterial-strip.json",
        &[r#"solver.mechanics={"implicit":{"factor_precision":"half"}}"#],
    );
    assert!(
        issues.iter().any(|i| i.contains("solver.mechanics")),
        "{issues:?}"
    );
    let issues = invalid_example(
        "bimaterial-strip.json",
        &[r#"solver.mechanics={"implicit":{"form":"quasi"}}"#],
    );
    assert!(
        issues.iter().any(|i| i.contains("solver.mechanics")),
        "{issues:?}"
    );
}

#[test]
fn static_cantilever_reaches_the_heavy_elastica() {
    // Gravity ramped over 30 static load steps to w L³/(E′I) = 2.9: measured 1.2% from the
    // elastica with 4 cells through the thickness (0.34% with 8). The same beam settled by
    // damped explicit dynamics (examples/cantilever.json) ends 6.1% off.
    let m = run(&load_example("cantilever-static.json", &[]));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let error = m.error.expect("the cantilever has a reference");
    println!(
        "tip error {error:.3e}; metrics {:?}",
        m.physics.get("implicit.newton_iterations")
    );
    assert!(error < 0.025, "tip error {error}");
}

/// Keeps the stress, volume and material of the last frame (output order).
#[derive(Default)]
struct LastFrame {
    columns: [usize; 3],
    values: Vec<Vec<f64>>,
}

impl OutputSink for LastFrame {
    fn begin(&mut self, info: &RunInfo<'_>) -> Result<(), OutputError> {
        for (slot, name) in self
            .columns
            .iter_mut()
            .zip(["stress", "volume", "material"])
        {
            *slot = info
                .fields
                .iter()
                .position(|f| f.name == name)
                .ok_or_else(|| OutputError(format!("the scene must write {name}")))?;
        }
        Ok(())
    }
    fn write_frame(&mut self, frame: &Frame<'_>) -> Result<(), OutputError> {
        self.values = frame.values.to_vec();
        Ok(())
    }
    fn finish(&mut self, _: &Metrics) -> Result<(), OutputError> {
        Ok(())
    }
}

#[test]
fn underfill_cure_runs_implicit_to_self_equilibrated_residual_stress() {
    // The example's oven cycle: 100 static steps of 30 s through the liquid, gelation and
    // cool-down. A free body's residual stress integrates to zero: ∫σxx dV = ∫ x t_x dA
    // and ∫σyy dV = ∫ y t_y dA vanish here (the symmetry plane is x = 0, the slip wall
    // y = 0). Measured: 1e-8 and 2e-5 of ∫|σ| dV (the damped explicit relaxation at its
    // tolerance 1e-4: about 0.15 and 0.04, it is not at equilibrium). The layer's mean σxx
    // (generalized plane strain, the cure predicted and corrected around conduction) is
    // 52.89 MPa, 0.8% above the damped explicit relaxation's 52.46 MPa at tolerance 1e-5
    // (`--set 'solver.mechanics={"quasi_static":{"max_iterations":100000,
    // "tolerance":0.00001}}'`, 18,993 iterations, 111 s). At its default 1e-4 the
    // relaxation stops at 54.86 MPa: with the section's contraction along z it has not
    // converged there. Before the cure's corrector: 54.45 implicit, 56.62 relaxed at 1e-4;
    // in plane strain 54.8 against 55.2 (with the in-plane free strain 41.6 and 41.8).
    let scene = load_example(
        "underfill-cure.json",
        &[r#"output.fields=["stress","volume","material"]"#],
    );
    let mut last = LastFrame::default();
    let m = run_scene(&scene, &mut last, &mut |_: &Progress| Control::Continue).expect("run");
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let [s, v, mat] = last.columns.map(|c| &last.values[c]);
    let n = v.len();
    let (mut net, mut total) = ([0.0f64; 2], [0.0f64; 2]);
    let (mut layer, mut layer_volume) = (0.0, 0.0);
    for p in 0..n {
        for (k, comp) in [0usize, 3].into_iter().enumerate() {
            net[k] += v[p] * s[4 * p + comp];
            total[k] += v[p] * s[4 * p + comp].abs();
        }
        // Materials in scene order: silicon, substrate, underfill.
        if mat[p] == 2.0 {
            layer += v[p] * s[4 * p];
            layer_volume += v[p];
        }
    }
    let balance = [net[0] / total[0], net[1] / total[1]];
    let mean = layer / layer_volume;
    println!(
        "∫σ dV / ∫|σ| dV: xx {:.3e}, yy {:.3e}; layer σxx {mean:.4e} Pa",
        balance[0], balance[1]
    );
    assert!(
        balance[0].abs() < 1e-2 && balance[1].abs() < 1e-2,
        "{balance:?}"
    );
    assert!((mean - 52.46e6).abs() < 0.02 * 52.46e6, "layer σxx {mean}");
}

#[test]
fn generalized_plane_strain_costs_newton_no_more_than_plane_strain() {
    // Each residual of the generalized plane strain solves ε₀ anew, so Newton's tangent
    // needs ε₀'s response (the rank-one term of `implicit/out_of_plane.rs`); without it
    // Newton converges linearly. Measured on the cure example: 174 Newton iterations (at
    // most 2 a step) against 168 (2) in plane strain; without the term 634 (8).
    let newton = |mode: &str| {
        let setting = format!("solver.free_strain_2d={mode}");
        let m = run(&load_example("underfill-cure.json", &[setting.as_str()]));
        assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
        let k = |name: &str| m.physics[&format!("implicit.{name}")];
        (k("newton_iterations"), k("max_newton_per_step"))
    };
    let (plane, plane_most) = newton("plane_strain");
    let (generalized, generalized_most) = newton("generalized_plane_strain");
    println!(
        "Newton: plane strain {plane} (at most {plane_most}), generalized {generalized} (at most {generalized_most})"
    );
    assert!(
        generalized <= 1.15 * plane && generalized_most <= plane_most + 1.0,
        "generalized plane strain {generalized} ({generalized_most} a step) against {plane} ({plane_most})"
    );
}

#[test]
fn plate_with_a_hole_carries_kirschs_stress_field() {
    // Quarter plate, 20 mm wide with a 2 mm hole, one static step, 4 cells per hole
    // radius: measured 3.3% relative L2 over the near field (2.7% at 8 cells, 3.1% at 16:
    // the staircase hole, not the solver, sets that floor; see the README).
    let m = run(&load_example(
        "kirsch-plate.json",
        &["domain.cell_size=0.00025"],
    ));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let error = m.error.expect("the plate has a reference");
    println!(
        "near-field error {error:.3e}, peak {:?} against Kirsch {:?} at the same particle",
        m.measured_value, m.reference_value
    );
    assert!(error < 0.05, "near-field error {error}");
}

/// Mean σ_yy error and largest particle error of the Johnson–Cook block in uniaxial
/// strain below, with `solver.anti_locking` set to `anti_locking`.
fn uniaxial_strain_errors(anti_locking: &str) -> (f64, f64) {
    // A Johnson–Cook block (rate-independent: C = 0) compressed in plane strain between
    // slip walls by a stick grip moving down: uniaxial strain, 10 static steps to 4%
    // shortening, about 10× the yield strain. Closed form at each particle's own stretch
    // λ = F_yy (monotonic uniaxial strain is path-independent): plastic strain
    // εₚ = (2/3)|ln λ| − q/(3μ) with q = σ_y(εₚ), and σ_yy = (−(2/3) q + K ln λ)/λ.
    let (e, nu) = (200e9, 0.29);
    let (y0, b, n) = (792e6, 510e6, 0.26);
    let scene = serde_json::json!({
        "name": "jc-uniaxial-strain",
        "dimension": 2,
        "domain": {"min": [0.0, 0.0], "max": [0.01, 0.014], "cell_size": 0.001,
            "walls": [{"sides": ["x-", "x+", "y-"], "condition": "slip"}]},
        "solver": {"end_time": 1e-3, "dt": 1e-4, "kernel": "bspline2", "transfer": "apic",
            "anti_locking": anti_locking, "mechanics": {"implicit": {"form": "static"}}},
        "materials": {"steel": {"type": "johnson_cook", "density": 7830.0,
            "youngs_modulus": e, "poisson_ratio": nu, "specific_heat": 477.0,
            "taylor_quinney": 0.0,
            "flow_stress": {"yield_stress": y0, "hardening_modulus": b, "hardening_exponent": n,
                "strain_rate_sensitivity": 0.0, "thermal_softening_exponent": 1.03,
                "reference_strain_rate": 1.0, "room_temperature": 293.0, "melt_temperature": 1793.0}}},
        "obstacles": [{"shape": {"box": {"min": [-0.01, 0.008], "max": [0.02, 0.02]}},
            "condition": "stick", "velocity": [0.0, -0.4]}],
        "bodies": [{"name": "block", "material": "steel",
            "shape": {"box": {"min": [0.0, 0.0], "max": [0.01, 0.01]}}, "particles_per_cell": 2}],
        "output": {"frames": 1, "fields": ["x", "F", "stress"]}
    });
    let dir = tempfile::tempdir().unwrap();
    let scene = load(&write_scene(dir.path(), "jc.json", &scene), &[]);
    let (m, frames) = run_fields(&scene, &["x", "F", "stress"]);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let mu = e / (2.0 * (1.0 + nu));
    let bulk = e / (3.0 * (1.0 - 2.0 * nu));
    let flow = |strain: f64| y0 + b * strain.max(0.0).powf(n);
    let last = frames.times.len() - 1;
    let (x, f, stress) = (
        &frames.values[0][last],
        &frames.values[1][last],
        &frames.values[2][last],
    );
    let (mut scatter, mut checked, mut shortest) = (0.0f64, 0, 1.0f64);
    let (mut sum, mut sum_expected) = (0.0, 0.0);
    for p in 0..x.len() / 2 {
        // The free part, below the grip and away from the bottom wall's layer.
        if !(0.001..0.007).contains(&x[2 * p + 1]) {
            continue;
        }
        // J = λ in uniaxial strain (F_xx = 1); with F-bar F̄ is J̄/J-scaled in the plane,
        // so J̄ = det F̄ is the stretch its stress answers to.
        let stretch = f[4 * p] * f[4 * p + 3] - f[4 * p + 1] * f[4 * p + 2];
        shortest = shortest.min(stretch);
        let strain = stretch.ln().abs();
        let (mut lo, mut hi) = (0.0, 2.0 / 3.0 * strain);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if 2.0 / 3.0 * strain - flow(mid) / (3.0 * mu) - mid > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let q = flow(lo).min(2.0 * mu * strain);
        let expected = (-2.0 / 3.0 * q + bulk * stretch.ln()) / stretch;
        scatter = scatter.max((stress[4 * p + 3] - expected).abs() / expected.abs());
        sum += stress[4 * p + 3];
        sum_expected += expected;
        checked += 1;
    }
    let mean = sum / sum_expected - 1.0;
    let (mut lo_s, mut hi_s, mut lo_j, mut hi_j) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in 0..x.len() / 2 {
        if !(0.001..0.007).contains(&x[2 * p + 1]) {
            continue;
        }
        let s = stress[4 * p + 3];
        let j = f[4 * p] * f[4 * p + 3] - f[4 * p + 1] * f[4 * p + 2];
        lo_s = lo_s.min(s);
        hi_s = hi_s.max(s);
        lo_j = lo_j.min(j);
        hi_j = hi_j.max(j);
    }
    println!(
        "spread: σ_yy {lo_s:.4e} .. {hi_s:.4e}, J {lo_j:.5} .. {hi_j:.5}, mean σ_yy {:.4e}",
        sum / checked as f64
    );
    println!(
        "anti_locking {anti_locking}: {checked} particles, shortest stretch {shortest:.4}, \
         mean σ_yy error {mean:.2e}, largest particle error {scatter:.2e}"
    );
    assert!(checked > 50);
    assert!(
        shortest < 0.97,
        "the block must be compressed well past yield: {shortest}"
    );
    (mean, scatter)
}

#[test]
fn implicit_plasticity_follows_the_uniaxial_strain_closed_form() {
    // Each particle's σ_yy against the closed form at its own J (measured: mean −0.07%,
    // largest particle 0.64%). The particles' J is not uniform (0.940 to 0.962 over the
    // free part, σ_yy −7.1 to −11.2 GPa): an earlier note blamed volumetric locking, but
    // F-bar leaves the same spread and so does an elastic block (ν = 0.29, neo-Hookean),
    // so the cause is elsewhere (the README's implicit section). With F-bar the in-plane
    // scaling of F̄ makes F̄_xx ≠ 1, so the uniaxial form holds per particle only to
    // measured 6.5% (mean −0.41%).
    let (mean, scatter) = uniaxial_strain_errors("none");
    assert!(
        mean.abs() < 1e-2,
        "mean σ_yy off the closed form by {mean:.2e}"
    );
    assert!(scatter < 2e-2, "particle error {scatter:.2e}");
    let (mean, scatter) = uniaxial_strain_errors("fbar");
    assert!(
        mean.abs() < 1e-2,
        "F-bar: mean σ_yy off the closed form by {mean:.2e}"
    );
    assert!(scatter < 0.1, "F-bar: particle error {scatter:.2e}");
}
