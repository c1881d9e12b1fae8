//! Stress update: every material group's law updates its particles' stress, one batch of
//! particles per call, batches in parallel. When a physics creates a free strain (thermal
//! expansion, shrinkage) the laws see the mechanical part of F only.

use super::generalized_plane_strain::GeneralizedPlaneStrain;
use super::parallel::{SharedSlice, ordered_particle_sum, ordered_reduce};
use super::stats::ParticleFault;
use crate::material::{BatchStats, MAX_SHARED_READS, MAX_STATE_FIELDS, StateSlices, StressBatch};
use crate::math::Matrix;
use crate::particles::{MaterialGroup, Particles};
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
    /// Each particle's mechanical stretch across the plane, 1/(1 + free strain), where the
    /// free strain acts across it (`MaterialGroup::free_strain_across_plane`), else 1;
    /// empty when no group takes it so.
    stretch: Vec<f64>,
    /// ε₀ and its solve with `free_strain_2d: "generalized_plane_strain"` (2D; else none).
    pub generalized: Option<GeneralizedPlaneStrain>,
    /// Largest wave speed of each material group at the last update (implicit mechanics
    /// scales its preconditioner with it).
    pub group_wave_speed: Vec<f64>,
}

impl<const D: usize> StressScratch<D> {
    /// Buffers for a scene, with ε₀'s solve when it takes generalized plane strain.
    pub fn new(generalized: bool) -> Self {
        Self {
            generalized: generalized.then(GeneralizedPlaneStrain::default),
            ..Self::default()
        }
    }

    /// The stretch across the plane each particle's law saw in the last update (empty: 1).
    pub fn last_stretch(&self) -> &[f64] {
        match &self.generalized {
            Some(g) => &g.stretch,
            None => &self.stretch,
        }
    }

    /// ε₀ of the last solve with generalized plane strain (none without it).
    pub fn out_of_plane_strain(&self) -> Option<f64> {
        self.generalized.as_ref().map(|g| g.strain)
    }

    /// Makes the updates evaluate at ε₀ = `strain` instead of solving for it (`None`: solve
    /// again), and sets the stretch [`StressScratch::last_stretch`] gives for it, so that
    /// what a probe changed is undone by `hold_out_of_plane_strain(None)` without an update.
    /// Nothing without generalized plane strain.
    pub fn hold_out_of_plane_strain(&mut self, strain: Option<f64>, groups: &[MaterialGroup]) {
        if let Some(g) = &mut self.generalized {
            g.held = strain;
            if !g.stretch.is_empty() {
                let n = g.stretch.len();
                g.fill(strain.unwrap_or(g.strain), &self.stretch, groups, n);
            }
        }
    }

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
        if let Some(g) = &self.generalized {
            c.put("stress.out_of_plane_strain", vec![g.strain, g.slope]);
        }
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
        // A checkpoint from before generalized plane strain starts ε₀ at 0.
        if let (Some(g), Some(&[strain, slope])) = (
            &mut self.generalized,
            c.arrays
                .get("stress.out_of_plane_strain")
                .map(|v| v.as_slice()),
        ) {
            g.strain = strain;
            g.slope = slope;
        }
        Ok(())
    }
}

/// The factor particle `p`'s material group applies to its free strain in the plane (see
/// `MaterialGroup::free_strain_factor`); groups cover the particles in order.
#[inline]
pub(crate) fn free_strain_factor(groups: &[crate::particles::MaterialGroup], p: usize) -> f64 {
    group_of(groups, p).map_or(1.0, |g| g.free_strain_factor)
}

/// Whether particle `p`'s free strain also acts across the plane (see
/// `MaterialGroup::free_strain_across_plane`).
#[inline]
pub(crate) fn free_strain_across_plane(
    groups: &[crate::particles::MaterialGroup],
    p: usize,
) -> bool {
    group_of(groups, p).is_some_and(|g| g.free_strain_across_plane)
}

