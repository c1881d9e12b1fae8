//! The staged process example `examples/underfill-cure-cycles.json`: cure, cool-down and
//! thermal cycles of the underfill-cure section in one run and one store; with the
//! underfill yielding and damaging, its damage averaged over a material length.

use crate::common;

use common::{example, invalid_example, load_example, mpm, run, run_to_store, text};
use mpm_core::output::Outcome;
use mpm_io::ResultStore;

/// In-plane von Mises stress of every particle of a frame of 2×2 stresses.
fn von_mises(stress: &[f64]) -> Vec<f64> {
    stress
        .chunks_exact(4)
        .map(|s| {
            let (xx, xy, yy) = (s[0], s[1], s[3]);
            (xx * xx - xx * yy + yy * yy + 3.0 * xy * xy).sqrt()
        })
        .collect()
}

fn peak(store: &ResultStore, frame: u64) -> f64 {
    let (_, s) = store.frame("stress", frame).unwrap();
    von_mises(&s).into_iter().fold(0.0, f64::max)
}

#[test]
fn cure_cool_and_cycles_run_as_one_chain() {
    let dir = tempfile::tempdir().unwrap();
    let staged = example("underfill-cure-cycles.json");
    let out = mpm(
        &["run", staged.to_str().unwrap(), "--out", "r", "-q"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    let unstaged = example("underfill-cure.json");
    let out = mpm(
        &["run", unstaged.to_str().unwrap(), "--out", "r", "-q"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    let path = dir.path().join("r/underfill-cure-cycles.zarr");
    let whole = ResultStore::open(dir.path().join("r/underfill-cure.zarr")).unwrap();

    // The stages `cure` and `cool` are the one-stage underfill-cure run (same steps, same
    // frame times: 150 s apart), bit for bit, across the hand-over at 2100 s.
    for (stage, offset) in [("cure", 0u64), ("cool", 14)] {
        let s = ResultStore::open_stage(&path, Some(stage)).unwrap();
        for frame in 0..s.frame_count().unwrap() {
            for field in ["x", "stress", "temperature", "cure"] {
                assert_eq!(
                    s.frame(field, frame).unwrap(),
                    whole.frame(field, frame + offset).unwrap(),
                    "{stage} frame {frame}: {field}"
                );
            }
        }
    }

    // The cycles start from the cool-down's residual stress and temperature.
    let cool = ResultStore::open_stage(&path, Some("cool")).unwrap();
    let cycles = ResultStore::open_stage(&path, Some("cycles")).unwrap();
    let last_cool = cool.frame_count().unwrap() - 1;
    assert_eq!(
        cycles.frame("stress", 0).unwrap(),
        cool.frame("stress", last_cool).unwrap()
    );
    let residual = peak(&cool, last_cool);
    // Frames every 300 s; each cycle is 3600 s: the cold dwell (233 K) ends at frame
    // 12·k, the hot dwell (398 K) at 12·k − 6.
    let cold: Vec<f64> = (1..=3).map(|k| peak(&cycles, 12 * k)).collect();
    let hot: Vec<f64> = (1..=3).map(|k| peak(&cycles, 12 * k - 6)).collect();
    for k in 0..3 {
        // Colder than the end of cool-down (298 K): more mismatch stress; hotter: less.
        assert!(
            cold[k] > residual && hot[k] < residual,
            "{residual:e} {cold:?} {hot:?}"
        );
    }
    // The underfill post-cures in the hot dwells (cure 0.885 → 0.963), so the cold-dwell
    // stress ratchets up, by less each cycle as the cure saturates.
    let growth: Vec<f64> = cold.windows(2).map(|w| w[1] / w[0] - 1.0).collect();
    assert!(
        growth.iter().all(|&g| g > 0.0 && g < 0.02) && growth[1] < growth[0],
        "cold-dwell peaks {cold:?}"
    );
    let (_, before) = cycles.frame("cure", 0).unwrap();
    let (_, after) = cycles
        .frame("cure", cycles.frame_count().unwrap() - 1)
        .unwrap();
    assert!(after.iter().zip(&before).all(|(a, b)| a >= b));
}

/// The process examples' cured-underfill plasticity and damage (`solid.plasticity` of
/// `phase_mixture`, `examples/underfill-process-2d.json`): Johnson–Cook flow stress
/// softening towards 473 K, Johnson–Cook damage.
const PLASTICITY: &str = r#"materials.underfill.solid.plasticity={"flow_stress":{"yield_stress":7e7,"hardening_modulus":5e7,"hardening_exponent":0.3,"strain_rate_sensitivity":0,"thermal_softening_exponent":1,"room_temperature":298,"melt_temperature":473},"damage":{"d1":0.01,"d2":0.08,"d3":-2.0}}"#;

/// Flow stress of [`PLASTICITY`] at plastic strain `ep` and temperature `t`, Pa.
fn flow_stress(ep: f64, t: f64) -> f64 {
    let homologous = ((t - 298.0) / (473.0 - 298.0)).clamp(0.0, 1.0);
    (7e7 + 5e7 * ep.max(0.0).powf(0.3)) * (1.0 - homologous)
}

/// The cure-cycles chain with a yielding, damaging underfill: in every frame of the
/// cool-down and the cycles the solid's von Mises stress (plane strain, with the σ_zz the
/// law keeps) stays within the solid fraction's share of the flow stress at the particle's
/// plastic strain and temperature, the plastic strain and the damage only grow, damage is
/// at most εₚ/D1 (the smallest failure strain), and each stage's summary reports the
/// store's largest damage at its end.
#[test]
fn the_cured_underfill_yields_within_its_flow_stress_and_damages() {
    let dir = tempfile::tempdir().unwrap();
    let staged = example("underfill-cure-cycles.json");
    let fields = r#"stages[1].changes.output.fields=["x","stress","temperature","solid_fraction","solid_stress","plastic_strain","damage"]"#;
    let out = mpm(
        &[
            "run",
            staged.to_str().unwrap(),
            "--out",
            "r",
            "-q",
            "--json",
            "--set",
            PLASTICITY,
            "--set",
            fields,
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let metrics = report.get("metrics").unwrap_or(&report);
    let path = dir.path().join("r/underfill-cure-cycles.zarr");
    let mut yielded = 0usize;
    for (index, stage) in [(1usize, "cool"), (2, "cycles")] {
        let s = ResultStore::open_stage(&path, Some(stage)).unwrap();
        let frames = s.frame_count().unwrap();
        let mut last_strain: Option<Vec<f64>> = None;
        let mut last_damage: Option<Vec<f64>> = None;
        for frame in 0..frames {
            let (_, solid) = s.frame("solid_stress", frame).unwrap();
            let (_, phi) = s.frame("solid_fraction", frame).unwrap();
            let (_, t) = s.frame("temperature", frame).unwrap();
            let (_, ep) = s.frame("plastic_strain", frame).unwrap();
            let (_, d) = s.frame("damage", frame).unwrap();
            for p in 0..ep.len() {
                if ep[p].is_nan() {
                    continue; // not underfill
                }
                let c = &solid[9 * p..9 * p + 9];
                let (xx, xy, yy, zz) = (c[0], c[1], c[3], c[8]);
                let q = (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2))
                    + 3.0 * xy * xy)
                    .sqrt();
                let bound = phi[p].clamp(0.0, 1.0) * flow_stress(ep[p], t[p]);
                assert!(
                    q <= bound * (1.0 + 1e-6) + 1.0,
                    "{stage} frame {frame} particle {p}: von Mises {q:e} above {bound:e}"
                );
                assert!(
                    d[p] >= 0.0 && d[p] <= ep[p] / 0.01 + 1e-12,
                    "{} {}",
                    d[p],
                    ep[p]
                );
                if ep[p] > 0.0 {
                    yielded += 1;
                }
            }
            if let (Some(a), Some(b)) = (&last_strain, &last_damage) {
                for p in 0..ep.len() {
                    if !ep[p].is_nan() {
                        assert!(ep[p] >= a[p] && d[p] >= b[p], "{stage} frame {frame}");
                    }
                }
            }
            last_strain = Some(ep);
            last_damage = Some(d);
        }
        let store_peak = last_damage
            .unwrap()
            .into_iter()
            .filter(|v| !v.is_nan())
            .fold(0.0, f64::max);
        let summary = metrics["stages"][index]["damage"]["underfill"]["peak"]
            .as_f64()
            .unwrap();
        assert_eq!(summary, store_peak, "{stage}");
    }
    assert!(yielded > 0, "no underfill particle yielded");
}

/// Bad plasticity constants are refused at their JSON path before anything runs.
#[test]
fn bad_solid_plasticity_is_refused_at_its_path() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("underfill-process-2d.json");
    for (set, path) in [
        (
            "materials.underfill.solid.plasticity.flow_stress.yield_stress=-1",
            "materials.underfill.solid.plasticity.flow_stress.yield_stress",
        ),
        (
            "materials.underfill.solid.plasticity.flow_stress.melt_temperature=200",
            "materials.underfill.solid.plasticity.flow_stress.melt_temperature",
        ),
        (
            "materials.underfill.solid.plasticity.damage.d2=-0.01",
            "materials.underfill.solid.plasticity.damage",
        ),
    ] {
        let out = mpm(
            &["validate", scene.to_str().unwrap(), "--set", set],
            dir.path(),
        );
        assert!(!out.status.success(), "{set}");
        assert!(text(&out).contains(path), "{set}: {}", text(&out));
    }
}

/// Radius of the damage average in the tests of `solid.plasticity.damage.averaging_radius`
/// (`solver/state_averaging.rs`), on this example with a yielding, damaging underfill.
const RADIUS: f64 = 5e-5;

/// The underfill of the example with the process example's flow stress and damage, the
/// damage averaged over `RADIUS`.
fn plastic_underfill() -> String {
    format!(
        r#"materials.underfill.solid.plasticity={{"flow_stress":{{"yield_stress":7e7,
        "hardening_modulus":5e7,"hardening_exponent":0.3,"strain_rate_sensitivity":0,
        "thermal_softening_exponent":1,"room_temperature":298,"melt_temperature":473}},
        "damage":{{"d1":0.001,"d2":0.002,"d3":-2,"averaging_radius":{RADIUS}}},
        "failure_time":600}}"#
    )
}

