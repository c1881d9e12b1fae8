//! `output.stress_averaging_radius`: each stage's summary reports the largest von Mises
//! stress averaged over a material's particles within the radius of a particle
//! (`stress_measures.rs`). Checked against the same average computed here from the store,
//! and for convergence on examples/underfill-cure-cycles.json, whose corner peaks grow
//! under refinement.

use crate::common;

use common::*;
use mpm_core::output::{Metrics, Outcome};
use mpm_io::ResultStore;

const EXAMPLE: &str = "underfill-cure-cycles.json";

fn cycles(m: &Metrics) -> &mpm_core::output::StageSummary {
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    m.stages.iter().find(|s| s.name == "cycles").expect("stage")
}

#[test]
fn the_summary_is_the_average_of_the_stored_stress() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("r.zarr");
    let scene = load_example(
        EXAMPLE,
        &[r#"output.fields=["x","stress","stress_zz","volume","material"]"#],
    );
    let m = run_to_store(&scene, &store);
    let summary = cycles(&m);
    let s = ResultStore::open_stage(&store, Some("cycles")).unwrap();
    let last = s.frame_count().unwrap() - 1;
    let field = |name: &str| s.frame(name, last).unwrap().1;
    let (x, stress, zz, volume, material) = (
        field("x"),
        field("stress"),
        field("stress_zz"),
        field("volume"),
        field("material"),
    );
    let radius = 5e-5;
    // Plane strain: σzz counts.
    let vm: Vec<f64> = stress
        .chunks_exact(4)
        .zip(&zz)
        .map(|(s, &z)| {
            let (xx, yy, xy) = (s[0], s[3], s[1]);
            (0.5 * ((xx - yy).powi(2) + (yy - z).powi(2) + (z - xx).powi(2)) + 3.0 * xy * xy).sqrt()
        })
        .collect();
    // Materials in scene order: silicon, substrate, underfill.
    for (index, name) in ["silicon", "substrate", "underfill"].iter().enumerate() {
        let mine: Vec<usize> = (0..vm.len())
            .filter(|&p| material[p] == index as f64)
            .collect();
        let mut best = 0.0f64;
        for &p in &mine {
            let (mut weighted, mut total) = (0.0, 0.0);
            for &q in &mine {
                let d =
                    ((x[2 * p] - x[2 * q]).powi(2) + (x[2 * p + 1] - x[2 * q + 1]).powi(2)).sqrt();
                if d <= radius {
                    weighted += volume[q] * vm[q];
                    total += volume[q];
                }
            }
            best = best.max(weighted / total);
        }
        let reported = summary.averaged_von_mises[*name];
        let peak = summary.peak_von_mises[*name];
        println!("{name}: averaged {reported:.6e} Pa (from the store {best:.6e}), peak {peak:.4e}");
        assert!(
            (reported - best).abs() <= 1e-9 * best,
            "{name}: {reported} against {best}"
        );
        assert!(reported <= peak, "{name}: average above the peak");
    }
}

#[test]
fn the_averaged_underfill_stress_converges_where_the_peak_does_not() {
    // Measured after the third cycle, 25 → 12.5 µm cells, generalized plane strain with σzz
    // in the von Mises stress (stop 50): underfill peak 111.3 → 156.9 MPa (6.25 µm: 224.7),
    // averaged over 50 µm 83.4 → 87.8 MPa (91.4): +5.3% then +4.1%, converging slowly.
    // Before, with σzz left out of the figure, 88.7 → 87.4 (87.1) and a 3% bound; the bound
    // is now 1.5 times the measured step, and the average must move less than a quarter of
    // the peak's move.
    let coarse = run(&load_example(EXAMPLE, &[]));
    let fine = run(&load_example(EXAMPLE, &["domain.cell_size=1.25e-5"]));
    let (c, f) = (cycles(&coarse), cycles(&fine));
    let average = |s: &mpm_core::output::StageSummary| s.averaged_von_mises["underfill"];
    let peak = |s: &mpm_core::output::StageSummary| s.peak_von_mises["underfill"];
    println!(
        "underfill after the cycles: peak {:.1} → {:.1} MPa, averaged {:.1} → {:.1} MPa",
        peak(c) / 1e6,
        peak(f) / 1e6,
        average(c) / 1e6,
        average(f) / 1e6
    );
    let (average_step, peak_step) = (average(f) / average(c) - 1.0, peak(f) / peak(c) - 1.0);
    assert!(average_step.abs() < 0.08, "average moved {average_step}");
    assert!(peak_step > 0.2, "peak moved {peak_step}");
    assert!(
        average_step.abs() < 0.25 * peak_step,
        "average {average_step}, peak {peak_step}"
    );
}

#[test]
fn a_bad_radius_is_refused_at_its_path() {
    for value in ["0", "-1e-5", "1e-3"] {
        let issues = invalid_example(
            EXAMPLE,
            &[&format!("output.stress_averaging_radius={value}")],
        );
        assert!(
            issues
                .iter()
                .any(|i| i.starts_with("output.stress_averaging_radius")),
            "{value}: {issues:?}"
        );
    }
}

#[test]
fn a_bad_fatigue_layer_is_refused_at_its_paths() {
    for (value, path) in [
        (
            r#"{"thickness":0,"along":["silicon"]}"#,
            "output.fatigue_layer.thickness",
        ),
        (
            r#"{"thickness":1,"along":["silicon"]}"#,
            "output.fatigue_layer.thickness",
        ),
        (
            r#"{"thickness":1e-5,"along":[]}"#,
            "output.fatigue_layer.along",
        ),
        (
            r#"{"thickness":1e-5,"along":["silicon","pad"]}"#,
            "output.fatigue_layer.along[1]",
        ),
        (r#"{"thickness":1e-5}"#, "output.fatigue_layer"),
    ] {
        let issues = invalid_example(EXAMPLE, &[&format!("output.fatigue_layer={value}")]);
        assert!(
            issues.iter().any(|i| i.starts_with(path)),
            "{value}: {issues:?}"
        );
    }
}
