//! The sparse grid (`solver.grid: "sparse"`, the default) against the dense one: the same
//! particle states bit for bit (P2G adds the same terms in the same order and the grid update
//! treats every node alike, so only the energy sums' grouping differs), with grid memory
//! following the particles instead of the domain; the heat conduction's node arrays too.

use crate::common;

use common::*;
use mpm_core::output::Outcome;

/// Runs `example` with `overrides` on a sparse and on a dense grid; returns the grid bytes of
/// each after checking that every frame's positions and velocities agree bit for bit and the
/// energy diagnostics to round-off.
fn sparse_against_dense(example: &str, overrides: &[&str]) -> (usize, usize) {
    let mut runs = Vec::new();
    for grid in ["sparse", "dense"] {
        let mut o: Vec<&str> = overrides.to_vec();
        let storage = format!("solver.grid=\"{grid}\"");
        o.push(&storage);
        o.push("output.fields=[\"x\",\"v\"]");
        let (m, frames) = run_fields(&load_example(example, &o), &["x", "v"]);
        assert_eq!(
            m.outcome,
            Some(Outcome::Finished),
            "{example} {grid}: {:?}",
            m.diagnostic
        );
        runs.push((m, frames));
    }
    let ((sparse, fs), (dense, fd)) = (&runs[0], &runs[1]);
    assert_eq!(sparse.steps, dense.steps, "{example}");
    assert!(fs.times.len() >= 2, "{example}: frames");
    for (k, name) in ["x", "v"].iter().enumerate() {
        for (frame, (a, b)) in fs.values[k].iter().zip(&fd.values[k]).enumerate() {
            let differ = a
                .iter()
                .zip(b)
                .filter(|(x, y)| x.to_bits() != y.to_bits())
                .count();
            let worst = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            assert_eq!(
                differ, 0,
                "{example}: {name} of frame {frame} differs by up to {worst}"
            );
        }
    }
    for (a, b) in fs
        .diagnostics
        .iter()
        .flatten()
        .zip(fd.diagnostics.iter().flatten())
    {
        let scale = a.abs().max(b.abs()).max(1e-300);
        assert!(
            (a - b).abs() <= 1e-9 * scale || (a - b).abs() < 1e-12,
            "{example}: diagnostic {a} against {b}"
        );
    }
    println!(
        "{example}: {} steps, grid bytes sparse {} dense {}",
        sparse.steps, sparse.grid_bytes, dense.grid_bytes
    );
    (sparse.grid_bytes, dense.grid_bytes)
}

#[test]
fn sparse_grid_gives_the_dense_results_bit_for_bit() {
    // 3D, APIC with the MLS force, slip walls; the cube falls and lands.
    let (sparse, dense) = sparse_against_dense(
        "cube-drop.json",
        &["domain.cell_size=0.03125", "solver.end_time=0.06"],
    );
    // The cube and its fall take a fraction of the box.
    assert!(sparse * 2 < dense, "{sparse} against {dense}");
    // 2D, stick wall (the fold and mirror of ghost nodes), gravity and damping.
    sparse_against_dense("cantilever.json", &["solver.end_time=0.05"]);
    // The other update schemes and FLIP, cubic B-splines and GIMP.
    sparse_against_dense(
        "vibrating-bar.json",
        &[
            "solver.end_time=0.05",
            "solver.scheme=\"musl\"",
            "solver.transfer=\"flip\"",
        ],
    );
    sparse_against_dense(
        "vibrating-bar.json",
        &[
            "solver.end_time=0.05",
            "solver.scheme=\"usf\"",
            "solver.kernel=\"bspline3\"",
        ],
    );
    sparse_against_dense(
        "vibrating-bar.json",
        &["solver.end_time=0.05", "solver.kernel=\"gimp\""],
    );
    // 3D Johnson–Cook impact with symmetry walls (folded images), plastic heating.
    sparse_against_dense("taylor-bar.json", &["solver.end_time=5e-6"]);
    // Quasi-static relaxation.
    sparse_against_dense("cantilever-static.json", &["solver.end_time=0.05"]);
}

