//! Void markers: the voids of a table in the store's metrics, read for drawing as red
//! circles (of the void's area in 2D; in 3D of the sphere of its volume, at its centroid in
//! the picture's plane).

use serde_json::Value;

/// One void of a metrics table.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Void {
    /// Centre along the picture's first axis, m.
    pub x: f64,
    /// Centre along the picture's second axis, m.
    pub y: f64,
    /// Radius of the circle of the void's area (2D) or of the sphere of its volume (3D), m.
    pub radius: f64,
    /// The row's `id`, if the table has that column.
    pub id: Option<String>,
}

/// The voids of a table, and how many rows were left out.
#[derive(Debug)]
pub(crate) struct VoidTable {
    /// Rows with a finite centre and a non-negative size.
    pub voids: Vec<Void>,
    /// Rows without.
    pub skipped: usize,
}

/// Reads table `table` of the store's `metrics` attribute:
/// `tables: { TABLE: { columns: [...], rows: [[...], ...] } }` with the centre's columns
/// named by `axes` (`x`, `y` for a 2D store), `area` (2D) or `volume` (3D: `dim` 3), and
/// optionally `id`. Rows may also be objects keyed by column. A table with `closed_time`
/// and `filled_time` columns gives only the voids open at `time` (closed by then, not yet
/// filled). The error is a message for a warning.
pub(crate) fn parse_voids(
    metrics: Option<&Value>,
    table: &str,
    axes: [&str; 2],
    dim: usize,
    time: f64,
) -> Result<VoidTable, String> {
    let tables = metrics
        .and_then(|m| m.get("tables"))
        .and_then(Value::as_object)
        .ok_or_else(|| format!("no table `{table}`: the store's metrics carry no tables"))?;
    let t = tables.get(table).ok_or_else(|| {
        let names: Vec<&str> = tables.keys().map(String::as_str).collect();
        format!(
            "no table `{table}` in the store's metrics (tables: {})",
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        )
    })?;
    let columns: Vec<&str> = t
        .get("columns")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("table `{table}` has no `columns` list"))?
        .iter()
        .map(|c| c.as_str().unwrap_or(""))
        .collect();
    let column = |name: &str| columns.iter().position(|c| *c == name);
    let size = if dim == 3 { "volume" } else { "area" };
    let (Some(ix), Some(iy), Some(ia)) = (column(axes[0]), column(axes[1]), column(size)) else {
        return Err(format!(
            "table `{table}` needs columns {}, {} and {size}; it has {}",
            axes[0],
            axes[1],
            columns.join(", ")
        ));
    };
    let iid = column("id");
    let (iclosed, ifilled) = (column("closed_time"), column("filled_time"));
    // Times are written with the step's rounding: a void closed in the frame's own step
    // counts as open at that frame.
    let slack = 1e-9 * time.abs().max(1e-30);
    let rows = t
        .get("rows")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("table `{table}` has no `rows` list"))?;
    let mut out = VoidTable {
        voids: Vec::new(),
        skipped: 0,
    };
    for row in rows {
        let cell = |i: usize| -> Option<&Value> {
            match row {
                Value::Array(cells) => cells.get(i),
                Value::Object(map) => map.get(columns[i]),
                _ => None,
            }
        };
        let number = |i: usize| cell(i).and_then(Value::as_f64).filter(|v| v.is_finite());
        let closed_later = iclosed.and_then(number).is_some_and(|c| c > time + slack);
        let filled_before = ifilled.and_then(number).is_some_and(|f| f <= time + slack);
        if closed_later || filled_before {
            continue;
        }
        match (number(ix), number(iy), number(ia)) {
            (Some(x), Some(y), Some(size)) if size >= 0.0 => {
                let radius = if dim == 3 {
                    (0.75 * size / std::f64::consts::PI).cbrt()
                } else {
                    (size / std::f64::consts::PI).sqrt()
                };
                let id = iid.and_then(cell).and_then(|v| match v {
                    Value::Null => None,
                    Value::String(s) => Some(s.clone()),
                    // Tables of numbers carry ids as floats: 3.0 is "3".
                    Value::Number(n) => Some(match n.as_f64() {
                        Some(f) if f.fract() == 0.0 && f.abs() < 1e15 => format!("{}", f as i64),
                        _ => n.to_string(),
                    }),
                    other => Some(other.to_string()),
                });
                out.voids.push(Void { x, y, radius, id });
            }
            _ => out.skipped += 1,
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    const XY: [&str; 2] = ["x", "y"];
    fn r(area: f64) -> f64 {
        (area / std::f64::consts::PI).sqrt()
    }

    #[test]
    fn void_tables_are_read_from_the_metrics() {
        let metrics = json!({
            "outcome": "finished",
            "tables": {
                "voids": {
                    "columns": ["id", "x", "y", "area", "frame"],
                    "rows": [
                        [1, 3e-4, 5e-5, 7.0e-10, 4],
                        ["B", 5.5e-4, 6e-5, 2.5e-10, 4],
                        [7.0, 2e-4, 2e-5, 1e-10, 4],
                        [null, 7.5e-4, 4.5e-5, 0.0, 4],
                        [4, "far", 4.5e-5, 1e-10, 4],
                        [5, 1e-4, 1e-5, -1.0, 4],
                        [6, 1e-4]
                    ]
                },
                "fronts": { "columns": ["t", "x"], "rows": [[0.0, 0.0]] }
            }
        });
        let t = parse_voids(Some(&metrics), "voids", XY, 2, 0.0).unwrap();
        assert_eq!(t.skipped, 3);
        assert_eq!(
            t.voids,
            vec![
                Void {
                    x: 3e-4,
                    y: 5e-5,
                    radius: r(7.0e-10),
                    id: Some("1".into())
                },
                Void {
                    x: 5.5e-4,
                    y: 6e-5,
                    radius: r(2.5e-10),
                    id: Some("B".into())
                },
                Void {
                    x: 2e-4,
                    y: 2e-5,
                    radius: r(1e-10),
                    id: Some("7".into())
                },
                Void {
                    x: 7.5e-4,
                    y: 4.5e-5,
                    radius: r(0.0),
                    id: None
                },
            ]
        );

        // Rows as objects; no id column.
        let metrics = json!({ "tables": { "v": {
            "columns": ["x", "y", "area"],
            "rows": [{ "x": 1.0, "y": 2.0, "area": 3.0 }]
        } } });
        let t = parse_voids(Some(&metrics), "v", XY, 2, 0.0).unwrap();
        assert_eq!(
            t.voids,
            vec![Void {
                x: 1.0,
                y: 2.0,
                radius: r(3.0),
                id: None
            }]
        );

        // Missing tables and columns are messages naming what there is.
        let e = parse_voids(Some(&metrics), "voids", XY, 2, 0.0).unwrap_err();
        assert!(
            e.contains("no table `voids`") && e.contains("tables: v"),
            "{e}"
        );
        let e = parse_voids(Some(&json!({"tables": {}})), "voids", XY, 2, 0.0).unwrap_err();
        assert!(e.contains("tables: none"), "{e}");
        let e =
            parse_voids(Some(&json!({"outcome": "finished"})), "voids", XY, 2, 0.0).unwrap_err();
        assert!(e.contains("no tables"), "{e}");
        assert!(parse_voids(Some(&Value::Null), "voids", XY, 2, 0.0).is_err());
        assert!(parse_voids(None, "voids", XY, 2, 0.0).is_err());
        let fronts = json!({ "tables": { "fronts": { "columns": ["t", "x"], "rows": [] } } });
        let e = parse_voids(Some(&fronts), "fronts", XY, 2, 0.0).unwrap_err();
        assert!(
            e.contains("needs columns x, y and area") && e.contains("t, x"),
            "{e}"
        );

        // 3D: the centre in the picture's plane, the sphere of the volume.
        let metrics = json!({ "tables": { "v": {
            "columns": ["id", "x", "y", "z", "volume"],
            "rows": [[1, 1.0, 2.0, 3.0, 4.0 / 3.0 * std::f64::consts::PI * 8.0]]
        } } });
        let t = parse_voids(Some(&metrics), "v", ["x", "z"], 3, 0.0).unwrap();
        assert_eq!((t.voids[0].x, t.voids[0].y), (1.0, 3.0));
        assert!((t.voids[0].radius - 2.0).abs() < 1e-12);
        let e = parse_voids(Some(&metrics), "v", ["x", "z"], 2, 0.0).unwrap_err();
        assert!(e.contains("needs columns x, z and area"), "{e}");

        // With closing and filling times: only the voids open at the frame's time.
        let metrics = json!({ "tables": { "v": {
            "columns": ["id", "closed_time", "x", "y", "area", "filled_time"],
            "rows": [[1, 0.1, 0.0, 0.0, 1.0, 0.3], [2, 0.2, 0.0, 0.0, 1.0, null],
                     [3, 0.25, 0.0, 0.0, 1.0, 0.26]]
        } } });
        let open = |t: f64| -> Vec<String> {
            parse_voids(Some(&metrics), "v", XY, 2, t)
                .unwrap()
                .voids
                .into_iter()
                .filter_map(|v| v.id)
                .collect()
        };
        assert!(open(0.05).is_empty());
        assert_eq!(open(0.1), ["1"]);
        assert_eq!(open(0.25), ["1", "2", "3"]);
        assert_eq!(open(0.3), ["2"]);
    }
}
