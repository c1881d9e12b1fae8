//! `examples/underfill-process-3d.json` in short: the liquid fill among the held die,
//! substrate and bump (incompressible mechanics, `scene::held_bodies`), its hand-over to
//! the underfill, and the start of the cure.

use crate::common;

use common::{example, run_scene_json};
use mpm_io::ResultStore;
use serde_json::{Value, json};

const UM: f64 = 1e-6;

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Whether `x` (m) lies more than `depth` µm inside the die, the substrate or the bump of
/// the example.
fn inside_a_solid(x: &[f64], depth: f64) -> bool {
    let [x, y, z] = [x[0] / UM, x[1] / UM, x[2] / UM];
    let die = x < 180.0 - depth && (100.0 + depth..150.0 - depth).contains(&z);
    let substrate = x < 260.0 - depth && z < 50.0 - depth;
    let bump = (x - 100.0).powi(2) + y * y < (40.0 - depth).powi(2)
        && (50.0 + depth..100.0 - depth).contains(&z);
    die || substrate || bump
}

#[test]
fn the_liquid_fills_among_the_held_die_substrate_and_bump_then_cures_as_the_underfill() {
    // The fill's first 0.4 ms (about 1,200 steps at the capillary bound) and the cure's
    // first five minutes (ten implicit steps); the whole example's figures are in the
    // README.
    let mut scene: Value = serde_json::from_str(
        &std::fs::read_to_string(example("underfill-process-3d.json")).unwrap(),
    )
    .unwrap();
    let fill_end = 4e-4;
    scene["solver"]["end_time"] = json!(fill_end);
    scene["output"]["frames"] = json!(4);
    let stages = scene["stages"].as_array_mut().unwrap();
    stages.truncate(2);
    stages[1]["changes"]["solver"]["end_time"] = json!(fill_end + 300.0);
    stages[1]["changes"]["output"]["frames"] = json!(2);
    let dir = tempfile::tempdir().unwrap();
    let m = run_scene_json(dir.path(), "p3", &scene);
    for stage in 0..2 {
        assert_eq!(m["stages"][stage]["outcome"], "finished", "{m}");
    }
    let open = |stage: &str| {
        ResultStore::open(dir.path().join("p3/underfill-process-3d.zarr"))
            .unwrap()
            .stage(stage)
            .unwrap()
    };
    let (fill, cure) = (open("fill"), open("cure"));
    let last = fill.frame_count().unwrap() - 1;
    let x0 = fill.frame("x", 0).unwrap().1;
    let material = fill.frame("material", 0).unwrap().1;
    let n = material.len();
    // The material codes name the scene's materials in order: resin is 0 here.
    let liquid = |p: usize| material[p] == 0.0;
    assert!((0..n).filter(|&p| liquid(p)).count() == 5376);
    for frame in 0..=last {
        let x = fill.frame("x", frame).unwrap().1;
        let v = fill.frame("v", frame).unwrap().1;
        for p in (0..n).filter(|&p| !liquid(p)) {
            // Held: where it started, at rest.
            assert_eq!(
                bits(&x[3 * p..3 * p + 3]),
                bits(&x0[3 * p..3 * p + 3]),
                "{p}"
            );
            assert!(v[3 * p..3 * p + 3].iter().all(|&c| c == 0.0), "{p}");
        }
        // No liquid inside the solids: they are obstacles of their shapes, which hold the
        // liquid to within half a cell, as a wall does (its constrained nodes are on the
        // surface; a particle beside it gathers from the free nodes behind it too):
        // measured, 3 of the 5,376 particles lay within 5 µm inside the die or substrate
        // at 0.27 ms, none deeper.
        let inside = (0..n)
            .filter(|&p| liquid(p) && inside_a_solid(&x[3 * p..3 * p + 3], 5.0))
            .count();
        assert_eq!(inside, 0, "frame {frame}");
    }
    // Capillarity alone drew the bead into the gap (none of it was there at the start).
    let x = fill.frame("x", last).unwrap().1;
    let in_gap = (0..n)
        .filter(|&p| {
            let [px, _, pz] = [x[3 * p] / UM, x[3 * p + 1] / UM, x[3 * p + 2] / UM];
            liquid(p) && px < 180.0 && pz > 50.0 && pz < 100.0
        })
        .count();
    assert!(in_gap > 800, "{in_gap} liquid particles in the gap");
    // The hand-over: the liquid is the underfill where it was.
    assert_eq!(bits(&cure.frame("x", 0).unwrap().1), bits(&x));
    let peaks = m["stages"][1]["peak_von_mises"].as_object().unwrap();
    assert!(!peaks.contains_key("resin"), "{peaks:?}");
    // Heating bends the bonded stack: the die carries stress, the still-liquid underfill
    // next to none.
    let silicon = peaks["silicon"].as_f64().unwrap();
    let underfill = peaks["underfill"].as_f64().unwrap();
    assert!(silicon > 1e6, "{silicon}");
    assert!(underfill < 1e3, "{underfill}");
    // F-bar's preconditioner splits each particle's whole measured tangent (the creeping
    // solder's is anisotropic): measured 115 Krylov iterations over these ten steps, where
    // the isotropic estimate it had before took 345 (and 9,746 over the example's first ten
    // cure steps from its whole fill).
    let krylov = m["stages"][1]["physics"]["implicit.krylov_iterations"]
        .as_f64()
        .unwrap();
    assert!(krylov <= 200.0, "{krylov} Krylov iterations");
}