/// The material group particle `p` belongs to.
#[inline]
fn group_of(
    groups: &[crate::particles::MaterialGroup],
    p: usize,
) -> Option<&crate::particles::MaterialGroup> {
    groups.get(groups.partition_point(|g| g.range.end <= p))
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
        stress_zz,
        groups,
        shared,
        ..
    } = particles;
    let free_strain = shared.get(FREE_STRAIN);
    let mut free_strain_work = 0.0;
    let across_plane = free_strain.is_some() && groups.iter().any(|g| g.free_strain_across_plane);
    if let Some(fs) = free_strain {
        scratch.mechanical.resize(n, Matrix::<D>::identity());
        scratch.applied.resize(n, 0.0);
        scratch.lever.resize(n, 0.0);
        scratch
            .stretch
            .resize(if across_plane { n } else { 0 }, 1.0);
        let mechanical = SharedSlice::new(&mut scratch.mechanical);
        let applied = SharedSlice::new(&mut scratch.applied);
        let lever = SharedSlice::new(&mut scratch.lever);
        let stretch = SharedSlice::new(&mut scratch.stretch);
        let stress_zz = &*stress_zz;
        free_strain_work = ordered_particle_sum(n, |p| {
            // SAFETY: the sum visits each particle once, in disjoint chunks.
            let (fm, applied, lever) = unsafe { (mechanical.get(p), applied.get(p), lever.get(p)) };
            let f = &deformation_gradient[p];
            let e = fs[p] * free_strain_factor(groups, p);
            *fm = f * (1.0 / (1.0 + e));
            let mut trace: f64 = (0..D).map(|d| stress[p][(d, d)]).sum();
            if across_plane {
                let across = free_strain_across_plane(groups, p);
                // SAFETY: as above.
                unsafe { *stretch.get(p) = if across { 1.0 / (1.0 + e) } else { 1.0 } };
                if across {
                    trace += stress_zz[p];
                }
            }
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
    let has_zz = n > 0 && stress_zz.len() == n;
    let zz_out = SharedSlice::new(stress_zz);
    let has_work = n > 0 && plastic_work.len() == n;
    let work_out = SharedSlice::new(&mut plastic_work);
    let mut total = StressStats {
        free_strain_work,
        ..StressStats::default()
    };
    scratch.group_wave_speed.resize(groups.len(), 0.0);
    let laws = Laws {
        dt,
        kinematic,
        velocity_gradient,
        volume0,
        shared,
        stress_out,
        zz_out: has_zz.then_some(zz_out),
        work_out: has_work.then_some(work_out),
    };
    let stats = match scratch.generalized.as_mut().filter(|_| has_zz) {
        Some(gps) if gps.held.is_some() => {
            // A probe at a given ε₀: one evaluation, no solve.
            gps.fill(gps.held.unwrap_or(gps.strain), &scratch.stretch, groups, n);
            laws.run(&gps.stretch, groups, &mut scratch.group_wave_speed)
        }
        Some(gps) => {
            // Solve ε₀ for no net force across the plane (`generalized_plane_strain.rs`).
            gps.save(groups);
            let mut step = None;
            // From the last update's ε₀.
            let mut strain = gps.strain;
            loop {
                gps.fill(strain, &scratch.stretch, groups, n);
                let stats = laws.run(&gps.stretch, groups, &mut scratch.group_wave_speed);
                // SAFETY: no batch is running; the whole slice is read here only.
                let zz = unsafe { zz_out.range(0..n) };
                let (force, scale) =
                    GeneralizedPlaneStrain::force(zz, deformation_gradient, volume0);
                match gps.next(&mut step, strain, force, scale) {
                    Some(next) => {
                        gps.restore(groups);
                        strain = next;
                    }
                    None => break stats,
                }
            }
        }
        None => laws.run(&scratch.stretch, groups, &mut scratch.group_wave_speed),
    };
    total.batch = stats.batch;
    total.non_finite = stats.non_finite;
    if free_strain.is_some() {
        // The other half of the trapezoid: the stress after the update.
        let lever = &scratch.lever;
        let (stress_zz, groups) = (&*stress_zz, &*groups);
        total.free_strain_work += ordered_particle_sum(n, |p| {
            let mut trace = (0..D).map(|d| stress[p][(d, d)]).sum::<f64>();
            if across_plane && free_strain_across_plane(groups, p) {
                trace += stress_zz[p];
            }
            -0.5 * trace * lever[p]
        });
    }
    if has_work {
        total.plastic_work = ordered_particle_sum(n, |p| plastic_work[p] * volume0[p]);
    }
    particles.shared.restore(PLASTIC_WORK, plastic_work);
    total
}

/// What every law's batch update reads and where it writes, for one evaluation of all
/// groups (the generalized plane strain evaluates them again with another stretch).
struct Laws<'a, const D: usize> {
    dt: f64,
    /// The deformation gradient the laws see (the mechanical one with a free strain).
    kinematic: &'a [Matrix<D>],
    velocity_gradient: &'a [Matrix<D>],
    volume0: &'a [f64],
    shared: &'a crate::physics::ParticleFields,
    stress_out: SharedSlice<Matrix<D>>,
    /// σzz of every particle (2D).
    zz_out: Option<SharedSlice<f64>>,
    /// The plastic work field, when allocated.
    work_out: Option<SharedSlice<f64>>,
}

impl<const D: usize> Laws<'_, D> {
    /// Runs every group's law on its particles with `stretch` across the plane (empty: 1),
    /// batches in parallel; records each group's largest wave speed.
    fn run(
        &self,
        stretch: &[f64],
        groups: &mut [crate::particles::MaterialGroup],
        group_wave_speed: &mut [f64],
    ) -> StressStats
    where
        dyn crate::material::Material: DimensionDispatch<D>,
    {
        let mut total = StressStats::default();
        for (g, group) in groups.iter_mut().enumerate() {
            if group.held {
                // Held in place at F = I: no stress, and no history to advance.
                group_wave_speed[g] = 0.0;
                continue;
            }
            let range = group.range.clone();
            let count = range.len();
            let material = group.material.clone();
            let writes_zz = material.plane_strain_stress();
            let specs = material.state_fields();
            let reads: [Option<&[f64]>; MAX_SHARED_READS] = std::array::from_fn(|k| {
                material
                    .shared_reads()
                    .get(k)
                    .and_then(|r| self.shared.get(r.name))
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
                    let stress = unsafe { self.stress_out.range(global.clone()) };
                    let fields = std::array::from_fn(|k| match state_out[k] {
                        // SAFETY: as above, scaled by the field's components.
                        Some(s) => unsafe { s.range(local.start * comps[k]..local.end * comps[k]) },
                        None => &mut [][..],
                    });
                    let plastic_work = match self.work_out {
                        // SAFETY: as above.
                        Some(w) => unsafe { w.range(global.clone()) },
                        None => &mut [][..],
                    };
                    let out_of_plane_stress = match self.zz_out {
                        Some(zz) => {
                            // SAFETY: as above.
                            let zz = unsafe { zz.range(global.clone()) };
                            if !writes_zz {
                                // A law that does not give σzz leaves none from an earlier
                                // stage's.
                                zz.fill(0.0);
                            }
                            zz
                        }
                        None => &mut [][..],
                    };
                    let batch = StressBatch {
                        dt: self.dt,
                        deformation_gradient: &self.kinematic[global.clone()],
                        out_of_plane_stretch: if stretch.is_empty() {
                            &[]
                        } else {
                            &stretch[global.clone()]
                        },
                        out_of_plane_stress,
                        velocity_gradient: if self.velocity_gradient.is_empty() {
                            &[]
                        } else {
                            &self.velocity_gradient[global.clone()]
                        },
                        volume0: &self.volume0[global.clone()],
                        stress,
                        state: StateSlices { fields },
                        shared: std::array::from_fn(|k| {
                            reads[k].map_or(&[][..], |f| &f[global.clone()])
                        }),
                        plastic_work,
                    };
                    let batch_stats = material.as_ref().update(batch);
                    // SAFETY: as above (the batch's borrow ended with the call).
                    let stress = unsafe { self.stress_out.range(global.clone()) };
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
            group_wave_speed[g] = stats.batch.max_wave_speed;
            total.batch = total.batch.merge(stats.batch);
            total.non_finite = ParticleFault::first(total.non_finite, stats.non_finite);
        }
        total
    }
}
