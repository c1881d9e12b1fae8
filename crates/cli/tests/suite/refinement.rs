//! Local refinement in a run (`solver.refinement`, issue 26): the refined step on a grid
//! with levels of hierarchical B-splines. A body translating across a level boundary keeps
//! its velocity and F exactly; the vibrating bar refined over the whole body is the
//! uniform run at half the cell size, refined over half of it lies between the two, and
//! without a refined level it is the uniform run; what the refined step cannot do yet is
//! refused at its JSON path.

use crate::common;

use common::*;
use mpm_core::output::Outcome;
use mpm_io::ResultStore;

/// The bar refined over `boxes` (a JSON list of `{min, max}`) at the example's 0.05 m.
fn refined_bar(boxes: &str, sets: &[&str]) -> mpm_core::output::Metrics {
    let refinement = format!("solver.refinement={{\"levels\":[{{\"boxes\":{boxes}}}]}}");
    let mut all = vec![refinement.as_str()];
    all.extend_from_slice(sets);
    run(&load_example("vibrating-bar.json", &all))
}

#[test]
fn the_bar_refined_over_its_length_is_the_uniform_run_at_half_the_cell() {
    let uniform = run(&load_example("vibrating-bar.json", &[]));
    let fine = run(&load_example(
        "vibrating-bar.json",
        &["domain.cell_size=0.025"],
    ));
    let no_level = run(&load_example(
        "vibrating-bar.json",
        &["solver.refinement={\"levels\":[]}"],
    ));
    let whole = refined_bar("[{\"min\":[-0.1,-0.1],\"max\":[1.2,0.3]}]", &[]);
    let half = refined_bar("[{\"min\":[0.5,-0.1],\"max\":[1.2,0.3]}]", &[]);
    let error = |m: &mpm_core::output::Metrics| m.error.unwrap();
    for (name, m) in [
        ("uniform 0.05", &uniform),
        ("uniform 0.025", &fine),
        ("no level", &no_level),
        ("refined whole", &whole),
        ("refined half", &half),
    ] {
        println!(
            "{name}: error {:.4e}, particles {}, drift {:.3e}",
            error(m),
            m.particles,
            m.energy_drift
        );
        assert_eq!(m.outcome, Some(Outcome::Finished), "{name}");
    }
    // Without a refined level the basis is the base grid's B-splines and the walls fold as
    // the uniform grid's do. Measured: 3.1399e-3 both.
    assert!(
        (error(&no_level) / error(&uniform) - 1.0).abs() < 1e-6,
        "no level {} vs uniform {}",
        error(&no_level),
        error(&uniform)
    );
    // Refined everywhere the bar is: the particles split to the fine run's lattice.
    // Measured: 7.8392e-4 against 7.8483e-4, 1280 particles both.
    assert_eq!(whole.particles, fine.particles);
    assert!(
        (error(&whole) / error(&fine) - 1.0).abs() < 0.02,
        "refined {} vs fine {}",
        error(&whole),
        error(&fine)
    );
    assert!(whole.energy_drift.abs() < 2e-3, "{}", whole.energy_drift);
    // Half the bar refined (its free end, where the displacement is largest): between the
    // two. Measured: 2.5891e-3.
    assert!(
        error(&half) < error(&uniform) && error(&half) > error(&fine),
        "half {}",
        error(&half)
    );
}

