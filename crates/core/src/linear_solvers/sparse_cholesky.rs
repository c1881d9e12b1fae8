//! Sparse Cholesky factorisation (faer's supernodal LLᵀ with a fill-reducing ordering) of
//! an assembled symmetric positive definite matrix, used as a preconditioner: the implicit
//! solver factors an elastic estimate of its tangent once per step and applies it in every
//! Krylov iteration. A preconditioner need not be exact, so it may be factored and applied
//! in single precision ([`Precision::Single`]): half the bytes of a factor whose fill is
//! most of a 3D step's time.

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

/// The arithmetic a factor is made and applied in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// f64 throughout.
    #[default]
    Double,
    /// The values rounded to f32, factored and solved in f32 (the right-hand side and the
    /// solution stay f64 outside); f64 from then on if an f32 factorisation fails.
    Single,
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
    /// The values rounded to f32 (reused).
    single: Vec<f32>,
    /// Whether an f32 factorisation failed where f64 succeeded (positive definite, but not
    /// at f32's precision): later ones asked for in single precision are made in f64.
    single_failed: bool,
}

impl PatternCache {
    /// Whether a single-precision factorisation failed and f64 took over.
    pub fn single_failed(&self) -> bool {
        self.single_failed
    }

    /// Makes later single-precision factorisations f64 (the caller found the f32 factor
    /// too coarse a preconditioner).
    pub fn give_up_single(&mut self) {
        self.single_failed = true;
    }
}

/// A factored n×n matrix.
pub struct SparseCholesky {
    llt: Factor,
    n: usize,
}

/// The factor in its precision.
enum Factor {
    Double(Llt<usize, f64>),
    Single(Llt<usize, f32>),
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
        Ok(Self {
            llt: Factor::Double(llt),
            n,
        })
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
        Self::factor_with_pattern_in(n, pairs, values, cache, Precision::Double)
    }

    /// [`SparseCholesky::factor_with_pattern`] in the given precision.
    pub fn factor_with_pattern_in(
        n: usize,
        pairs: &[Pair<usize, usize>],
        values: &[f64],
        cache: &mut PatternCache,
        precision: Precision,
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
        let mut single_failed = false;
        if precision == Precision::Single && !cache.single_failed {
            cache.single.clear();
            cache.single.extend(values.iter().map(|&v| v as f32));
            let matrix = SparseColMat::new_from_argsort(symbolic.clone(), order, &cache.single)
                .map_err(|e| CholeskyError::Assembly(format!("{e:?}")))?;
            match Llt::try_new_with_symbolic(
                symbolic_llt.clone(),
                matrix.as_ref(),
                faer::Side::Lower,
            ) {
                Ok(llt) => {
                    return Ok(Self {
                        llt: Factor::Single(llt),
                        n,
                    });
                }
                Err(_) => single_failed = true,
            }
        }
        let matrix = SparseColMat::new_from_argsort(symbolic.clone(), order, values)
            .map_err(|e| CholeskyError::Assembly(format!("{e:?}")))?;
        let llt =
            Llt::try_new_with_symbolic(symbolic_llt.clone(), matrix.as_ref(), faer::Side::Lower)
                .map_err(|e| CholeskyError::Factorisation(format!("{e:?}")))?;
        // Only a matrix f64 factors tells that f32 was too coarse (an indefinite one fails
        // in both).
        cache.single_failed |= single_failed;
        Ok(Self {
            llt: Factor::Double(llt),
            n,
        })
    }

    /// Unknowns of the factored matrix.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the matrix has no unknowns.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Whether the factor is in single precision.
    pub fn is_single(&self) -> bool {
        matches!(self.llt, Factor::Single(_))
    }

    /// Overwrites `x` (the right-hand side) with the solution.
    pub fn solve_in_place(&self, x: &mut [f64]) {
        let n = self.n;
        match &self.llt {
            Factor::Double(llt) => {
                llt.solve_in_place(faer::MatMut::from_column_major_slice_mut(x, n, 1));
            }
            Factor::Single(llt) => {
                let mut single: Vec<f32> = x.iter().map(|&v| v as f32).collect();
                llt.solve_in_place(faer::MatMut::from_column_major_slice_mut(&mut single, n, 1));
                for (x, s) in x.iter_mut().zip(&single) {
                    *x = f64::from(*s);
                }
            }
        }
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

    #[test]
    fn a_single_precision_factor_solves_to_f32_accuracy_and_falls_back_where_f32_fails() {
        // tridiag(-1, 4, -1): well conditioned, so the f32 solve is good to about 1e-7.
        let n = 40;
        let mut pairs = Vec::new();
        let mut values = Vec::new();
        for i in 0..n {
            pairs.push(Pair::new(i, i));
            values.push(4.0);
            if i > 0 {
                pairs.push(Pair::new(i, i - 1));
                values.push(-1.0);
            }
        }
        let single = |n: usize, pairs: &[Pair<usize, usize>], values: &[f64]| {
            let mut cache = PatternCache::default();
            let chol = SparseCholesky::factor_with_pattern_in(
                n,
                pairs,
                values,
                &mut cache,
                Precision::Single,
            );
            (chol.expect("f32 or f64 factors it"), cache.single_failed())
        };
        let (chol, failed) = single(n, &pairs, &values);
        assert!(matches!(chol.llt, Factor::Single(_)));
        let b: Vec<f64> = (0..n).map(|i| (i as f64).cos() + 2.0).collect();
        let mut x = b.clone();
        chol.solve_in_place(&mut x);
        for i in 0..n {
            let left = if i > 0 { x[i - 1] } else { 0.0 };
            let right = if i + 1 < n { x[i + 1] } else { 0.0 };
            let error = (4.0 * x[i] - left - right - b[i]).abs() / b[i].abs();
            assert!(error < 1e-5, "row {i}: relative residual {error}");
        }
        assert!(!failed);
        // [[1, 1 − 1e-10], [1 − 1e-10, 1]]: positive definite, singular once rounded to f32.
        let pairs = [Pair::new(0, 0), Pair::new(1, 0), Pair::new(1, 1)];
        let values = [1.0, 1.0 - 1e-10, 1.0];
        let (chol, failed) = single(2, &pairs, &values);
        assert!(failed);
        assert!(matches!(chol.llt, Factor::Double(_)));
        let mut x = vec![1.0, -1.0];
        chol.solve_in_place(&mut x);
        // A (1, −1)ᵀ = 1e-10 (1, −1)ᵀ.
        assert!((x[0] - 1e10).abs() < 1e-3 * 1e10 && (x[1] + 1e10).abs() < 1e-3 * 1e10);
    }
}
