//! Tables in the metrics are written as `tables/<name>` arrays and read back unchanged.

use mpm_core::output::{FieldInfo, Frame, Metrics, OutputSink, RunInfo};
use mpm_core::physics::Table;
use mpm_io::{ResultStore, ZarrSink};
use std::path::Path;

/// Writes a one-frame, two-particle run whose metrics carry `tables`; returns the sink's
/// result of `finish`.
fn write_run(path: &Path, tables: &[(&str, Table)]) -> Result<(), String> {
    let fields = [FieldInfo {
        name: "x".into(),
        shape: vec![2],
    }];
    let scene = serde_json::json!({ "name": "tables" });
    let mut sink = ZarrSink::new(path);
    sink.begin(&RunInfo {
        name: "tables",
        dimension: 2,
        particles: 2,
        fields: &fields,
        scene: &scene,
    })
    .map_err(|e| e.to_string())?;
    let diagnostics = vec![0.0; mpm_core::output::FRAME_DIAGNOSTICS.len()];
    sink.write_frame(&Frame {
        index: 0,
        time: 0.0,
        values: &[vec![0.0, 1.0, 2.0, 3.0]],
        diagnostics: &diagnostics,
    })
    .map_err(|e| e.to_string())?;
    let metrics = Metrics {
        tables: tables
            .iter()
            .map(|(n, t)| (n.to_string(), t.clone()))
            .collect(),
        ..Default::default()
    };
    sink.finish(&metrics).map_err(|e| e.to_string())
}

fn table(columns: &[&str], rows: Vec<Vec<f64>>) -> Table {
    Table {
        columns: columns.iter().map(|c| c.to_string()).collect(),
        rows,
    }
}

#[test]
fn tables_round_trip_through_the_store() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.zarr");
    let voids = table(
        &["x", "y", "volume"],
        vec![vec![0.5, -1.25, 3e-9], vec![f64::MAX, 0.0, -7.0]],
    );
    let empty = table(&["time", "front"], Vec::new());
    write_run(&path, &[("voids", voids.clone()), ("history", empty)]).unwrap();

    let store = ResultStore::open(&path).unwrap();
    let (columns, rows) = store.table("voids").unwrap().expect("voids stored");
    assert_eq!(columns, voids.columns);
    assert_eq!(rows, voids.rows);
    let (columns, rows) = store.table("history").unwrap().expect("history stored");
    assert_eq!(columns, ["time", "front"]);
    assert!(rows.is_empty());
    assert!(store.table("missing").unwrap().is_none());

    // The metrics attribute carries the tables too.
    let metrics = &store.attributes()["metrics"];
    assert_eq!(metrics["tables"]["voids"]["columns"][2], "volume");
    assert_eq!(metrics["tables"]["voids"]["rows"][0][1], -1.25);

    // The array's layout is as documented.
    let meta: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(path.join("tables/voids/zarr.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(meta["shape"], serde_json::json!([2, 3]));
    assert_eq!(
        meta["dimension_names"],
        serde_json::json!(["voids_row", "voids_column"])
    );
    assert_eq!(meta["data_type"], "float64");
    let meta: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(path.join("tables/history/zarr.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(meta["shape"], serde_json::json!([0, 2]));
}

#[test]
fn runs_without_tables_have_no_tables_group() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.zarr");
    write_run(&path, &[]).unwrap();
    assert!(!path.join("tables").exists());
    let store = ResultStore::open(&path).unwrap();
    assert!(store.table("voids").unwrap().is_none());
    assert!(
        !store.attributes()["metrics"]
            .as_object()
            .unwrap()
            .contains_key("tables")
    );
}

#[test]
fn ragged_tables_and_bad_names_are_errors_after_the_metrics_are_stored() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.zarr");
    let ragged = table(&["a", "b"], vec![vec![1.0, 2.0], vec![3.0]]);
    let e = write_run(&path, &[("ragged", ragged)]).unwrap_err();
    assert!(e.contains("row 1 has 1 numbers for 2 columns"), "{e}");
    let store = ResultStore::open(&path).unwrap();
    assert!(store.attributes()["metrics"]["tables"]["ragged"].is_object());

    let e = write_run(&path, &[("a/b", table(&["a"], Vec::new()))]).unwrap_err();
    assert!(e.contains("`a/b`"), "{e}");
}
