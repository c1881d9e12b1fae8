//! Small fixed-size linear algebra shared by the solver and material plugins.
//!
//! Everything is generic over the dimension `D` (2 or 3) so hot loops monomorphise; the
//! branches on `D` below are resolved at compile time.

use nalgebra::{SMatrix, SVector};

/// A point or vector in `D` dimensions.
pub type Vector<const D: usize> = SVector<f64, D>;
/// A `D`×`D` matrix (deformation gradient, stress, velocity gradient ...).
pub type Matrix<const D: usize> = SMatrix<f64, D, D>;

/// Determinant of a 2×2 or 3×3 matrix.
#[inline(always)]
pub fn determinant<const D: usize>(m: &Matrix<D>) -> f64 {
    match D {
        2 => m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)],
        3 => {
            m[(0, 0)] * (m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)])
                - m[(0, 1)] * (m[(1, 0)] * m[(2, 2)] - m[(1, 2)] * m[(2, 0)])
                + m[(0, 2)] * (m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)])
        }
        _ => unreachable!("only 2 and 3 dimensions are supported"),
    }
}

/// Cofactor matrix (so that `inverse = cofactor^T / det`, and `cofactor = det · F^{-T}`).
#[inline(always)]
pub fn cofactor<const D: usize>(m: &Matrix<D>) -> Matrix<D> {
    let mut c = Matrix::<D>::zeros();
    match D {
        2 => {
            c[(0, 0)] = m[(1, 1)];
            c[(0, 1)] = -m[(1, 0)];
            c[(1, 0)] = -m[(0, 1)];
            c[(1, 1)] = m[(0, 0)];
        }
        3 => {
            c[(0, 0)] = m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)];
            c[(0, 1)] = m[(1, 2)] * m[(2, 0)] - m[(1, 0)] * m[(2, 2)];
            c[(0, 2)] = m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)];
            c[(1, 0)] = m[(0, 2)] * m[(2, 1)] - m[(0, 1)] * m[(2, 2)];
            c[(1, 1)] = m[(0, 0)] * m[(2, 2)] - m[(0, 2)] * m[(2, 0)];
            c[(1, 2)] = m[(0, 1)] * m[(2, 0)] - m[(0, 0)] * m[(2, 1)];
            c[(2, 0)] = m[(0, 1)] * m[(1, 2)] - m[(0, 2)] * m[(1, 1)];
            c[(2, 1)] = m[(0, 2)] * m[(1, 0)] - m[(0, 0)] * m[(1, 2)];
            c[(2, 2)] = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)];
        }
        _ => unreachable!("only 2 and 3 dimensions are supported"),
    }
    c
}

/// Inverse of a 2×2 or 3×3 matrix, `None` when it is singular.
#[inline(always)]
pub fn inverse<const D: usize>(m: &Matrix<D>) -> Option<Matrix<D>> {
    let det = determinant(m);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    Some(cofactor(m).transpose() / det)
}

/// Rotation `R` of the polar decomposition `F = R·S` (S symmetric positive definite).
///
/// 2D uses the closed form; 3D uses Higham's scaled Newton iteration, which converges
/// quadratically and needs only 3×3 inverses (much cheaper than an SVD). Requires det F > 0,
/// which the solver guarantees (it stops a run at det F <= 0).
#[inline]
pub fn polar_rotation<const D: usize>(f: &Matrix<D>) -> Matrix<D> {
    match D {
        2 => {
            let a = f[(0, 0)] + f[(1, 1)];
            let b = f[(1, 0)] - f[(0, 1)];
            let norm = (a * a + b * b).sqrt();
            let mut r = Matrix::<D>::identity();
            if norm > 0.0 {
                let (c, s) = (a / norm, b / norm);
                r[(0, 0)] = c;
                r[(0, 1)] = -s;
                r[(1, 0)] = s;
                r[(1, 1)] = c;
            }
            r
        }
        3 => {
            let mut x = *f;
            for _ in 0..32 {
                let det = determinant(&x);
                if det.abs() < 1e-300 || !det.is_finite() {
                    break;
                }
                // X^{-T} = cofactor / det
                let inv_t = cofactor(&x) / det;
                let gamma = (inv_t.norm_squared() / x.norm_squared()).sqrt().sqrt();
                let next = (x * gamma + inv_t / gamma) * 0.5;
                let change = (next - x).norm_squared();
                x = next;
                // Quadratic convergence: a change below 1e-8 leaves an error near 1e-16.
                if change < 1e-16 * x.norm_squared() {
                    break;
                }
            }
            x
        }
        _ => unreachable!("only 2 and 3 dimensions are supported"),
    }
}

/// The 3×3 form of a `D`×`D` matrix with `diagonal` on the rest of the diagonal: 1 for a
/// plane-strain deformation gradient (F_zz = 1), 0 for its change, σ_zz for a stress.
#[inline]
pub fn embed3<const D: usize>(m: &Matrix<D>, diagonal: f64) -> Matrix<3> {
    let mut out = Matrix::<3>::identity() * diagonal;
    for r in 0..D {
        for c in 0..D {
            out[(r, c)] = m[(r, c)];
        }
    }
    out
}

/// The `D`×`D` top-left part of a 3×3 matrix (the inverse of [`embed3`]).
#[inline]
pub fn top_left<const D: usize>(m: &Matrix<3>) -> Matrix<D> {
    let mut out = Matrix::<D>::zeros();
    for r in 0..D {
        for c in 0..D {
            out[(r, c)] = m[(r, c)];
        }
    }
    out
}

/// Trace of a square matrix.
#[inline(always)]
pub fn trace<const D: usize>(m: &Matrix<D>) -> f64 {
    let mut t = 0.0;
    for i in 0..D {
        t += m[(i, i)];
    }
    t
}

