//! The die/underfill/substrate stack of the underfill examples, cooled 423 → 298 K as a
//! free layered strip (examples/layered-stack.json), against laminated-beam theory
//! (`layered_strip` reference): the curvature, and each layer's mean stress along the
//! strip and across the plane (σzz), at two resolutions; in plane strain and in
//! generalized plane strain.

use crate::common;

use common::*;
use mpm_core::output::Outcome;

#[test]
fn the_cooled_stack_bends_and_stresses_as_laminated_beam_theory_says() {
    let mut last: Option<Vec<f64>> = None;
    // (cell, curvature bound, layer bounds bottom-up). Measured at 25 / 12.5 µm: curvature
    // 0.30% / 0.18%; layer means substrate −1.4% / −0.3%, underfill +13.2% / +7.0%, die
    // +5.7% / +3.0% (6.25 µm: 0.15%; +0.2%, +3.7%, +1.6%: first order in the cell, the
    // interfaces' shared nodes smear the strain over a cell). Bounds about 1.5 times those.
    for (dx, curvature_bound, layer_bounds) in [
        ("2.5e-5", 0.005, [0.03, 0.2, 0.09]),
        ("1.25e-5", 0.003, [0.01, 0.11, 0.05]),
    ] {
        let m = run(&load_example(
            "layered-stack.json",
            &[&format!("domain.cell_size={dx}")],
        ));
        assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
        let error = m.error.expect("curvature error");
        let layers: Vec<f64> = (0..3)
            .map(|k| {
                let (measured, reference) = comparison(&m, &format!("layer_{k}_mean_stress"));
                measured / reference - 1.0
            })
            .collect();
        println!(
            "cell {dx} m: curvature error {error:.2e}; layer mean stress off by {:+.2}%, {:+.2}%, {:+.2}% (substrate, underfill, die)",
            layers[0] * 100.0,
            layers[1] * 100.0,
            layers[2] * 100.0
        );
        assert!(error < curvature_bound, "curvature error {error}");
        for k in 0..3 {
            assert!(
                layers[k].abs() < layer_bounds[k],
                "layer {k}: {}",
                layers[k]
            );
        }
        if let Some(coarse) = &last {
            for k in 1..3 {
                assert!(
                    layers[k].abs() < 0.7 * coarse[k].abs(),
                    "layer {k} does not converge: {} → {}",
                    coarse[k],
                    layers[k]
                );
            }
        }
        last = Some(layers);
        // σzz = ν σxx − E α ΔT (εzz = 0). Measured at 25 / 12.5 µm: substrate +0.01% /
        // +0.10%, underfill +10.8% / +5.7%, die −2.2% / −1.1%.
        let across = layer_errors(&m, "stress_zz");
        println!("  σzz off by {across:+.4?}");
        for (k, bound) in [0.005, 1.5 * layer_bounds[1], 1.5 * layer_bounds[2] / 2.0]
            .into_iter()
            .enumerate()
        {
            assert!(across[k].abs() < bound, "layer {k} σzz: {}", across[k]);
        }
    }
}

/// Each layer's relative error in `layer_k_mean_{name}`.
fn layer_errors(m: &mpm_core::output::Metrics, name: &str) -> Vec<f64> {
    (0..3)
        .map(|k| {
            let (measured, reference) = comparison(m, &format!("layer_{k}_mean_{name}"));
            measured / reference - 1.0
        })
        .collect()
}

#[test]
fn the_cooled_stack_as_a_section_contracts_along_its_length_too() {
    // Generalized plane strain: one ε_zz for the three layers with no net force along z.
    // Measured at 25 µm: curvature 0.29%; σxx −1.3%, +13.1%, +5.5%; σzz −0.10%, +12.2%,
    // +2.2% (substrate, underfill, die). The die's σzz turns compressive (−42 MPa; +38 MPa
    // in plane strain): the stack contracts past what the die alone would.
    let m = run(&load_example(
        "layered-stack.json",
        &[
            "solver.free_strain_2d=generalized_plane_strain",
            "reference.generalized_plane_strain=true",
        ],
    ));
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let error = m.error.expect("curvature error");
    let (along, across) = (layer_errors(&m, "stress"), layer_errors(&m, "stress_zz"));
    println!("curvature error {error:.2e}; σxx off by {along:+.4?}; σzz off by {across:+.4?}");
    assert!(error < 0.005, "curvature error {error}");
    for (k, (a, z)) in along.iter().zip(&across).enumerate() {
        let bound = [0.03, 0.2, 0.09][k];
        assert!(
            a.abs() < bound && z.abs() < bound,
            "layer {k}: σxx {a}, σzz {z}"
        );
    }
    let (die_zz, _) = comparison(&m, "layer_2_mean_stress_zz");
    assert!(die_zz < 0.0, "the die's σzz {die_zz}");
    // The run reports the section's strain along z and its solve.
    let report = |k: &str| m.physics[&format!("generalized_plane_strain.{k}")];
    println!(
        "|ε_zz| {:.3e}, at most {} evaluations a solve",
        report("largest_strain"),
        report("most_evaluations")
    );
    assert!(
        report("largest_strain") > 1e-4,
        "the stack contracts along z"
    );
    assert!(report("most_evaluations") >= 2.0);
    assert_eq!(report("unbalanced"), 0.0);
}