#[test]
fn the_damage_is_the_average_of_the_stored_local_damage() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("r.zarr");
    let fields = r#"stages[2].changes.output.fields=["x","volume","material","damage","local_damage","plastic_strain"]"#;
    let scene = load_example(
        "underfill-cure-cycles.json",
        &[&plastic_underfill(), fields],
    );
    let m = run_to_store(&scene, &store);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let s = ResultStore::open_stage(&store, Some("cycles")).unwrap();
    let last = s.frame_count().unwrap() - 1;
    let field = |name: &str| s.frame(name, last).unwrap().1;
    let (x, volume, material) = (field("x"), field("volume"), field("material"));
    // The damage fields hold values for every particle (0 where a law keeps none).
    let (damage, local) = (field("damage"), field("local_damage"));
    // Materials in scene order: silicon, substrate, underfill.
    let mine: Vec<usize> = (0..volume.len()).filter(|&p| material[p] == 2.0).collect();
    let (mut largest, mut worst) = (0.0f64, 0.0f64);
    for &p in &mine {
        let (mut weighted, mut total) = (0.0, 0.0);
        for &q in &mine {
            let d = ((x[2 * p] - x[2 * q]).powi(2) + (x[2 * p + 1] - x[2 * q + 1]).powi(2)).sqrt();
            if d <= RADIUS {
                weighted += volume[q] * local[q];
                total += volume[q];
            }
        }
        let average = (weighted / total).min(1.0);
        // The averaged damage never falls: it is at least this step's average, and above
        // it only by what the average lost since it was larger (the particles moved).
        assert!(
            damage[p] >= average - 1e-12,
            "particle {p}: {} < {average}",
            damage[p]
        );
        worst = worst.max(damage[p] - average);
        largest = largest.max(average);
    }
    let peak = m.stages[2].damage["underfill"].peak;
    let local_peak = mine.iter().map(|&p| local[p]).fold(0.0, f64::max);
    println!(
        "underfill after the cycles: averaged damage {peak:.4} (from the store {largest:.4}, \
         largest excess {worst:.2e}), local damage {local_peak:.4}"
    );
    assert!(largest > 0.05, "too little damage to check: {largest}");
    // The local damage only grows, so the average falls only as particles move across
    // the radius or change volume (the cycles' thermal strain): by less than one
    // particle's share of the disk at the largest local damage.
    let particle = mine.iter().map(|&p| volume[p]).sum::<f64>() / mine.len() as f64;
    let share = local_peak * particle / (std::f64::consts::PI * RADIUS * RADIUS);
    assert!(
        worst <= share,
        "the average fell by {worst}, one particle's share {share}"
    );
    // (The recomputed average sums in another order: the same round-off allowance as above.)
    assert!(
        peak >= largest - 1e-12 && peak - largest <= share,
        "{peak} against {largest}"
    );
    assert!(
        local_peak > 2.0 * peak,
        "the local damage concentrates: {local_peak}"
    );
}

