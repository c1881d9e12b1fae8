//! Damage figures a stage reports at its end, per material whose law keeps a `damage`
//! state field (`johnson_cook`, `phase_mixture` with damage): the largest damage, and the
//! particles that failed (damage 1) with their current volume, the size of the cracks.

use crate::math::determinant;
use crate::particles::Particles;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One material's damage at a stage's end.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DamageFigures {
    /// Largest damage of its particles, in [0, 1].
    pub peak: f64,
    /// Particles at damage 1 (failed: they carry no tension).
    pub failed_particles: usize,
    /// Current volume of the failed particles, m³ (m² per unit thickness in 2D): a crack's
    /// area in a 2D section, whose length is about this over the particle spacing.
    pub failed_volume: f64,
}

/// The damage figures of every material whose law keeps a `damage` field; materials
/// without one are left out.
pub fn damage_figures<const D: usize>(particles: &Particles<D>) -> BTreeMap<String, DamageFigures> {
    let mut out = BTreeMap::new();
    for group in &particles.groups {
        let Some(field) = group
            .material
            .state_fields()
            .iter()
            .position(|f| f.name == "damage" && f.components == 1)
        else {
            continue;
        };
        let entry: &mut DamageFigures = out.entry(group.name.clone()).or_default();
        for (k, &d) in group.state[field].iter().enumerate() {
            entry.peak = entry.peak.max(d);
            if d >= 1.0 {
                let p = group.range.start + k;
                entry.failed_particles += 1;
                entry.failed_volume +=
                    determinant(&particles.deformation_gradient[p]) * particles.volume0[p];
            }
        }
    }
    out
}
