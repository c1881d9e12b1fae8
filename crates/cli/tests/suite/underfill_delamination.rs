//! Cool-down delamination of a flip-chip underfill (`examples/underfill-delamination.json`):
//! the expansion mismatch loads the cohesive interfaces, and the die–underfill interface
//! starts to debond at the die's corners (the free edge), not at its centre.

use crate::common;

use common::*;
use mpm_core::output::Outcome;

/// Die edges, m, and the die–underfill interface's height.
const DIE: [f64; 2] = [0.0005, 0.0025];
const INTERFACE: f64 = 0.000575;

#[test]
fn delamination_starts_at_the_die_corners() {
    // The example up to 52 us: 2 us past the first debonded nodes (48.6 us, measured).
    let scene = load_example(
        "underfill-delamination.json",
        &["solver.end_time=5.2e-5", "output.frames=2"],
    );
    let (m, frames) = run_fields(&scene, &["x", "interface_damage"]);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let table = &m.tables["cohesive"];
    let first = table
        .rows
        .iter()
        .find(|r| r[3] > 0.0)
        .expect("no node debonded");
    let last = table.rows.last().unwrap();
    println!(
        "first debonded nodes at {:.2} us; at {:.2} us {:.3} mm debonded ({} nodes)",
        first[0] * 1e6,
        last[0] * 1e6,
        last[1] * 1e3,
        last[3]
    );
    let k = frames.times.len() - 1;
    let (x, damage) = (&frames.values[0][k], &frames.values[1][k]);
    // The largest damage by the interface (within a cell of it) near each die edge
    // (within 0.1 mm, two cells) and around the centre (within 0.25 mm).
    let near = |p: usize| (x[2 * p + 1] - INTERFACE).abs() < 5e-5;
    let largest = |within: &dyn Fn(f64) -> bool| {
        (0..damage.len())
            .filter(|&p| near(p) && within(x[2 * p]))
            .map(|p| damage[p])
            .fold(0.0f64, f64::max)
    };
    let left = largest(&|x| (x - DIE[0]).abs() < 1e-4);
    let right = largest(&|x| (x - DIE[1]).abs() < 1e-4);
    let centre = largest(&|x| (x - 0.5 * (DIE[0] + DIE[1])).abs() < 2.5e-4);
    println!("damage at the left corner {left}, right corner {right}, centre {centre}");
    assert_eq!(left, 1.0, "left die corner not debonded");
    assert_eq!(right, 1.0, "right die corner not debonded");
    assert!(centre < 1.0, "the centre debonded too");
}
