//! Stress from the scene's materials over a set of particles (by parallel material
//! batches), and the row-major matrices the map writes, shared by the step and the frames.

use mpm_core::material::{BatchStats, Material, StateSlices, StressBatch};
use mpm_core::math::Matrix;
use mpm_core::solver::DimensionDispatch;
use rayon::prelude::*;

/// Builds a matrix from `D·D` row-major numbers.
#[inline(always)]
pub(super) fn matrix_from_rows<const D: usize>(s: &[f64]) -> Matrix<D> {
    Matrix::<D>::from_fn(|r, c| s[r * D + c])
}

/// Calls a material's batch update on chunks of particles in parallel.
pub(super) fn update_stress_parallel<const D: usize>(
    material: &(dyn Material + 'static),
    dt: f64,
    f: &[Matrix<D>],
    volume0: &[f64],
    stress: &mut [Matrix<D>],
) -> BatchStats
where
    dyn Material: DimensionDispatch<D>,
{
    const CHUNK: usize = 1024;
    stress
        .par_chunks_mut(CHUNK)
        .zip(f.par_chunks(CHUNK))
        .zip(volume0.par_chunks(CHUNK))
        .map(|((stress, f), volume0)| {
            <dyn Material as DimensionDispatch<D>>::update(
                material,
                StressBatch {
                    dt,
                    deformation_gradient: f,
                    velocity_gradient: &[],
                    volume0,
                    stress,
                    out_of_plane_stretch: &[],
                    out_of_plane_stress: &mut [],
                    state: StateSlices {
                        fields: Default::default(),
                    },
                    shared: [&[]; mpm_core::material::MAX_SHARED_READS],
                    plastic_work: &mut [],
                },
            )
        })
        .reduce(BatchStats::default, BatchStats::merge)
}
