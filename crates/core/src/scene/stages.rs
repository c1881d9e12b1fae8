//! Staged scenes: an ordered list of stages (fill, cure, cool-down, thermal cycling), each
//! the scene before it changed by a JSON merge patch (RFC 7396: an object merges key by
//! key, `null` removes a key, anything else replaces), run on from where the stage before
//! it ended, sharing the bodies, materials, domain and contact. Each stage is validated as
//! a scene of its own; its `solver.end_time` is the (absolute) time the stage ends.

use super::{Issue, Limits, ValidatedScene, parse_scene_value_limited};
use crate::plugin::Registry;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// One stage of a staged scene.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    /// Name of the stage (`fill`, `cure`, ...): its group in the result store is
    /// `stages/<index>-<name>`. Letters, digits, `-`, `_`.
    pub name: String,
    /// Changes to the scene of the stage before (the base scene for the first): a JSON
    /// merge patch. It must set `solver.end_time` later than the stage before ends, and may
    /// not change `name`, `dimension`, `domain`, `materials`, `bodies`, `contact` or `loads`
    /// (`convert` changes the bodies' materials).
    #[serde(default)]
    pub changes: serde_json::Value,
    /// Particles the stage removes as it takes over from the stage before (the gap's
    /// particles a fill left empty become the voids of the cured underfill).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub remove: Option<RemoveParticles>,
    /// Materials the stage turns particles into as it takes over, after any removal:
    /// `{"resin": "underfill"}` makes every particle of `resin` a particle of `underfill`
    /// where it is (the liquid at the end of a fill becomes the curing underfill). A
    /// converted particle starts as the new material's particles start a run: F = I, zero
    /// stress, the law's initial state, its mass from the new density; velocity and the
    /// physics fields (temperature, cure) carry over. Later stages keep the new material.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub convert: BTreeMap<String, String>,
}

/// A hand-over rule: the particles of `materials` (all when empty) whose particle field
/// `field`, as the stage before left it, is below `below` leave the run; the rest carry on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RemoveParticles {
    /// A particle field a physics of the stage before writes (`fill`, say).
    pub field: String,
    /// Particles with a value below this are removed.
    pub below: f64,
    /// Materials whose particles the rule applies to (empty: every material).
    #[serde(default)]
    pub materials: Vec<String>,
}

/// Top-level keys a stage may not change: the particles and the grid they live on carry
/// over from stage to stage as they are.
pub const FIXED_ACROSS_STAGES: &[&str] = &[
    "name",
    "dimension",
    "domain",
    "materials",
    "bodies",
    "contact",
    "loads",
    "stages",
];

/// A validated stage: its name and its scene.
pub struct ValidatedStage {
    /// The stage's name.
    pub name: String,
    /// The scene this stage runs (the base with every change up to this stage applied).
    pub scene: Box<ValidatedScene>,
    /// Particles the stage removes when it takes over.
    pub remove: Option<RemoveParticles>,
    /// Materials whose particles the stage converts when it takes over (its scene's
    /// bodies are already the converted ones).
    pub convert: BTreeMap<String, String>,
}

/// Applies the merge patch `patch` to `target` (RFC 7396).
pub fn merge_patch(target: &mut serde_json::Value, patch: &serde_json::Value) {
    let Some(changes) = patch.as_object() else {
        *target = patch.clone();
        return;
    };
    if !target.is_object() {
        *target = serde_json::Value::Object(serde_json::Map::new());
    }
    let Some(object) = target.as_object_mut() else {
        return;
    };
    for (key, value) in changes {
        if value.is_null() {
            object.remove(key);
        } else {
            merge_patch(
                object.entry(key.clone()).or_insert(serde_json::Value::Null),
                value,
            );
        }
    }
}