#[test]
fn a_body_translating_across_a_level_boundary_keeps_its_velocity_exactly() {
    // A free elastic block moving at a uniform velocity through a region refined twice:
    // partition of unity makes the gathered velocity the block's and ∇v zero, on every
    // level and across their boundaries, so nothing may change.
    let dir = tempfile::tempdir().unwrap();
    let scene = serde_json::json!({
        "name": "translating-block",
        "dimension": 2,
        "domain": {"min": [0.0, 0.0], "max": [2.0, 1.0], "cell_size": 0.1},
        "solver": {
            "end_time": 0.5, "kernel": "bspline2", "transfer": "apic", "scheme": "usl",
            "cfl": 0.3,
            "refinement": {"levels": [
                {"boxes": [{"min": [0.8, 0.2], "max": [1.6, 0.8]}]},
                {"boxes": [{"min": [1.0, 0.4], "max": [1.3, 0.6]}]}
            ]}
        },
        "materials": {"block": {"type": "linear_elastic", "density": 1000.0,
                                "youngs_modulus": 1.0e6, "poisson_ratio": 0.3}},
        "bodies": [{"name": "block", "material": "block",
                    "shape": {"box": {"min": [0.3, 0.25], "max": [0.9, 0.75]}},
                    "particles_per_cell": 2, "velocity": {"uniform": [1.5, 0.1]}}],
        "output": {"frames": 2, "fields": ["x", "v", "F"]}
    });
    let path = write_scene(dir.path(), "block", &scene);
    let store = dir.path().join("block.zarr");
    let m = run_to_store(&load(&path, &[]), &store);
    assert_eq!(m.outcome, Some(Outcome::Finished));
    let s = ResultStore::open(&store).unwrap();
    let last = s.times().unwrap().len() as u64 - 1;
    let (_, x) = s.frame("x", last).unwrap();
    let (_, v) = s.frame("v", last).unwrap();
    let (_, f) = s.frame("F", last).unwrap();
    // The block crossed into both refined levels.
    let leading = x.chunks_exact(2).map(|p| p[0]).fold(f64::MIN, f64::max);
    println!("{} particles, leading edge at {leading} m", m.particles);
    assert!(leading > 1.3, "the block reached {leading} m");
    let velocity_error = v
        .chunks_exact(2)
        .map(|p| (p[0] - 1.5).abs().max((p[1] - 0.1).abs()))
        .fold(0.0, f64::max);
    let f_error = f
        .chunks_exact(4)
        .map(|a| {
            (a[0] - 1.0)
                .abs()
                .max(a[1].abs())
                .max(a[2].abs())
                .max((a[3] - 1.0).abs())
        })
        .fold(0.0, f64::max);
    // Round-off only, over the run's steps: measured 6.7e-13 (v) and 6.8e-13 (F).
    println!("velocity error {velocity_error:.3e}, F error {f_error:.3e}");
    assert!(velocity_error < 1e-11, "velocity error {velocity_error}");
    assert!(f_error < 1e-11, "F error {f_error}");
}

#[test]
fn what_the_refined_step_cannot_do_is_refused_at_its_path() {
    let level = |boxes: &str| format!("solver.refinement={{\"levels\":[{{\"boxes\":{boxes}}}]}}");
    let cases: Vec<(String, Vec<String>, &str)> = vec![
        (
            level("[{\"min\":[0.5],\"max\":[1.2,0.3]}]"),
            vec![],
            "solver.refinement.levels[0].boxes[0].min",
        ),
        (
            level("[{\"min\":[0.5,0.3],\"max\":[1.2,0.1]}]"),
            vec![],
            "solver.refinement.levels[0].boxes[0].max[1]",
        ),
        (level("[]"), vec![], "solver.refinement.levels[0].boxes"),
        (
            level("[{\"min\":[5,5],\"max\":[6,6]}]"),
            vec![],
            "solver.refinement.levels[0].boxes",
        ),
        (
            "solver.refinement={\"levels\":[{\"boxes\":[{\"min\":[0,0],\"max\":[1,0.2]}]},{\"boxes\":[{\"min\":[0,0],\"max\":[1,0.2]}]},{\"boxes\":[{\"min\":[0,0],\"max\":[1,0.2]}]},{\"boxes\":[{\"min\":[0,0],\"max\":[1,0.2]}]},{\"boxes\":[{\"min\":[0,0],\"max\":[1,0.2]}]},{\"boxes\":[{\"min\":[0,0],\"max\":[1,0.2]}]},{\"boxes\":[{\"min\":[0,0],\"max\":[1,0.2]}]},{\"boxes\":[{\"min\":[0,0],\"max\":[1,0.2]}]}]}".to_string(),
            vec![],
            "solver.refinement",
        ),
        (
            level("[{\"min\":[0.5,0],\"max\":[1.2,0.2]}]"),
            vec!["solver.kernel=\"linear\"".to_string()],
            "solver.kernel",
        ),
        (
            level("[{\"min\":[0.5,0],\"max\":[1.2,0.2]}]"),
            vec!["solver.transfer=\"flip\"".to_string()],
            "solver.transfer",
        ),
        (
            level("[{\"min\":[0.5,0],\"max\":[1.2,0.2]}]"),
            vec!["solver.mechanics=\"total_lagrangian\"".to_string()],
            "solver.mechanics",
        ),
    ];
    for (refinement, mut sets, path) in cases {
        sets.insert(0, refinement.clone());
        let sets: Vec<&str> = sets.iter().map(|s| s.as_str()).collect();
        let issues = invalid_example("vibrating-bar.json", &sets);
        println!("{refinement}: {issues:?}");
        assert!(
            issues.iter().any(|i| i.starts_with(path)),
            "{sets:?}: expected an issue at {path}, got {issues:?}"
        );
    }
}
