//! Sparse Cholesky factorisation (faer's supernodal LLᵀ with a fill-reducing ordering) of
//! an assembled symmetric positive definite matrix, used as a preconditioner: the implicit
//! solver factors an elastic estimate of its tangent once per step and applies it in every
//! Krylov iteration.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::sparse::{SparseColMat, Triplet};

/// Why a factorisation failed.
#[derive(Debug, thiserror::Error)]
pub enum CholeskyError {
    /// The triplets do not describe an n×n matrix, or memory ran out.
    #[error("could not assemble the sparse matrix: {0}")]
    Assembly(String),
    /// The matrix is not positive definite (or memory ran out in the factorisation).
    #[error("the matrix could not be factored: {0}")]
    Factorisation(String),
}

/// A factored n×n matrix.
pub struct SparseCholesky {
    llt: Llt<usize, f64>,
    n: usize,
}

impl SparseCholesky {
    /// Factors the n×n symmetric matrix given by `(row, column, value)` triplets (duplicates
    /// are summed; only the lower triangle is read).
    pub fn factor(
        n: usize,
        triplets: &[Triplet<usize, usize, f64>],
    ) -> Result<Self, CholeskyError> {
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, triplets)
            .map_err(|e| CholeskyError::Assembly(format!("{e:?}")))?;
        let llt = matrix
            .sp_cholesky(faer::Side::Lower)
            .map_err(|e| CholeskyError::Factorisation(format!("{e:?}")))?;
        Ok(Self { llt, n })
    }

    /// Unknowns of the factored matrix.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the matrix has no unknowns.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Overwrites `x` (the right-hand side) with the solution.
    pub fn solve_in_place(&self, x: &mut [f64]) {
        let n = self.n;
        self.llt
            .solve_in_place(faer::MatMut::from_column_major_slice_mut(x, n, 1));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_tridiagonal_system() {
        let n = 50;
        let mut t = Vec::new();
        for i in 0..n {
            t.push(Triplet::new(i, i, 4.0));
            if i > 0 {
                t.push(Triplet::new(i, i - 1, -1.0));
                t.push(Triplet::new(i - 1, i, -1.0));
            }
        }
        let chol = SparseCholesky::factor(n, &t).expect("positive definite");
        let b: Vec<f64> = (0..n).map(|i| (i as f64).cos()).collect();
        let mut x = b.clone();
        chol.solve_in_place(&mut x);
        for i in 0..n {
            let left = if i > 0 { x[i - 1] } else { 0.0 };
            let right = if i + 1 < n { x[i + 1] } else { 0.0 };
            assert!((4.0 * x[i] - left - right - b[i]).abs() < 1e-12);
        }
    }
}
