//! The project's one place for linear solvers: matrix-free Krylov methods on the free
//! unknowns of a grid (the operator is a function, never an assembled matrix).
//!
//! - [`conjugate_gradient`]: Jacobi-preconditioned CG for symmetric positive definite
//!   operators (heat conduction, the underfill pressure, implicit mechanics with a
//!   symmetric tangent).
//! - [`gmres`]: restarted GMRES, right-preconditioned by Jacobi, for operators that are not
//!   symmetric (implicit mechanics with plasticity, or a finite-difference tangent).
//!
//! - [`sparse_cholesky`]: a sparse direct factorisation (faer), the implicit solver's
//!   preconditioner.
//!
//! The Krylov methods take the preconditioner as an inverse diagonal whose zero entries mark fixed
//! unknowns, which keep their value.

pub mod conjugate_gradient;
pub mod gmres;
pub mod sparse_cholesky;

/// Jacobi preconditioning z = D⁻¹ r with the inverse diagonal (zero for fixed unknowns).
pub fn jacobi(inverse_diagonal: &[f64]) -> impl Fn(&[f64], &mut [f64]) + '_ {
    move |r, z| {
        for ((z, r), d) in z.iter_mut().zip(r).zip(inverse_diagonal) {
            *z = r * d;
        }
    }
}
