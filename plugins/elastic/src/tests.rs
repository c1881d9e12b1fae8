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
    update_of(law, f, &[], &mut [])
}

/// One particle's update at `f` with `stretch` across the plane (empty: 1), σzz written to
/// `zz` (empty: not asked); the stress and the strain energy.
fn update_of<L: ConstitutiveLaw, const D: usize>(
    law: &L,
    f: Matrix<D>,
    stretch: &[f64],
    zz: &mut [f64],
) -> (Matrix<D>, f64) {
    let fs = [f];
    let mut stress = [Matrix::<D>::zeros()];
    let stats = law.update_stress(StressBatch {
        out_of_plane_stretch: stretch,
        out_of_plane_stress: zz,
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

/// The analytic stress derivative of `law` at `f` along `df`, against a central difference
/// of its own stress update.
fn derivative_error<L: ConstitutiveLaw, const D: usize>(
    law: &L,
    f: Matrix<D>,
    df: Matrix<D>,
) -> f64 {
    use mpm_core::material::{StateView, TangentBatch};
    assert!(law.has_stress_derivative());
    let (stress, _) = stress_of(law, f);
    let mut analytic = [Matrix::<D>::zeros()];
    law.stress_derivative(TangentBatch {
        out_of_plane_stretch: &[],
        dt: 0.0,
        deformation_gradient: &[f],
        direction: &[df],
        stress: &[stress],
        state: StateView { fields: [&[]; 8] },
        shared: [&[]; 4],
        stress_change: &mut analytic,
    });
    let h = 1e-6;
    let (plus, _) = stress_of(law, f + df * h);
    let (minus, _) = stress_of(law, f - df * h);
    let numeric = (plus - minus) / (2.0 * h);
    (analytic[0] - numeric).norm() / numeric.norm()
}

#[test]
fn analytic_stress_derivatives_match_differences_of_the_update() {
    // A finite stretch with shear and rotation, and a direction that changes every entry.
    let f3 = Matrix::<3>::new(1.2, 0.1, -0.05, 0.02, 0.9, 0.1, 0.03, -0.04, 1.05);
    let d3 = Matrix::<3>::new(0.3, -0.2, 0.1, 0.05, 0.4, -0.1, 0.2, 0.1, -0.3);
    let f2 = Matrix::<2>::new(1.1, 0.2, -0.1, 0.95);
    let d2 = Matrix::<2>::new(-0.2, 0.3, 0.1, 0.4);
    for error in [
        derivative_error(&NeoHookean::new(params()), f3, d3),
        derivative_error(&NeoHookean::new(params()), f2, d2),
        derivative_error(&LinearElastic::new(params()), f3, d3),
        derivative_error(&LinearElastic::new(params()), f2, d2),
    ] {
        assert!(error < 1e-7, "relative error {error}");
    }
}

/// The 2D update with a stretch across the plane: in-plane stress, σzz and energy.
fn plane_strain_stress_of<L: ConstitutiveLaw>(
    law: &L,
    f: Matrix<2>,
    stretch: f64,
) -> (Matrix<2>, f64, f64) {
    let mut zz = [f64::NAN];
    let (stress, energy) = update_of(law, f, &[stretch], &mut zz);
    (stress, zz[0], energy)
}

/// Asserts that `law`'s 2D update at `f` with stretch `s` across the plane is its 3D update
/// at [[f, 0], [0, s]]: in-plane stress, σzz and energy, to round-off.
fn assert_plane_strain_is_3d<L: ConstitutiveLaw>(name: &str, law: &L, f: Matrix<2>, s: f64) {
    let (in_plane, zz, energy) = plane_strain_stress_of(law, f, s);
    let (full, energy3) = stress_of(law, mpm_core::math::embed3(&f, s));
    let scale = full.norm();
    for r in 0..2 {
        for c in 0..2 {
            assert!(
                (in_plane[(r, c)] - full[(r, c)]).abs() < 1e-12 * scale,
                "{name} s={s}: σ{r}{c} {} against 3D {}",
                in_plane[(r, c)],
                full[(r, c)]
            );
        }
    }
    assert!(
        (zz - full[(2, 2)]).abs() < 1e-12 * scale,
        "{name} s={s}: σzz {zz} against {}",
        full[(2, 2)]
    );
    assert!(
        (energy - energy3).abs() < 1e-12 * energy3.abs().max(1.0),
        "{name} s={s}: energy {energy} against {energy3}"
    );
}

#[test]
fn a_2d_particle_is_the_3d_law_with_its_stretch_across_the_plane() {
    // Finite shear and stretch in the plane, the third direction shrunk as a cooled
    // (free-strain) particle's is, or stretched.
    let f = Matrix::<2>::new(1.08, 0.21, -0.05, 0.93);
    for s in [1.0, 0.985, 1.02] {
        assert_plane_strain_is_3d("linear", &LinearElastic::new(params()), f, s);
        assert_plane_strain_is_3d("neo-Hookean", &NeoHookean::new(params()), f, s);
        assert_plane_strain_is_3d("fixed-corotated", &FixedCorotated::new(params()), f, s);
    }
}

#[test]
fn analytic_derivatives_hold_the_stretch_across_the_plane() {
    use mpm_core::material::{StateView, TangentBatch};
    let f = Matrix::<2>::new(1.1, 0.2, -0.1, 0.95);
    let df = Matrix::<2>::new(-0.2, 0.3, 0.1, 0.4);
    let s = 0.97;
    let laws: [&dyn Fn(Matrix<2>) -> Matrix<2>; 2] = [
        &|f| plane_strain_stress_of(&NeoHookean::new(params()), f, s).0,
        &|f| plane_strain_stress_of(&LinearElastic::new(params()), f, s).0,
    ];
    for (k, stress) in laws.iter().enumerate() {
        let mut analytic = [Matrix::<2>::zeros()];
        let batch = TangentBatch {
            out_of_plane_stretch: &[s],
            dt: 0.0,
            deformation_gradient: &[f],
            direction: &[df],
            stress: &[stress(f)],
            state: StateView { fields: [&[]; 8] },
            shared: [&[]; 4],
            stress_change: &mut analytic,
        };
        if k == 0 {
            NeoHookean::new(params()).stress_derivative(batch);
        } else {
            LinearElastic::new(params()).stress_derivative(batch);
        }
        let h = 1e-6;
        let numeric = (stress(f + df * h) - stress(f - df * h)) / (2.0 * h);
        let error = (analytic[0] - numeric).norm() / numeric.norm();
        assert!(error < 1e-7, "law {k}: relative error {error}");
    }
}