/// Stop 79: on the linear kernel the chain's interface stresses and its crack onset
/// converge at 2 cells across the 50 µm layer. The die, layer and substrate faces lie on
/// cell faces, so each cell holds one material and the strain may jump across an
/// interface; quadratic B-splines spread the jump over a cell (one velocity field), which
/// loads the stiff die's first cell and puts the underfill's plastic strain in a band a
/// cell or two under the die. Measured after the cycles with [`plastic_underfill`] at
/// 25 / 12.5 / 6.25 µm cells: linear, silicon averaged over 50 µm 64.7 / 65.4 / 67.3 MPa,
/// underfill 76.0 / 76.1 / 75.6, first failure 5,700 / 5,640 / 5,700 s (one 60 s step
/// apart); quadratic B-splines, silicon 127.1 / 98.2 / 76.7 MPa, no failure at 25 µm,
/// then 12,960 and 5,760 s.
#[test]
fn on_the_linear_kernel_the_interface_stress_and_the_crack_onset_converge() {
    let linear = r#"solver.kernel="linear""#;
    let runs = ["domain.cell_size=2.5e-5", "domain.cell_size=1.25e-5"].map(|cell| {
        let m = run(&load_example(
            "underfill-cure-cycles.json",
            &[&plastic_underfill(), linear, cell],
        ));
        assert_eq!(
            m.outcome,
            Some(Outcome::Finished),
            "{cell}: {:?}",
            m.diagnostic
        );
        m.stages.into_iter().find(|s| s.name == "cycles").unwrap()
    });
    for material in ["silicon", "substrate", "underfill"] {
        let [coarse, fine] = [&runs[0], &runs[1]].map(|s| s.averaged_von_mises[material]);
        println!(
            "{material}: averaged {:.1} → {:.1} MPa",
            coarse / 1e6,
            fine / 1e6
        );
        // Measured: +1.1%, −0.3%, +0.1%.
        assert!(
            (fine / coarse - 1.0).abs() < 0.03,
            "{material}: {coarse} → {fine} Pa"
        );
    }
    let onset = runs.each_ref().map(|s| {
        s.damage["underfill"]
            .onset
            .expect("no particle failed in the cycles")
    });
    println!(
        "onsets {:?}",
        onset.each_ref().map(|o| (o.time, o.position))
    );
    // Within one 60 s step, both within 20 µm under the die's face (y = 300 µm), between
    // x = 500 µm and the die's corner (x = 750 µm).
    assert!(
        (onset[0].time - onset[1].time).abs() <= 60.0 + 1e-9,
        "{} s against {} s",
        onset[0].time,
        onset[1].time
    );
    for o in &onset {
        assert!(
            (0.5e-3..0.76e-3).contains(&o.position[0]) && (2.8e-4..3.0e-4).contains(&o.position[1]),
            "onset at {:?}",
            o.position
        );
    }
}

