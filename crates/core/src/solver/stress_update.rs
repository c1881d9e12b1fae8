//! Stress update: every material group's law updates its particles' stress, one batch of
//! particles per call, batches in parallel. When a physics creates a free strain (thermal
//! expansion, shrinkage) the laws see the mechanical part of F only.

use super::parallel::{SharedSlice, ordered_particle_sum, ordered_reduce};
use super::stats::ParticleFault;
use crate::material::{BatchStats, MAX_SHARED_READS, MAX_STATE_FIELDS, StateSlices, StressBatch};
use crate::math::Matrix;
use crate::particles::Particles;
use crate::physics::{FREE_STRAIN, PLASTIC_WORK};
use crate::solver::DimensionDispatch;

/// Particles per material call.
const BATCH: usize = 1024;

/// Statistics of the stress update.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct StressStats {
    pub batch: BatchStats,
    pub non_finite: Option<ParticleFault>,
    /// Work the change of free strain did on the stress in this update (it enters the energy
    /// balance like work done from outside), J (J/m in 2D).
    pub free_strain_work: f64,
    /// Plastic work the materials reported in this update, J (J/m in 2D).
    pub plastic_work: f64,
}

/// Buffers of the stress update, allocated only when the scene has a free strain.
#[derive(Default)]
pub(crate) struct StressScratch<const D: usize> {
    /// Mechanical deformation gradient `F / (1 + free strain)`.
    mechanical: Vec<Matrix<D>>,
    /// Free strain at the last update.
    applied: Vec<f64>,
    /// Each particle's lever for the free-strain work of this update, Δ(free strain)·J·V₀:
    /// the work is −tr σ times it, with σ averaged over the update (trapezoid).
    lever: Vec<f64>,
    /// Largest wave speed of each material group at the last update (implicit mechanics
    /// scales its preconditioner with it).
    pub group_wave_speed: Vec<f64>,
}

impl<const D: usize> StressScratch<D> {
    /// Free strain each particle's stress had at the last update (empty without one).
    pub fn applied(&self) -> &[f64] {
        &self.applied
    }

    /// The same, to restore it when a step is retried.
    pub fn applied_mut(&mut self) -> &mut Vec<f64> {
        &mut self.applied
    }

    /// Writes what the next update reads of the last one into a checkpoint.
    pub fn save(&self, c: &mut crate::checkpoint::Checkpoint) {
        c.put("stress.applied_free_strain", self.applied.clone());
        c.put("stress.group_wave_speed", self.group_wave_speed.clone());
    }

    /// Takes back what [`StressScratch::save`] wrote.
    pub fn restore(
        &mut self,
        c: &crate::checkpoint::Checkpoint,
    ) -> Result<(), crate::checkpoint::CheckpointError> {
        for (name, target) in [
            ("stress.applied_free_strain", &mut self.applied),
            ("stress.group_wave_speed", &mut self.group_wave_speed),
        ] {
            let values = c
                .arrays
                .get(name)
                .ok_or_else(|| crate::checkpoint::CheckpointError::Missing(name.into()))?;
            target.clear();
            target.extend_from_slice(values);
        }
        Ok(())
    }
}

/// The factor particle `p`'s material group applies to its free strain in the plane (see
/// `MaterialGroup::free_strain_factor`); groups cover the particles in order.
#[inline]
pub(crate) fn free_strain_factor(groups: &[crate::particles::MaterialGroup], p: usize) -> f64 {
    let g = groups.partition_point(|g| g.range.end <= p);
    groups.get(g).map_or(1.0, |g| g.free_strain_factor)
}

