//! Stress figures a stage reports at its end: the peak von Mises stress of each material
//! and, with `output.stress_averaging_radius`, the peak of its local average.
//!
//! The peak of a particle value does not converge at a corner where the elastic stress is
//! singular (the die corner over an underfill layer): it grows as the cell shrinks. The
//! average over a disk (sphere in 3D) of fixed radius around each particle, over the
//! particles of the same material, weighted by their current volume, does converge where
//! the singularity is integrable, which is the case at bimaterial corners (the stress
//! grows as r^−λ with λ < 1). This is the area method of the theory of critical distances:
//! the radius is a length of the material, not of the mesh.

use crate::cell_hash::CellHash;
use crate::math::{Matrix, determinant};
use crate::particles::Particles;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Von Mises stress of a stress tensor; in 2D (plane strain) `zz` is σzz, the stress across
/// the plane (the shears out of the plane are zero there). `zz` is unused in 3D.
pub(crate) fn von_mises<const D: usize>(s: &Matrix<D>, zz: f64) -> f64 {
    let c = |i: usize, j: usize| if i < D && j < D { s[(i, j)] } else { 0.0 };
    let zz = if D == 2 { zz } else { c(2, 2) };
    let (xx, yy) = (c(0, 0), c(1, 1));
    let (xy, yz, zx) = (c(0, 1), c(1, 2), c(2, 0));
    (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2))
        + 3.0 * (xy * xy + yz * yz + zx * zx))
        .sqrt()
}

/// Von Mises stress of particle `p`, σzz included in 2D (see [`Particles::stress_zz`]).
fn particle_von_mises<const D: usize>(particles: &Particles<D>, p: usize) -> f64 {
    let zz = particles.stress_zz.get(p).copied().unwrap_or(0.0);
    von_mises::<D>(&particles.stress[p], zz)
}

/// Largest von Mises stress of each material's particles, Pa.
pub fn peak_von_mises<const D: usize>(particles: &Particles<D>) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    for group in &particles.groups {
        let peak = group
            .range
            .clone()
            .map(|p| particle_von_mises(particles, p))
            .fold(0.0, f64::max);
        let entry = out.entry(group.name.clone()).or_insert(0.0f64);
        *entry = entry.max(peak);
    }
    out
}

/// Largest, over each material's particles, of the volume-weighted mean von Mises stress of
/// that material's particles within `radius` of the particle, Pa. Allocates (a cell hash
/// per material); called once at a stage's end.
pub fn averaged_peak_von_mises<const D: usize>(
    particles: &Particles<D>,
    radius: f64,
) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    for group in &particles.groups {
        let range = group.range.clone();
        let stress: Vec<f64> = range
            .clone()
            .map(|p| particle_von_mises(particles, p))
            .collect();
        let volume: Vec<f64> = range
            .clone()
            .map(|p| determinant(&particles.deformation_gradient[p]) * particles.volume0[p])
            .collect();
        let hash = CellHash::new(radius, &particles.position, range.clone());
        let start = range.start;
        let peak = range
            .into_par_iter()
            .map(|p| {
                let x = particles.position[p];
                let (mut weighted, mut total) = (0.0, 0.0);
                for q in hash.near(&x) {
                    if (particles.position[q] - x).norm() <= radius {
                        weighted += volume[q - start] * stress[q - start];
                        total += volume[q - start];
                    }
                }
                if total > 0.0 { weighted / total } else { 0.0 }
            })
            .reduce(|| 0.0, f64::max);
        let entry = out.entry(group.name.clone()).or_insert(0.0f64);
        *entry = entry.max(peak);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn von_mises_of_uniaxial_and_pure_shear() {
        let uniaxial = Matrix::<3>::from_diagonal(&crate::math::Vector::<3>::new(2.0, 0.0, 0.0));
        assert!((von_mises::<3>(&uniaxial, 0.0) - 2.0).abs() < 1e-12);
        // σzz is read from the matrix in 3D, whatever `zz` says.
        assert!((von_mises::<3>(&uniaxial, 7.0) - 2.0).abs() < 1e-12);
        let mut shear = Matrix::<2>::zeros();
        shear[(0, 1)] = 1.0;
        shear[(1, 0)] = 1.0;
        assert!((von_mises::<2>(&shear, 0.0) - 3f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn plane_strain_von_mises_counts_the_stress_across_the_plane() {
        // A hydrostatic state in plane strain has no von Mises stress only with σzz.
        let p = Matrix::<2>::identity() * -5.0;
        assert!(von_mises::<2>(&p, -5.0).abs() < 1e-12);
        assert!((von_mises::<2>(&p, 0.0) - 5.0).abs() < 1e-12);
        // Uniaxial σxx with σzz = ν σxx (plane strain, ν = 0.3): √(1 − ν + ν²) σxx.
        let mut s = Matrix::<2>::zeros();
        s[(0, 0)] = 10.0;
        let expected = 10.0 * (1.0f64 - 0.3 + 0.09).sqrt();
        assert!((von_mises::<2>(&s, 3.0) - expected).abs() < 1e-12);
    }
}
