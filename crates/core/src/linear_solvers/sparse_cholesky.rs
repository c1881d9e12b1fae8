//! Sparse Cholesky factorisation (faer's supernodal LLᵀ with a fill-reducing ordering) of
//! an assembled symmetric positive definite matrix, used as a preconditioner: the implicit
//! solver factors an elastic estimate of its tangent once per step and applies it in every
//! Krylov iteration.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat, Triplet};

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

/// The pattern of the last matrix [`SparseCholesky::factor_with_pattern`] factored, with
/// its value order and symbolic factorisation.
#[derive(Default)]
pub struct PatternCache {
    n: usize,
    pairs: Vec<Pair<usize, usize>>,
    plan: Option<(
        SymbolicSparseColMat<usize>,
        Argsort<usize>,
        SymbolicLlt<usize>,
    )>,
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

    /// Factors the n×n symmetric matrix whose lower-triangle entries are `values` at
    /// `pairs` (duplicates summed), reusing `cache`'s value order and symbolic factorisation
    /// (ordering, elimination tree) when the pairs are those of the last call: a sequence of
    /// matrices with one pattern (an implicit step's Newton iterations, steps whose particles
    /// stay in their cells) then pays only for the numeric factorisation.
    pub fn factor_with_pattern(
        n: usize,
        pairs: &[Pair<usize, usize>],
        values: &[f64],
        cache: &mut PatternCache,
    ) -> Result<Self, CholeskyError> {
        if cache.plan.is_none() || cache.n != n || cache.pairs != pairs {
            cache.plan = None;
            let (symbolic, order) = SymbolicSparseColMat::try_new_from_indices(n, n, pairs)
                .map_err(|e| CholeskyError::Assembly(format!("{e:?}")))?;
            let llt = SymbolicLlt::try_new(symbolic.as_ref(), faer::Side::Lower)
                .map_err(|e| CholeskyError::Factorisation(format!("{e:?}")))?;
            cache.n = n;
            cache.pairs.clear();
            cache.pairs.extend_from_slice(pairs);
            cache.plan = Some((symbolic, order, llt));
        }
        let Some((symbolic, order, symbolic_llt)) = &cache.plan else {
            unreachable!("the plan was made above");
        };
        let matrix = SparseColMat::new_from_argsort(symbolic.clone(), order, values)
            .map_err(|e| CholeskyError::Assembly(format!("{e:?}")))?;
        let llt =
            Llt::try_new_with_symbolic(symbolic_llt.clone(), matrix.as_ref(), faer::Side::Lower)
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

    #[test]
    fn a_cached_pattern_factors_new_values_and_a_new_pattern_replaces_it() {
        // Lower triangle of tridiag(-1, d, -1), with the diagonal entry given twice (summed).
        let n = 30;
        let system = |d: f64, bandwidth: usize| {
            let mut pairs = Vec::new();
            let mut values = Vec::new();
            for i in 0..n {
                pairs.extend([Pair::new(i, i), Pair::new(i, i)]);
                values.extend([0.5 * d, 0.5 * d]);
                for k in 1..=bandwidth.min(i) {
                    pairs.push(Pair::new(i, i - k));
                    values.push(-1.0 / k as f64);
                }
            }
            (pairs, values)
        };
        let check = |chol: &SparseCholesky, d: f64, bandwidth: usize| {
            let b: Vec<f64> = (0..n).map(|i| (i as f64).sin() + 1.0).collect();
            let mut x = b.clone();
            chol.solve_in_place(&mut x);
            for i in 0..n {
                let mut ax = d * x[i];
                for k in 1..=bandwidth {
                    if i >= k {
                        ax -= x[i - k] / k as f64;
                    }
                    if i + k < n {
                        ax -= x[i + k] / k as f64;
                    }
                }
                assert!((ax - b[i]).abs() < 1e-10, "row {i}: {ax} vs {}", b[i]);
            }
        };
        let mut cache = PatternCache::default();
        for (d, bandwidth) in [(4.0, 1), (9.0, 1), (6.0, 2), (3.0, 1)] {
            let (pairs, values) = system(d, bandwidth);
            let chol = SparseCholesky::factor_with_pattern(n, &pairs, &values, &mut cache)
                .expect("positive definite");
            check(&chol, d, bandwidth);
        }
    }
}