/// Validates every stage of `stages` against the base scene `base` (the scene document
/// without its `stages`); issues carry the stage's path.
pub(super) fn validate_stages(
    base: &serde_json::Value,
    stages: &[StageSpec],
    registry: &Registry,
    base_dir: &Path,
    limits: &Limits,
) -> Result<Vec<ValidatedStage>, Vec<Issue>> {
    let mut issues = Vec::new();
    let mut out = Vec::new();
    let mut current = base.clone();
    let mut previous_end = 0.0f64;
    let mut names = std::collections::BTreeSet::new();
    for (i, stage) in stages.iter().enumerate() {
        let path = format!("stages[{i}]");
        let name_ok = !stage.name.is_empty()
            && stage
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
        if !name_ok {
            issues.push(Issue::new(
                format!("{path}.name"),
                "must be letters, digits, `-` or `_` (it names the stage's group in the store)",
            ));
        }
        if !names.insert(stage.name.clone()) {
            issues.push(Issue::new(
                format!("{path}.name"),
                format!("a stage named `{}` comes earlier", stage.name),
            ));
        }
        let Some(changes) = stage.changes.as_object() else {
            issues.push(Issue::new(
                format!("{path}.changes"),
                "must be an object (a JSON merge patch of the scene)",
            ));
            continue;
        };
        if stage.changes.pointer("/solver/refinement").is_some() {
            issues.push(Issue::new(
                format!("{path}.changes.solver.refinement"),
                "the refined step (solver.refinement) runs in a scene of one stage so far",
            ));
        }
        for key in changes.keys() {
            if FIXED_ACROSS_STAGES.contains(&key.as_str()) {
                issues.push(Issue::new(
                    format!("{path}.changes.{key}"),
                    format!(
                        "a stage may not change `{key}`: the particles, materials and grid carry \
                         over from stage to stage (stages may change solver, physics, obstacles, \
                         output, stop and reference)"
                    ),
                ));
            }
        }
        merge_patch(&mut current, &stage.changes);
        issues.extend(super::stage_conversion::apply_conversion(
            &mut current,
            &stage.convert,
            &path,
            i == 0,
        ));
        let end = current
            .pointer("/solver/end_time")
            .and_then(|v| v.as_f64())
            .unwrap_or(f64::NAN);
        if end.is_nan() || end <= previous_end {
            let before = if i == 0 {
                "the start (0 s)".to_string()
            } else {
                format!("the previous stage's end ({previous_end} s)")
            };
            issues.push(Issue::new(
                format!("{path}.changes.solver.end_time"),
                format!(
                    "the stage must end later than {before}: set solver.end_time to the time it \
                     ends (absolute, not its duration)"
                ),
            ));
        }
        previous_end = end;
        if !issues.is_empty() {
            continue;
        }
        match parse_scene_value_limited(current.clone(), registry, base_dir, limits) {
            Ok(scene) => {
                let before = out.last().map(|s: &ValidatedStage| &*s.scene);
                issues.extend(check_hand_over(&path, stage, &scene, before));
                out.push(ValidatedStage {
                    name: stage.name.clone(),
                    scene: Box::new(scene),
                    remove: stage.remove.clone(),
                    convert: stage.convert.clone(),
                });
            }
            Err(e) => issues.extend(e.issues.into_iter().map(|issue| {
                let top = issue.path.split(['.', '[']).next().unwrap_or("");
                let path = if changes.contains_key(top) {
                    format!("{path}.changes.{}", issue.path)
                } else {
                    issue.path
                };
                Issue::new(
                    path,
                    format!("in stage `{}`: {}", stage.name, issue.message),
                )
            })),
        }
    }
    if issues.is_empty() {
        Ok(out)
    } else {
        Err(issues)
    }
}

/// What a stage can take over from the stage before (`before`; none for the first): a
/// removal rule names a field that stage writes and materials the scene has, and no
/// physics whose state lives outside the particles continues across the hand-over.
fn check_hand_over(
    path: &str,
    stage: &StageSpec,
    scene: &ValidatedScene,
    before: Option<&ValidatedScene>,
) -> Vec<Issue> {
    let mut issues = Vec::new();
    if let Some(before) = before {
        for (name, _) in &scene.physics {
            let continued = before.physics.iter().find(|(n, _)| n == name);
            if let Some(what) = continued.and_then(|(_, p)| p.hidden_state()) {
                issues.push(Issue::new(
                    format!("{path}.changes.physics.{name}"),
                    format!(
                        "physics `{name}` keeps {what} between steps, which a hand-over between \
                         stages does not carry: end it with the stage before (set it to null \
                         here) or keep both in one stage"
                    ),
                ));
            }
        }
    }
    let Some(rule) = &stage.remove else {
        return issues;
    };
    let at = format!("{path}.remove");
    if scene
        .scene
        .bodies
        .iter()
        .any(|b| matches!(b.shape, super::Shape::Inflow(_)))
    {
        // The inflow schedule reads each particle's place from its id, which removal
        // renumbers.
        issues.push(Issue::new(
            at.clone(),
            "a scene with an inflow body cannot remove particles between stages (removal \
             renumbers the particles the inflow's schedule counts)",
        ));
    }
    match before {
        None => issues.push(Issue::new(
            at.clone(),
            "the first stage has no stage before it to take particles over from",
        )),
        Some(before) => {
            let written: Vec<&'static str> = before
                .physics
                .iter()
                .flat_map(|(_, p)| p.fields().into_iter().map(|f| f.name))
                .collect();
            if !written.contains(&rule.field.as_str()) {
                issues.push(Issue::new(
                    format!("{at}.field"),
                    format!(
                        "no physics of the stage before writes a particle field `{}` (it writes: \
                         {})",
                        rule.field,
                        if written.is_empty() {
                            "none".to_string()
                        } else {
                            written.join(", ")
                        }
                    ),
                ));
            }
        }
    }
    if !rule.below.is_finite() {
        issues.push(Issue::new(format!("{at}.below"), "must be a finite number"));
    }
    for (i, m) in rule.materials.iter().enumerate() {
        if !scene.scene.materials.contains_key(m) {
            issues.push(Issue::new(
                format!("{at}.materials[{i}]"),
                format!("no material `{m}` in the scene's `materials`"),
            ));
        }
    }
    issues
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn merge_patch_follows_rfc_7396() {
        let mut target = json!({"a": "b", "c": {"d": "e", "f": "g"}, "k": [1, 2]});
        merge_patch(
            &mut target,
            &json!({"a": "z", "c": {"f": null, "h": 1}, "k": [3]}),
        );
        assert_eq!(target, json!({"a": "z", "c": {"d": "e", "h": 1}, "k": [3]}));
    }
}