#[test]
fn a_bad_averaging_radius_is_refused_at_its_path() {
    let path = "materials.underfill.solid.plasticity.damage.averaging_radius";
    let with =
        |value: &str| plastic_underfill().replace(&format!(":{RADIUS}}}"), &format!(":{value}}}"));
    for value in ["0", "-1e-5"] {
        let issues = invalid_example("underfill-cure-cycles.json", &[&with(value)]);
        assert!(
            issues.iter().any(|i| i.starts_with(path)),
            "{value}: {issues:?}"
        );
    }
}

/// The process example's SAC305 bump (`anand`): a bad constant is refused at its path.
#[test]
fn a_bad_solder_constant_is_refused_at_its_path() {
    for (set, path) in [
        (
            "materials.solder.rate_sensitivity=2",
            "materials.solder.rate_sensitivity",
        ),
        (
            "materials.solder.initial_resistance=0",
            "materials.solder.initial_resistance",
        ),
        (
            "materials.solder.fatigue.exponent=0.5",
            "materials.solder.fatigue.exponent",
        ),
    ] {
        let issues = invalid_example("underfill-process-2d.json", &[set]);
        assert!(
            issues.iter().any(|i| i.starts_with(path)),
            "{set}: {issues:?}"
        );
    }
}

/// Each material's peak von Mises stress of stage `b` within 0.5% of stage `a`'s (the
/// Newton tolerance, not the preconditioner, sets them).
fn assert_same_peaks(a: &mpm_core::output::StageSummary, b: &mpm_core::output::StageSummary) {
    for (material, peak) in &a.peak_von_mises {
        let other = b.peak_von_mises[material];
        assert!(
            (other / peak - 1.0).abs() < 5e-3,
            "{} {material}: {other} against {peak}",
            a.name
        );
    }
}

