//! The `physics.phase_change` scene section and its checks.

use crate::cure::CureParameters;
use crate::melting::Melting;
use mpm_core::scene::{Issue, Scene};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Scene section `physics.phase_change`.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PhaseChangeParameters {
    /// Materials that melt or cure, by material name; others keep solid fraction 1.
    pub materials: BTreeMap<String, PhaseChangeMaterial>,
}

/// What happens to one material: it melts and solidifies, or it cures (not both).
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PhaseChangeMaterial {
    /// Melting and solidification with latent heat.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub melting: Option<Melting>,
    /// Thermoset cure.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cure: Option<CureParameters>,
}

impl PhaseChangeParameters {
    /// Every problem with the section, with JSON paths below `path`.
    pub fn check(&self, path: &str, scene: &Scene) -> Vec<Issue> {
        let mut issues = Vec::new();
        if !scene.physics.contains_key("thermal") {
            issues.push(Issue::new(
                path,
                "phase change needs heat conduction: add a `physics.thermal` section",
            ));
        }
        for (name, m) in &self.materials {
            let p = format!("{path}.materials.{name}");
            if !scene.materials.contains_key(name) {
                issues.push(Issue::new(
                    &p,
                    format!("no material `{name}` in the scene's `materials`"),
                ));
            }
            match (&m.melting, &m.cure) {
                (Some(melt), None) => issues.extend(melt.check(&format!("{p}.melting"))),
                (None, Some(cure)) => issues.extend(cure.check(&format!("{p}.cure"))),
                _ => issues.push(Issue::new(&p, "give exactly one of `melting` and `cure`")),
            }
        }
        issues
    }

    /// Whether any material cures.
    pub fn has_cure(&self) -> bool {
        self.materials.values().any(|m| m.cure.is_some())
    }

    /// Whether any material produces a free strain (density change or shrinkage).
    pub fn has_free_strain(&self) -> bool {
        self.materials.values().any(|m| {
            m.melting
                .as_ref()
                .is_some_and(|x| x.solid.density != x.liquid.density)
                || m.cure.as_ref().is_some_and(|c| c.shrinkage > 0.0)
        })
    }
}
