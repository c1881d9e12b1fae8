//! Unit tests of the elastic laws on prescribed deformations.

use super::*;
use mpm_core::material::{ConstitutiveLaw, StateSlices, StressBatch};
use mpm_core::math::Matrix;

fn params() -> ElasticParameters {
    ElasticParameters {
        density: 1000.0,
        youngs_modulus: 1.0e6,
        poisson_ratio: 0.3,
    }
}

fn stress_of<L: ConstitutiveLaw, const D: usize>(law: &L, f: Matrix<D>) -> (Matrix<D>, f64) {
    let fs = [f];
    let mut stress = [Matrix::<D>::zeros()];
    let stats = law.update_stress(StressBatch {
        dt: 0.0,
        deformation_gradient: &fs,
        velocity_gradient: &[],
        volume0: &[1.0],
        stress: &mut stress,
        state: StateSlices {
            fields: std::array::from_fn(|_| &mut [][..]),
        },
        shared: [&[]; 4],
        plastic_work: &mut [],
    });
    (stress[0], stats.strain_energy)
}

#[test]
fn all_laws_agree_with_linear_elasticity_for_small_strain() {
    let eps = 1e-7;
    let f = Matrix::<3>::new(
        1.0 + eps,
        0.3 * eps,
        0.0,
        0.3 * eps,
        1.0 - 0.5 * eps,
        0.0,
        0.0,
        0.0,
        1.0,
    );
    let (lin, _) = stress_of(&LinearElastic::new(params()), f);
    let (nh, _) = stress_of(&NeoHookean::new(params()), f);
    let (fc, _) = stress_of(&FixedCorotated::new(params()), f);
    assert!((nh - lin).norm() < 1e-4 * lin.norm(), "{nh} vs {lin}");
    assert!((fc - lin).norm() < 1e-4 * lin.norm(), "{fc} vs {lin}");
}

#[test]
fn hyperelastic_laws_are_stress_free_under_rotation() {
    let (c, s) = (0.8f64.cos(), 0.8f64.sin());
    let rotation = Matrix::<2>::new(c, -s, s, c);
    for (stress, energy) in [
        stress_of(&NeoHookean::new(params()), rotation),
        stress_of(&FixedCorotated::new(params()), rotation),
    ] {
        assert!(stress.norm() < 1e-6, "{stress}");
        assert!(energy.abs() < 1e-9, "{energy}");
    }
}

#[test]
fn uniaxial_stretch_matches_closed_form() {
    // Fixed-corotated, F = diag(s, 1, 1): R = I, J = s.
    // σ_xx = [2μ (s − 1) s + λ (s − 1) s] / s, σ_yy = λ (s − 1).
    let p = params();
    let (lambda, mu) = mpm_core::material::lame_parameters(p.youngs_modulus, p.poisson_ratio);
    let stretch = 1.3;
    let f = Matrix::<3>::new(stretch, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    let (fc, _) = stress_of(&FixedCorotated::new(p), f);
    let sxx = (2.0 * mu * (stretch - 1.0) * stretch + lambda * (stretch - 1.0) * stretch) / stretch;
    assert!((fc[(0, 0)] - sxx).abs() < 1e-9 * sxx.abs());
    assert!((fc[(1, 1)] - lambda * (stretch - 1.0)).abs() < 1e-6);
    // Neo-Hookean: σ_xx = μ/J (s² − 1) + λ ln J / J.
    let (nh, _) = stress_of(&NeoHookean::new(p), f);
    let want = mu / stretch * (stretch * stretch - 1.0) + lambda * stretch.ln() / stretch;
    assert!((nh[(0, 0)] - want).abs() < 1e-9 * want.abs());
}
