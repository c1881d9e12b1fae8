//! Turning particles of one material into another at a stage's hand-over
//! (`stages[i].convert`): the liquid at the end of a fill becomes the curing underfill where
//! it is. The stage's scene is the scene before with the converted bodies' `material`
//! rewritten, so it is validated (mode, physics, output) as the scene its particles now
//! make; the solver's `solver/conversion.rs` moves their rows into the new material's
//! group.

use super::Issue;
use std::collections::BTreeMap;

/// Checks the conversion rule `convert` (material → material) of the stage at `path` and,
/// when it holds, rewrites the `material` of every body of `scene` (the scene document
/// the stage runs, before validation) made of a converted material. `first`: the stage
/// is the first (nothing to take over from).
pub(super) fn apply_conversion(
    scene: &mut serde_json::Value,
    convert: &BTreeMap<String, String>,
    path: &str,
    first: bool,
) -> Vec<Issue> {
    let mut issues = Vec::new();
    if convert.is_empty() {
        return issues;
    }
    let at = format!("{path}.convert");
    if first {
        issues.push(Issue::new(
            at.clone(),
            "the first stage has no stage before it to take particles over from",
        ));
        return issues;
    }
    let has_material = |name: &str| {
        scene
            .pointer("/materials")
            .and_then(|m| m.as_object())
            .is_some_and(|m| m.contains_key(name))
    };
    let bodies: Vec<(String, bool)> = scene
        .pointer("/bodies")
        .and_then(|b| b.as_array())
        .map(|bodies| {
            bodies
                .iter()
                .map(|b| {
                    let material = b["material"].as_str().unwrap_or_default().to_string();
                    let inflow = b.pointer("/shape/inflow").is_some();
                    (material, inflow)
                })
                .collect()
        })
        .unwrap_or_default();
    for (from, to) in convert {
        let key = format!("{at}.{from}");
        if !has_material(from) {
            issues.push(Issue::new(
                key.clone(),
                format!("no material `{from}` in the scene's `materials`"),
            ));
        } else if !bodies.iter().any(|(m, _)| m == from) {
            issues.push(Issue::new(
                key.clone(),
                format!("no body is made of `{from}`: there is nothing to convert"),
            ));
        }
        if !has_material(to) {
            issues.push(Issue::new(
                key.clone(),
                format!("no material `{to}` in the scene's `materials` to convert into"),
            ));
        }
        if from == to {
            issues.push(Issue::new(key.clone(), "converts a material into itself"));
        }
        if convert.contains_key(to) {
            issues.push(Issue::new(
                key.clone(),
                format!(
                    "`{to}` is converted too in this stage: a conversion names the material the \
                     particles end as"
                ),
            ));
        }
        if bodies.iter().any(|(m, inflow)| m == from && *inflow) {
            // The inflow's schedule and its waiting particles belong to incompressible
            // mechanics; a solid inlet means nothing.
            issues.push(Issue::new(
                key,
                format!(
                    "an inflow body is made of `{from}`: an inlet's particles cannot become \
                     another material (end the inflow and fill from a body, or keep the \
                     liquid)"
                ),
            ));
        }
    }
    if !issues.is_empty() {
        return issues;
    }
    if let Some(bodies) = scene.pointer_mut("/bodies").and_then(|b| b.as_array_mut()) {
        for body in bodies {
            let to = body["material"].as_str().and_then(|m| convert.get(m));
            if let Some(to) = to {
                body["material"] = serde_json::Value::String(to.clone());
            }
        }
    }
    issues
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn scene() -> serde_json::Value {
        json!({
            "materials": {"resin": {}, "underfill": {}, "die": {}},
            "bodies": [
                {"material": "die", "shape": {"box": {}}},
                {"material": "resin", "shape": {"box": {}}},
                {"material": "resin", "shape": {"sphere": {}}}
            ]
        })
    }

    #[test]
    fn a_conversion_rewrites_the_bodies_of_the_material() {
        let mut s = scene();
        let rule = BTreeMap::from([("resin".to_string(), "underfill".to_string())]);
        assert!(apply_conversion(&mut s, &rule, "stages[1]", false).is_empty());
        let materials: Vec<&str> = s["bodies"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| b["material"].as_str().unwrap())
            .collect();
        assert_eq!(materials, ["die", "underfill", "underfill"]);
    }

    #[test]
    fn bad_conversions_are_named_by_their_path() {
        let cases = [
            (("glue", "underfill"), "no material `glue`"),
            (("underfill", "die"), "no body is made of `underfill`"),
            (("resin", "paste"), "no material `paste`"),
            (("resin", "resin"), "into itself"),
        ];
        for ((from, to), expected) in cases {
            let mut s = scene();
            let rule = BTreeMap::from([(from.to_string(), to.to_string())]);
            let issues = apply_conversion(&mut s, &rule, "stages[1]", false);
            assert!(
                issues
                    .iter()
                    .any(|i| i.path == format!("stages[1].convert.{from}")
                        && i.message.contains(expected)),
                "{from} -> {to}: {issues:?}"
            );
            assert_eq!(s, scene(), "a refused rule changes nothing");
        }
        let mut s = scene();
        let rule = BTreeMap::from([("resin".to_string(), "underfill".to_string())]);
        let issues = apply_conversion(&mut s, &rule, "stages[0]", true);
        assert!(issues[0].message.contains("first stage"));
        let mut s = scene();
        s["bodies"][2]["shape"] = json!({"inflow": {}});
        let issues = apply_conversion(&mut s, &rule, "stages[1]", false);
        assert!(issues[0].message.contains("inflow body"), "{issues:?}");
        let mut s = scene();
        let chained = BTreeMap::from([
            ("resin".to_string(), "die".to_string()),
            ("die".to_string(), "underfill".to_string()),
        ]);
        let issues = apply_conversion(&mut s, &chained, "stages[1]", false);
        assert!(issues.iter().any(|i| i.message.contains("converted too")));
    }
}
