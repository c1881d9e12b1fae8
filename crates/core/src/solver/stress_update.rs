//! Stress update: every material group's law updates its particles' stress, one batch of
//! particles per call, batches in parallel.

use super::parallel::SharedSlice;
use super::stats::ParticleFault;
use crate::material::{BatchStats, MAX_STATE_FIELDS, StateSlices, StressBatch};
use crate::particles::Particles;
use crate::solver::DimensionDispatch;
use rayon::prelude::*;

/// Particles per material call.
const BATCH: usize = 1024;

/// Statistics of the stress update.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct StressStats {
    pub batch: BatchStats,
    pub non_finite: Option<ParticleFault>,
}

/// Runs every material on its particles.
pub(crate) fn update_stress<const D: usize>(particles: &mut Particles<D>, dt: f64) -> StressStats
where
    dyn crate::material::Material: DimensionDispatch<D>,
{
    let Particles {
        deformation_gradient,
        velocity_gradient,
        volume0,
        stress,
        groups,
        ..
    } = particles;
    let stress_out = SharedSlice::new(stress);
    let mut total = StressStats::default();
    for group in groups.iter_mut() {
        let range = group.range.clone();
        let n = range.len();
        let material = group.material.clone();
        let specs = material.state_fields();
        let mut state_out = [None; MAX_STATE_FIELDS];
        for (k, field) in group.state.iter_mut().enumerate() {
            state_out[k] = Some(SharedSlice::new(field));
        }
        let comps: [usize; MAX_STATE_FIELDS] =
            std::array::from_fn(|k| specs.get(k).map_or(0, |s| s.components));
        let stats = (0..n.div_ceil(BATCH))
            .into_par_iter()
            .map(|b| {
                let local = b * BATCH..((b + 1) * BATCH).min(n);
                let global = range.start + local.start..range.start + local.end;
                // SAFETY: batches are disjoint particle ranges of this group.
                let stress = unsafe { stress_out.range(global.clone()) };
                let fields = std::array::from_fn(|k| match state_out[k] {
                    // SAFETY: as above, scaled by the field's components.
                    Some(s) => unsafe { s.range(local.start * comps[k]..local.end * comps[k]) },
                    None => &mut [][..],
                });
                let batch = StressBatch {
                    dt,
                    deformation_gradient: &deformation_gradient[global.clone()],
                    velocity_gradient: if velocity_gradient.is_empty() {
                        &[]
                    } else {
                        &velocity_gradient[global.clone()]
                    },
                    volume0: &volume0[global.clone()],
                    stress,
                    state: StateSlices { fields },
                };
                let batch_stats = material.as_ref().update(batch);
                // SAFETY: as above (the batch's borrow ended with the call).
                let stress = unsafe { stress_out.range(global.clone()) };
                let non_finite = stress
                    .iter()
                    .position(|s| !s.iter().all(|c| c.is_finite()))
                    .map(|k| ParticleFault {
                        particle: global.start + k,
                        field: "stress",
                        value: stress[k].norm(),
                    });
                StressStats {
                    batch: batch_stats,
                    non_finite,
                }
            })
            .reduce(StressStats::default, |a, b| StressStats {
                batch: a.batch.merge(b.batch),
                non_finite: ParticleFault::first(a.non_finite, b.non_finite),
            });
        total.batch = total.batch.merge(stats.batch);
        total.non_finite = ParticleFault::first(total.non_finite, stats.non_finite);
    }
    total
}