#[test]
fn a_single_precision_factor_lands_on_the_same_stresses() {
    // `factor_precision: single`: the preconditioner is factored in f32, the residual and
    // the answer stay f64, so only the Krylov iterations may change. Bounds: peaks within
    // 0.5% (the Newton tolerance sets them, as for the kept preconditioner) and at most a
    // tenth more Newton iterations per stage.
    let run = |precision: &str| {
        let setting = format!("solver.mechanics.implicit.factor_precision={precision}");
        common::run(&load_example("underfill-cure-cycles.json", &[&setting]))
    };
    let (double, single) = (run("double"), run("single"));
    for (a, b) in double.stages.iter().zip(&single.stages) {
        assert_eq!(
            b.physics.get("implicit.single_precision_factors"),
            Some(&1.0)
        );
        assert!(!a.physics.contains_key("implicit.single_precision_factors"));
        let newton = |s: &mpm_core::output::StageSummary| s.physics["implicit.newton_iterations"];
        println!(
            "{}: Newton {} against {}, Krylov {} against {}, fell back {:?}",
            a.name,
            newton(b),
            newton(a),
            b.physics["implicit.krylov_iterations"],
            a.physics["implicit.krylov_iterations"],
            b.physics.get("implicit.single_precision_fell_back")
        );
        assert!(newton(b) <= 1.1 * newton(a), "{}", a.name);
        assert_same_peaks(a, b);
    }
}

#[test]
fn a_kept_preconditioner_factors_less_and_lands_on_the_same_stresses() {
    // `reuse_preconditioner`: the chain's particles keep their nodes, so each stage factors
    // its preconditioner once and again only when a Krylov solve runs long. Measured: 8 /
    // 4 / 12 factorisations against 70 / 30 / 168, the same Newton iterations, peaks within
    // 0.05%. Bounds: at most a fifth of the factorisations, peaks within 0.5% (the Newton
    // tolerance, not the preconditioner, sets them).
    let run = |reuse: bool| {
        let reuse = format!("solver.mechanics.implicit.reuse_preconditioner={reuse}");
        common::run(&load_example("underfill-cure-cycles.json", &[&reuse]))
    };
    let (fresh, kept) = (run(false), run(true));
    for (a, b) in fresh.stages.iter().zip(&kept.stages) {
        let factorisations =
            |s: &mpm_core::output::StageSummary| s.physics["implicit.factorisations"];
        assert!(
            factorisations(b) <= 0.2 * factorisations(a),
            "{}: {} against {}",
            a.name,
            factorisations(b),
            factorisations(a)
        );
        assert_same_peaks(a, b);
    }
}
