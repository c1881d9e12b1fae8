//! The analytic stress derivative of the implicit mode's tangent: every material group's
//! law differentiates its particles' stress along a change of F, one batch per call, batches
//! in parallel (as `stress_update.rs` updates them). With a free strain the laws see the
//! mechanical part of F and of its change.

use super::parallel::SharedSlice;
use crate::material::{MAX_SHARED_READS, MAX_STATE_FIELDS, StateView, TangentBatch};
use crate::math::Matrix;
use crate::particles::Particles;
use crate::physics::FREE_STRAIN;
use crate::solver::DimensionDispatch;
use rayon::prelude::*;

/// Particles per material call.
const BATCH: usize = 1024;

/// Whether every material of the particles gives its stress derivative analytically.
pub(crate) fn all_analytic<const D: usize>(particles: &Particles<D>) -> bool {
    particles
        .groups
        .iter()
        .all(|g| g.material.has_stress_derivative())
}

/// Scratch of the derivative with a free strain: the mechanical F and direction.
#[derive(Default)]
pub(crate) struct DerivativeScratch<const D: usize> {
    mechanical: Vec<Matrix<D>>,
    direction: Vec<Matrix<D>>,
}

/// Writes dσ_p = ∂σ/∂F : `direction[p]` at the particles' current F and stress into `out`;
/// `state` is each group's material state (per field) that the stress update started from,
/// `stretch` the stretch across the plane it used (`StressScratch::last_stretch`), held.
/// Only for particles whose laws all have the derivative ([`all_analytic`]).
pub(crate) fn stress_derivative<const D: usize>(
    particles: &Particles<D>,
    state: &[Vec<Vec<f64>>],
    direction: &[Matrix<D>],
    stretch: &[f64],
    dt: f64,
    scratch: &mut DerivativeScratch<D>,
    out: &mut [Matrix<D>],
) where
    dyn crate::material::Material: DimensionDispatch<D>,
{
    let n = particles.len();
    let (kinematic, direction): (&[Matrix<D>], &[Matrix<D>]) =
        match particles.shared.get(FREE_STRAIN) {
            Some(fs) => {
                scratch.mechanical.resize(n, Matrix::<D>::zeros());
                scratch.direction.resize(n, Matrix::<D>::zeros());
                scratch
                    .mechanical
                    .par_iter_mut()
                    .zip(scratch.direction.par_iter_mut())
                    .enumerate()
                    .for_each(|(p, (fm, dm))| {
                        let factor = super::stress_update::free_strain_factor(&particles.groups, p);
                        let scale = 1.0 / (1.0 + fs[p] * factor);
                        *fm = particles.deformation_gradient[p] * scale;
                        *dm = direction[p] * scale;
                    });
                (&scratch.mechanical, &scratch.direction)
            }
            None => (&particles.deformation_gradient, direction),
        };
    let out_slice = SharedSlice::new(out);
    for (g, group) in particles.groups.iter().enumerate() {
        let range = group.range.clone();
        let material = group.material.clone();
        let specs = material.state_fields();
        let saved: &[Vec<f64>] = state.get(g).map_or(&[], |s| s.as_slice());
        let comps: [usize; MAX_STATE_FIELDS] =
            std::array::from_fn(|k| specs.get(k).map_or(0, |s| s.components));
        let reads: [Option<&[f64]>; MAX_SHARED_READS] = std::array::from_fn(|k| {
            material
                .shared_reads()
                .get(k)
                .and_then(|r| particles.shared.get(r.name))
        });
        (0..range.len().div_ceil(BATCH))
            .into_par_iter()
            .for_each(|b| {
                let start = range.start + b * BATCH;
                let global = start..(start + BATCH).min(range.end);
                let local = global.start - range.start..global.end - range.start;
                let fields = std::array::from_fn(|k| {
                    saved.get(k).map_or(&[][..], |f| {
                        &f[local.start * comps[k]..local.end * comps[k]]
                    })
                });
                let batch = TangentBatch {
                    dt,
                    deformation_gradient: &kinematic[global.clone()],
                    direction: &direction[global.clone()],
                    stress: &particles.stress[global.clone()],
                    out_of_plane_stretch: if stretch.is_empty() {
                        &[]
                    } else {
                        &stretch[global.clone()]
                    },
                    state: StateView { fields },
                    shared: std::array::from_fn(|k| {
                        reads[k].map_or(&[][..], |f| &f[global.clone()])
                    }),
                    // SAFETY: batches are disjoint particle ranges.
                    stress_change: unsafe { out_slice.range(global.clone()) },
                };
                material.as_ref().derivative(batch);
            });
    }
}
