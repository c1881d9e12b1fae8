//! The die/underfill/substrate stack of the underfill examples, cooled 423 → 298 K as a
//! free layered strip (examples/layered-stack.json), against laminated-beam theory
//! (`layered_strip` reference): the curvature, and each layer's mean stress along the
//! strip, at two resolutions.

mod common;

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
    }
}
