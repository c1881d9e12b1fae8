//! Fatigue figures of a staged run's stages, per material whose law accumulates its
//! inelastic work ([`crate::material::INELASTIC_WORK`], the `anand` solder law): the work
//! density averaged over the material's reference volume at the stage's end, its increase
//! over the stage, and, when the law has a fatigue law and the stage is one thermal
//! cycle, the cycles to crack initiation that increase gives (energy-based solder fatigue
//! in the manner of Darveaux and Syed, who average the work over the joint's volume).

use crate::material::INELASTIC_WORK;
use crate::particles::Particles;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One material's inelastic work over a stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FatigueFigures {
    /// Inelastic work density accumulated since the run began, averaged over the
    /// material's reference volume, J/m³.
    pub work: f64,
    /// Its increase over this stage, J/m³: the work per cycle when the stage is a cycle.
    pub work_in_stage: f64,
    /// Cycles to crack initiation at `work_in_stage` per cycle, from the law's fatigue law
    /// (`None` without one, or without work in the stage).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cycles_to_crack: Option<f64>,
}

/// The fatigue figures of every material whose law keeps [`INELASTIC_WORK`], from its
/// average at the stage's start, `work_before` (0 for a material not in it).
pub fn fatigue_figures<const D: usize>(
    particles: &Particles<D>,
    work_before: &BTreeMap<String, f64>,
) -> BTreeMap<String, FatigueFigures> {
    let mut sums: BTreeMap<&str, (f64, f64, &dyn crate::material::Material)> = BTreeMap::new();
    for group in &particles.groups {
        let Some(field) = group
            .material
            .state_fields()
            .iter()
            .position(|f| f.name == INELASTIC_WORK && f.components == 1)
        else {
            continue;
        };
        let entry = sums
            .entry(group.name.as_str())
            .or_insert((0.0, 0.0, group.material.as_ref()));
        for (k, &w) in group.state[field].iter().enumerate() {
            let v0 = particles.volume0[group.range.start + k].abs();
            entry.0 += w * v0;
            entry.1 += v0;
        }
    }
    sums.into_iter()
        .map(|(name, (weighted, volume, material))| {
            let work = if volume > 0.0 { weighted / volume } else { 0.0 };
            let work_in_stage = work - work_before.get(name).copied().unwrap_or(0.0);
            let figures = FatigueFigures {
                work,
                work_in_stage,
                cycles_to_crack: material.cycles_to_crack(work_in_stage),
            };
            (name.to_string(), figures)
        })
        .collect()
}