/// Eigenvalues and eigenvectors (the columns of the returned matrix) of a symmetric 3×3
/// matrix, by cyclic Jacobi rotations; used for principal stretches and logarithmic strain.
///
/// Accurate to round-off for any symmetric input (it converges quadratically, typically in
/// 4 to 6 sweeps); the eigenvalues are not sorted.
pub fn symmetric_eigen3(m: &Matrix<3>) -> (Vector<3>, Matrix<3>) {
    let mut a = *m;
    let mut v = Matrix::<3>::identity();
    let scale = a.norm_squared();
    for _ in 0..32 {
        let off = a[(0, 1)] * a[(0, 1)] + a[(0, 2)] * a[(0, 2)] + a[(1, 2)] * a[(1, 2)];
        if off <= 1e-30 * scale || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            let apq = a[(p, q)];
            if apq == 0.0 {
                continue;
            }
            // Rotation angle that zeroes a[p][q] (Golub & Van Loan, sym.schur2).
            let tau = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
            let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
            let t = if tau == 0.0 { 1.0 } else { t };
            let c = 1.0 / (1.0 + t * t).sqrt();
            let s = t * c;
            for k in 0..3 {
                let (akp, akq) = (a[(k, p)], a[(k, q)]);
                a[(k, p)] = c * akp - s * akq;
                a[(k, q)] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[(p, k)], a[(q, k)]);
                a[(p, k)] = c * apk - s * aqk;
                a[(q, k)] = s * apk + c * aqk;
            }
            for k in 0..3 {
                let (vkp, vkq) = (v[(k, p)], v[(k, q)]);
                v[(k, p)] = c * vkp - s * vkq;
                v[(k, q)] = s * vkp + c * vkq;
            }
        }
    }
    (Vector::<3>::new(a[(0, 0)], a[(1, 1)], a[(2, 2)]), v)
}

/// Builds a `Vector<D>` from a slice of at least `D` numbers.
#[inline]
pub fn vector_from_slice<const D: usize>(s: &[f64]) -> Vector<D> {
    Vector::<D>::from_fn(|i, _| s[i])
}

/// Complementary error function, relative error below 1.2e-7 everywhere (Chebyshev fit of
/// Press et al., Numerical Recipes §6.2).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// Error function (see [`erfc`]).
pub fn erf(x: f64) -> f64 {
    1.0 - erfc(x)
}

/// The point in `[lo, hi]` where `below_root` turns from true to false, by 200 halvings of
/// the bracket (to round-off); the references' closed forms solve their equations with it.
/// The caller says which side of the root a point is on, so a closed form that loses
/// precision or overflows at one end of the bracket does not mislead it.
pub fn bisect(below_root: impl Fn(f64) -> bool, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if below_root(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3, Vector3};

    #[test]
    fn polar_3d_recovers_rotation() {
        let r = Rotation3::from_axis_angle(&Vector3::y_axis(), 0.7)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), -1.2);
        let s = Matrix3::new(1.3, 0.2, 0.1, 0.2, 0.8, -0.05, 0.1, -0.05, 1.1);
        let f = r.matrix() * s;
        let got = polar_rotation::<3>(&f);
        assert!((got - r.matrix()).norm() < 1e-13, "{got} vs {}", r.matrix());
        // Nearly a rotation (the common case in a step): still exact to round-off.
        let near = r.matrix()
            * (Matrix3::identity()
                + Matrix3::new(1e-4, 2e-5, 0.0, 2e-5, -3e-5, 1e-5, 0.0, 1e-5, 5e-5));
        let got = polar_rotation::<3>(&near);
        assert!((got - r.matrix()).norm() < 1e-13, "{got}");
    }

    #[test]
    fn symmetric_eigen_reconstructs_the_matrix() {
        for m in [
            Matrix3::new(2.0, 0.3, -0.1, 0.3, 1.0, 0.4, -0.1, 0.4, 0.5),
            Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 3.0),
            Matrix3::new(1.0, 1e-9, 0.0, 1e-9, 1.0, 0.0, 0.0, 0.0, 1.0),
            Matrix3::new(4.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        ] {
            let (values, vectors) = symmetric_eigen3(&m);
            let back = vectors * Matrix3::from_diagonal(&values) * vectors.transpose();
            assert!((back - m).norm() < 1e-13 * m.norm(), "{back} vs {m}");
            assert!((vectors.transpose() * vectors - Matrix3::identity()).norm() < 1e-13);
        }
    }

    #[test]
    fn polar_2d_recovers_rotation() {
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let r = Matrix::<2>::new(c, -s, s, c);
        let st = Matrix::<2>::new(1.5, 0.3, 0.3, 0.7);
        let got = polar_rotation::<2>(&(r * st));
        assert!((got - r).norm() < 1e-12);
    }

    #[test]
    fn inverse_and_determinant_agree_with_nalgebra() {
        let m = Matrix3::new(2.0, 0.5, 0.1, -0.3, 1.5, 0.2, 0.4, 0.0, 0.9);
        assert!((determinant::<3>(&m) - m.determinant()).abs() < 1e-12);
        let inv = inverse::<3>(&m).unwrap();
        assert!((inv * m - Matrix3::identity()).norm() < 1e-12);
        assert!(inverse::<3>(&Matrix3::zeros()).is_none());
    }

    #[test]
    fn erf_matches_tabulated_values() {
        // Abramowitz & Stegun table 7.1.
        for (x, v) in [
            (0.1, 0.112_462_916),
            (0.5, 0.520_499_878),
            (1.0, 0.842_700_793),
            (2.0, 0.995_322_265),
        ] {
            assert!((erf(x) - v).abs() < 2e-7, "{x}");
            assert!((erf(-x) + v).abs() < 2e-7, "{x}");
        }
    }
}
