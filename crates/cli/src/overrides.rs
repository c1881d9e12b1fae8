//! `--set PATH=VALUE`: change one value of a scene before validation (for quick changes and
//! parameter studies). PATH uses the same dotted form as error messages: `solver.cfl`,
//! `bodies[0].particles_per_cell`.

use anyhow::{Context, bail};
use serde_json::Value;

/// Applies `PATH=VALUE` to a scene document. VALUE is read as JSON, or as a string when it
/// is not valid JSON.
pub fn apply_override(scene: &mut Value, assignment: &str) -> anyhow::Result<()> {
    let (path, raw) = assignment
        .split_once('=')
        .with_context(|| format!("`{assignment}`: expected PATH=VALUE"))?;
    let value: Value = serde_json::from_str(raw).unwrap_or_else(|_| Value::String(raw.into()));
    let mut target = scene;
    let segments = split_path(path)?;
    let (last, parents) = segments.split_last().context("empty path")?;
    for seg in parents {
        target = match seg {
            Segment::Key(k) => {
                let obj = target
                    .as_object_mut()
                    .with_context(|| format!("`{path}`: `{k}` is not inside an object"))?;
                obj.entry(k.clone())
                    .or_insert_with(|| Value::Object(Default::default()))
            }
            Segment::Index(i) => target
                .as_array_mut()
                .and_then(|a| a.get_mut(*i))
                .with_context(|| format!("`{path}`: no element [{i}]"))?,
        };
    }
    match last {
        Segment::Key(k) => {
            let obj = target
                .as_object_mut()
                .with_context(|| format!("`{path}`: `{k}` is not inside an object"))?;
            obj.insert(k.clone(), value);
        }
        Segment::Index(i) => {
            let slot = target
                .as_array_mut()
                .and_then(|a| a.get_mut(*i))
                .with_context(|| format!("`{path}`: no element [{i}]"))?;
            *slot = value;
        }
    }
    Ok(())
}

/// The value at `path` (the `--set` form) in a scene document, if there is one.
pub fn value_at<'a>(scene: &'a Value, path: &str) -> anyhow::Result<Option<&'a Value>> {
    let mut target = scene;
    for seg in split_path(path)? {
        let next = match &seg {
            Segment::Key(k) => target.get(k),
            Segment::Index(i) => target.get(*i),
        };
        match next {
            Some(v) => target = v,
            None => return Ok(None),
        }
    }
    Ok(Some(target))
}

enum Segment {
    Key(String),
    Index(usize),
}

fn split_path(path: &str) -> anyhow::Result<Vec<Segment>> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let mut rest = part;
        let key_end = rest.find('[').unwrap_or(rest.len());
        if key_end > 0 {
            out.push(Segment::Key(rest[..key_end].to_string()));
        }
        rest = &rest[key_end..];
        while let Some(stripped) = rest.strip_prefix('[') {
            let close = stripped
                .find(']')
                .with_context(|| format!("`{path}`: missing ]"))?;
            let index: usize = stripped[..close]
                .parse()
                .with_context(|| format!("`{path}`: `{}` is not an index", &stripped[..close]))?;
            out.push(Segment::Index(index));
            rest = &stripped[close + 1..];
        }
        if !rest.is_empty() {
            bail!("`{path}`: cannot read `{rest}`");
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_nested_values() {
        let mut scene =
            serde_json::json!({"solver": {"cfl": 0.3}, "bodies": [{"particles_per_cell": 2}]});
        apply_override(&mut scene, "solver.cfl=0.5").unwrap();
        apply_override(&mut scene, "bodies[0].particles_per_cell=3").unwrap();
        apply_override(&mut scene, "solver.kernel=linear").unwrap();
        assert_eq!(scene["solver"]["cfl"], 0.5);
        assert_eq!(scene["bodies"][0]["particles_per_cell"], 3);
        assert_eq!(scene["solver"]["kernel"], "linear");
        assert!(apply_override(&mut scene, "bodies[3].x=1").is_err());
        assert!(apply_override(&mut scene, "nonsense").is_err());
    }
}
