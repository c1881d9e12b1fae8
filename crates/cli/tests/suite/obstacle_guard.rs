//! Liquid particles are kept out of obstacles (`solver/incompressible/obstacle_guard.rs`).

use crate::common;

use common::{load_example, run_fields};
use mpm_core::output::Outcome;

#[test]
fn a_dam_break_over_a_round_obstacle_leaves_no_liquid_inside_it() {
    // examples/dam-break.json with a slip half-disc of radius 30 mm on the floor 150 mm
    // from the wall, in the surge's path (4.2 cells across; 2 × 2 particles per cell).
    // Before the guard (stop 88) up to 8 particles lay inside the disc in one frame, the
    // deepest 1.56 mm (0.22 of a cell) in; with the guard none lie deeper than 1e-17 m and
    // at most 5 are put back in a step. Bound: none deeper than 1 nm in any frame.
    const CENTRE: [f64; 2] = [0.15, 0.0];
    const RADIUS: f64 = 0.03;
    let scene = load_example(
        "dam-break.json",
        &[
            r#"obstacles=[{"shape":{"sphere":{"center":[0.15,0.0],"radius":0.03}},"condition":"slip"}]"#,
        ],
    );
    let (m, frames) = run_fields(&scene, &["x"]);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    for (frame, x) in frames.values[0].iter().enumerate() {
        let inside = x
            .chunks(2)
            .filter(|p| RADIUS - (p[0] - CENTRE[0]).hypot(p[1] - CENTRE[1]) > 1e-9)
            .count();
        assert_eq!(
            inside, 0,
            "{inside} particles inside the disc at frame {frame}"
        );
    }
    let put_back = m.physics["incompressible.put_back"];
    eprintln!(
        "put back at most {put_back} in a step, {} frames",
        frames.values[0].len()
    );
    assert!(
        put_back > 0.0,
        "the guard put back {put_back} particles: the surge never reached the disc"
    );
}