/// 64 particles in a 1 m box at 1/520 m cells: a dense grid of 521³ nodes (4.5 GB) the
/// scene limits refuse; the sparse grid takes a few blocks and the cube falls freely.
#[test]
fn a_few_particles_in_a_large_box_take_a_few_blocks() {
    let scene = |grid: &str| {
        serde_json::json!({
            "name": "speck", "dimension": 3,
            "domain": {"min": [0, 0, 0], "max": [1, 1, 1], "cell_size": 1.0 / 520.0,
                       "walls": [{"sides": ["y-"], "condition": "stick"}]},
            "solver": {"end_time": 0.01, "dt": 1e-4, "grid": grid, "gravity": [0, -9.81, 0]},
            "materials": {"steel": {"type": "linear_elastic", "density": 7800.0,
                "youngs_modulus": 2e5, "poisson_ratio": 0.3}},
            "bodies": [{"material": "steel", "particles_per_cell": 2,
                "shape": {"box": {"min": [0.5, 0.5, 0.5],
                                  "max": [0.5 + 2.0 / 520.0, 0.5 + 2.0 / 520.0, 0.5 + 2.0 / 520.0]}}}],
            "output": {"frames": 2, "fields": ["x"]}
        })
    };
    let dir = tempfile::tempdir().unwrap();
    let dense = write_scene(dir.path(), "dense.json", &scene("dense"));
    match mpm_cli::load_scene(&dense, &[], &mpm_cli::default_registry()) {
        Err(mpm_cli::LoadError::Invalid(e)) => {
            let text: Vec<String> = e.issues.iter().map(|i| i.to_string()).collect();
            assert!(text.iter().any(|t| t.contains("grid_nodes")), "{text:?}");
        }
        Ok(_) => panic!("a dense grid of 521³ nodes was accepted"),
        Err(mpm_cli::LoadError::Io(e)) => panic!("{e:#}"),
    }
    let sparse = write_scene(dir.path(), "sparse.json", &scene("sparse"));
    let (m, frames) = run_fields(&load(&sparse, &[]), &["x"]);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    assert_eq!(m.particles, 64);
    // A block is 512 nodes of 32 bytes; the 64 particles' stencils reach a few dozen.
    println!("grid bytes: {}", m.grid_bytes);
    assert!(m.grid_bytes < 4 << 20, "{} bytes", m.grid_bytes);
    // Free fall: after n steps of symplectic Euler the mean height has dropped by
    // g·dt²·n(n+1)/2 (the floor is far below), to round-off.
    let y = |frame: usize| {
        let x = &frames.values[0][frame];
        x.chunks(3).map(|p| p[1]).sum::<f64>() / 64.0
    };
    let last = frames.times.len() - 1;
    let n = (frames.times[last] / 1e-4).round();
    let drop = y(0) - y(last);
    let expected = 9.81 * 1e-8 * n * (n + 1.0) / 2.0;
    assert!(
        (drop - expected).abs() < 1e-9 * expected,
        "dropped {drop} m in {n} steps, free fall {expected} m"
    );
}

/// Two steel cubes of 2 cells a side, one at 400 K and one at 300 K, touching, in a cubic
/// box from `min` to `max` of cells `h`, heat conduction (implicit) and mechanics off.
fn hot_and_cold_cubes(h: f64, min: f64, max: f64) -> serde_json::Value {
    let material = |t: f64| {
        serde_json::json!({"conductivity": 50.0, "specific_heat": 500.0,
        "initial_temperature": t})
    };
    let steel = serde_json::json!({"type": "linear_elastic", "density": 7800.0,
        "youngs_modulus": 2e11, "poisson_ratio": 0.3});
    let cube = |name: &str, x0: f64| {
        serde_json::json!({"name": name, "material": name,
        "particles_per_cell": 2, "shape": {"box": {"min": [x0, 0.5, 0.5],
            "max": [x0 + 2.0 * h, 0.5 + 2.0 * h, 0.5 + 2.0 * h]}}})
    };
    serde_json::json!({
        "name": "hot-and-cold", "dimension": 3,
        "domain": {"min": [min, min, min], "max": [max, max, max], "cell_size": h},
        "solver": {"end_time": 1.0, "dt": 0.1, "mechanics": "off", "kernel": "bspline2"},
        "materials": {"hot": steel, "cold": steel},
        "physics": {"thermal": {"integrator": "implicit",
            "materials": {"hot": material(400.0), "cold": material(300.0)}}},
        "bodies": [cube("hot", 0.5), cube("cold", 0.5 + 2.0 * h)],
        "output": {"frames": 2, "fields": ["temperature"]}
    })
}