/// Runs every material on its particles.
pub(crate) fn update_stress<const D: usize>(
    particles: &mut Particles<D>,
    dt: f64,
    scratch: &mut StressScratch<D>,
) -> StressStats
where
    dyn crate::material::Material: DimensionDispatch<D>,
{
    let n = particles.len();
    let mut plastic_work = particles.shared.take(PLASTIC_WORK);
    let Particles {
        deformation_gradient,
        velocity_gradient,
        volume0,
        stress,
        groups,
        shared,
        ..
    } = particles;
    let free_strain = shared.get(FREE_STRAIN);
    let mut free_strain_work = 0.0;
    if let Some(fs) = free_strain {
        scratch.mechanical.resize(n, Matrix::<D>::identity());
        scratch.applied.resize(n, 0.0);
        scratch.lever.resize(n, 0.0);
        let mechanical = SharedSlice::new(&mut scratch.mechanical);
        let applied = SharedSlice::new(&mut scratch.applied);
        let lever = SharedSlice::new(&mut scratch.lever);
        free_strain_work = ordered_particle_sum(n, |p| {
            // SAFETY: the sum visits each particle once, in disjoint chunks.
            let (fm, applied, lever) = unsafe { (mechanical.get(p), applied.get(p), lever.get(p)) };
            let f = &deformation_gradient[p];
            let e = fs[p] * free_strain_factor(groups, p);
            *fm = f * (1.0 / (1.0 + e));
            let trace: f64 = (0..D).map(|d| stress[p][(d, d)]).sum();
            *lever = (e - *applied) * crate::math::determinant(f) * volume0[p];
            *applied = e;
            -0.5 * trace * *lever
        });
    }
    let kinematic: &[Matrix<D>] = if free_strain.is_some() {
        &scratch.mechanical
    } else {
        deformation_gradient
    };
    let stress_out = SharedSlice::new(stress);
    let has_work = n > 0 && plastic_work.len() == n;
    let work_out = SharedSlice::new(&mut plastic_work);
    let mut total = StressStats {
        free_strain_work,
        ..StressStats::default()
    };
    scratch.group_wave_speed.resize(groups.len(), 0.0);
    for (g, group) in groups.iter_mut().enumerate() {
        let range = group.range.clone();
        let count = range.len();
        let material = group.material.clone();
        let specs = material.state_fields();
        let reads: [Option<&[f64]>; MAX_SHARED_READS] = std::array::from_fn(|k| {
            material
                .shared_reads()
                .get(k)
                .and_then(|r| shared.get(r.name))
        });
        let mut state_out = [None; MAX_STATE_FIELDS];
        for (k, field) in group.state.iter_mut().enumerate() {
            state_out[k] = Some(SharedSlice::new(field));
        }
        let comps: [usize; MAX_STATE_FIELDS] =
            std::array::from_fn(|k| specs.get(k).map_or(0, |s| s.components));
        let stats = ordered_reduce(
            count.div_ceil(BATCH),
            StressStats::default,
            |b| {
                let local = b * BATCH..((b + 1) * BATCH).min(count);
                let global = range.start + local.start..range.start + local.end;
                // SAFETY: batches are disjoint particle ranges of this group.
                let stress = unsafe { stress_out.range(global.clone()) };
                let fields = std::array::from_fn(|k| match state_out[k] {
                    // SAFETY: as above, scaled by the field's components.
                    Some(s) => unsafe { s.range(local.start * comps[k]..local.end * comps[k]) },
                    None => &mut [][..],
                });
                let plastic_work = if has_work {
                    // SAFETY: as above.
                    unsafe { work_out.range(global.clone()) }
                } else {
                    &mut [][..]
                };
                let batch = StressBatch {
                    dt,
                    deformation_gradient: &kinematic[global.clone()],
                    velocity_gradient: if velocity_gradient.is_empty() {
                        &[]
                    } else {
                        &velocity_gradient[global.clone()]
                    },
                    volume0: &volume0[global.clone()],
                    stress,
                    state: StateSlices { fields },
                    shared: std::array::from_fn(|k| {
                        reads[k].map_or(&[][..], |f| &f[global.clone()])
                    }),
                    plastic_work,
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
                    ..StressStats::default()
                }
            },
            |a, b| StressStats {
                batch: a.batch.merge(b.batch),
                non_finite: ParticleFault::first(a.non_finite, b.non_finite),
                ..StressStats::default()
            },
        );
        scratch.group_wave_speed[g] = stats.batch.max_wave_speed;
        total.batch = total.batch.merge(stats.batch);
        total.non_finite = ParticleFault::first(total.non_finite, stats.non_finite);
    }
    if free_strain.is_some() {
        // The other half of the trapezoid: the stress after the update.
        let lever = &scratch.lever;
        total.free_strain_work += ordered_particle_sum(n, |p| {
            -0.5 * (0..D).map(|d| stress[p][(d, d)]).sum::<f64>() * lever[p]
        });
    }
    if has_work {
        total.plastic_work = ordered_particle_sum(n, |p| plastic_work[p] * volume0[p]);
    }
    particles.shared.restore(PLASTIC_WORK, plastic_work);
    total
}
