//! Void markers: the voids of a table in the store's metrics, read for drawing as red
//! circles.

use serde_json::Value;

/// One void of a metrics table.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Void {
    /// Centre, m.
    pub x: f64,
    /// Centre, m.
    pub y: f64,
    /// Area, m².
    pub area: f64,
    /// The row's `id`, if the table has that column.
    pub id: Option<String>,
}

/// The voids of a table, and how many rows were left out.
#[derive(Debug)]
pub(crate) struct VoidTable {
    /// Rows with a finite x, y and a non-negative area.
    pub voids: Vec<Void>,
    /// Rows without.
    pub skipped: usize,
}

/// Reads table `table` of the store's `metrics` attribute:
/// `tables: { TABLE: { columns: [...], rows: [[...], ...] } }` with columns `x`, `y`, `area`
/// (and optionally `id`). Rows may also be objects keyed by column. The error is a message
/// for a warning.
pub(crate) fn parse_voids(metrics: Option<&Value>, table: &str) -> Result<VoidTable, String> {
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
    let (Some(ix), Some(iy), Some(ia)) = (column("x"), column("y"), column("area")) else {
        return Err(format!(
            "table `{table}` needs columns x, y and area; it has {}",
            columns.join(", ")
        ));
    };
    let iid = column("id");
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
        match (number(ix), number(iy), number(ia)) {
            (Some(x), Some(y), Some(area)) if area >= 0.0 => {
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
                out.voids.push(Void { x, y, area, id });
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
        let t = parse_voids(Some(&metrics), "voids").unwrap();
        assert_eq!(t.skipped, 3);
        assert_eq!(
            t.voids,
            vec![
                Void {
                    x: 3e-4,
                    y: 5e-5,
                    area: 7.0e-10,
                    id: Some("1".into())
                },
                Void {
                    x: 5.5e-4,
                    y: 6e-5,
                    area: 2.5e-10,
                    id: Some("B".into())
                },
                Void {
                    x: 2e-4,
                    y: 2e-5,
                    area: 1e-10,
                    id: Some("7".into())
                },
                Void {
                    x: 7.5e-4,
                    y: 4.5e-5,
                    area: 0.0,
                    id: None
                },
            ]
        );

        // Rows as objects; no id column.
        let metrics = json!({ "tables": { "v": {
            "columns": ["x", "y", "area"],
            "rows": [{ "x": 1.0, "y": 2.0, "area": 3.0 }]
        } } });
        let t = parse_voids(Some(&metrics), "v").unwrap();
        assert_eq!(
            t.voids,
            vec![Void {
                x: 1.0,
                y: 2.0,
                area: 3.0,
                id: None
            }]
        );

        // Missing tables and columns are messages naming what there is.
        let e = parse_voids(Some(&metrics), "voids").unwrap_err();
        assert!(
            e.contains("no table `voids`") && e.contains("tables: v"),
            "{e}"
        );
        let e = parse_voids(Some(&json!({"tables": {}})), "voids").unwrap_err();
        assert!(e.contains("tables: none"), "{e}");
        let e = parse_voids(Some(&json!({"outcome": "finished"})), "voids").unwrap_err();
        assert!(e.contains("no tables"), "{e}");
        assert!(parse_voids(Some(&Value::Null), "voids").is_err());
        assert!(parse_voids(None, "voids").is_err());
        let fronts = json!({ "tables": { "fronts": { "columns": ["t", "x"], "rows": [] } } });
        let e = parse_voids(Some(&fronts), "fronts").unwrap_err();
        assert!(
            e.contains("needs columns x, y and area") && e.contains("t, x"),
            "{e}"
        );
    }
}