/// Heat conduction between a hot and a cold cube, 2 cells each, in a 1 m box at 1/520 m
/// cells: the conduction's node arrays cover the nodes the particles' stencils reach, not
/// the box's 521³ (11 arrays of them would be 12 GB, which the limits used to refuse). The
/// cubes exchange heat as in a box just larger than they are, and keep their heat.
#[test]
fn heat_conduction_in_a_large_box_holds_arrays_for_its_own_nodes() {
    let h = 1.0 / 520.0;
    let scene = |min: f64, max: f64| hot_and_cold_cubes(h, min, max);
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, min: f64, max: f64| {
        let path = write_scene(dir.path(), name, &scene(min, max));
        let (m, frames) = run_fields(&load(&path, &[]), &["temperature"]);
        assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
        assert_eq!(m.particles, 128);
        (m, frames.values[0].last().unwrap().clone())
    };
    let (large, t_large) = run("large.json", 0.0, 1.0);
    let (_, t_small) = run("small.json", 0.5 - 8.0 * h, 0.5 + 12.0 * h);
    // The node arrays: 11 of 8 bytes on each reached node (a few hundred), plus the rows'
    // numbering, about 0.19 bytes per grid node of the box (26 MB).
    println!("grid bytes: {}", large.grid_bytes);
    assert!(large.grid_bytes < 40 << 20, "{} bytes", large.grid_bytes);
    // The same exchange as in the small box, to round-off of the nodes' positions.
    let worst = t_large
        .iter()
        .zip(&t_small)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "temperatures differ by {worst} K");
    // Equal masses and heat capacities: the mean temperature is the heat, kept; the hot
    // cube (the first 64 particles) cooled and the cold one warmed.
    let mean = |t: &[f64]| t.iter().sum::<f64>() / t.len() as f64;
    assert!((mean(&t_large) - 350.0).abs() < 1e-9, "{}", mean(&t_large));
    let (hot, cold) = (mean(&t_large[..64]), mean(&t_large[64..]));
    assert!(hot < 395.0 && cold > 305.0, "hot {hot} K, cold {cold} K");
}

#[test]
fn physics_whose_arrays_follow_the_particles_keep_the_sparse_estimate() {
    // The budget asks the registry which physics sections keep their node arrays to the
    // particles' stencils (heat conduction declares it): the large box's 1.45e8 nodes are
    // then estimated by the blocks 128 particles can reach at most (2.1e6 nodes); a
    // section that does not declare it keeps the box.
    let registry = mpm_cli::default_registry();
    let json = hot_and_cold_cubes(1.0 / 520.0, 0.0, 1.0);
    let mut scene: mpm_core::scene::Scene =
        mpm_core::scene::deserialize_at(&json, "$").expect("scene");
    let sparse = mpm_core::scene::estimate(&scene, &registry).grid_nodes;
    let section = scene.physics.remove("thermal").unwrap();
    scene.physics.insert("not_declared".into(), section);
    let dense = mpm_core::scene::estimate(&scene, &registry).grid_nodes;
    println!("grid nodes: {sparse:.3e} with heat conduction, {dense:.3e} otherwise");
    assert!(sparse < 1e7, "{sparse}");
    assert!(dense > 1e8, "{dense}");
}
