//! `mpm check-stability --only peer` end to end: the four peer failure cases (issue 25) run
//! through the binary, each passing its own physics check, whose figure is the note.

use crate::common;

use common::*;
use serde_json::Value;

#[test]
fn the_peer_cases_pass_their_physics_checks() {
    let dir = tempfile::tempdir().unwrap();
    let o = mpm(
        &["check-stability", "--only", "peer", "--json", "peer.json"],
        dir.path(),
    );
    let t = text(&o);
    assert_eq!(o.status.code(), Some(0), "{t}");
    assert!(t.contains("4 passed, 0 failed"), "{t}");
    let results: Vec<Value> =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("peer.json")).unwrap())
            .unwrap();
    let names: Vec<&str> = results
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "peer-tension-separation",
            "peer-cell-crossing-linear",
            "peer-near-zero-mass",
            "peer-resting-creep"
        ]
    );
    for r in &results {
        assert_eq!(r["pass"], true, "{r}");
        assert_eq!(r["outcome"], "finished", "{r}");
        // The note is the check's measured figure against its bound.
        assert!(r["note"].as_str().unwrap().contains("bound"), "{r}");
    }
}

#[test]
fn the_tension_check_fails_when_the_bar_breaks() {
    use mpm_cli::stability::{Case, Expected, run_case};
    use mpm_cli::stability_peer::{connected, tension};
    // The suite's bar with 2 x 2 particles per cell instead of 3 x 3: stretched to twice its
    // length its particles are a cell apart and lose their grid connection.
    let case = Case {
        name: "tension-2x2",
        what: "",
        scene: tension("bspline2", 1.0, 2),
        expected: Expected::Finished,
        check: Some(connected),
    };
    let r = run_case(&case, &mpm_cli::default_registry());
    assert_eq!(r.outcome, "finished", "{r:?}");
    assert!(!r.pass && r.note.contains("the bar broke"), "{r:?}");
}
