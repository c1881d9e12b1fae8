//! A banded matrix with its LU factorisation by partial pivoting (the scheme of LAPACK's
//! `gbtf2`), for the coupled velocity–pressure system of a cross-section: numbered along
//! the section's long axis, its unknowns couple only within a few columns of cells, so
//! the band is narrow and a direct solve costs O(n·bandwidth²).

/// An n×n matrix with `lower` sub- and `upper` super-diagonals, stored by columns with
/// room for the fill-in of row interchanges.
pub(crate) struct BandedMatrix {
    n: usize,
    lower: usize,
    upper: usize,
    /// Rows of storage per column: 2·lower + upper + 1.
    rows: usize,
    values: Vec<f64>,
    pivots: Vec<usize>,
}

/// The factorisation met a zero pivot: the system is singular.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Singular {
    /// Column of the zero pivot.
    pub column: usize,
}

impl BandedMatrix {
    /// An empty matrix; [`Self::reset`] sizes it.
    pub fn new() -> Self {
        Self {
            n: 0,
            lower: 0,
            upper: 0,
            rows: 1,
            values: Vec::new(),
            pivots: Vec::new(),
        }
    }

    /// Zeroes the matrix at size `n` with the given bandwidths (keeps its allocation when
    /// it is large enough).
    pub fn reset(&mut self, n: usize, lower: usize, upper: usize) {
        self.n = n;
        self.lower = lower;
        self.upper = upper;
        self.rows = 2 * lower + upper + 1;
        let len = self.rows * n;
        self.values.clear();
        self.values.resize(len, 0.0);
        self.pivots.clear();
        self.pivots.resize(n, 0);
    }

    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> usize {
        j * self.rows + self.lower + self.upper + i - j
    }

    /// Adds `v` to entry (i, j), which must lie inside the band.
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        debug_assert!(i <= j + self.lower && j <= i + self.upper);
        let k = self.at(i, j);
        self.values[k] += v;
    }

    /// Factorises in place (PA = LU).
    pub fn factorise(&mut self) -> Result<(), Singular> {
        let (n, kl, ku) = (self.n, self.lower, self.upper);
        let mut last = 0usize;
        for j in 0..n {
            let below = kl.min(n - 1 - j);
            let mut best = 0;
            let mut best_value = self.values[self.at(j, j)].abs();
            for t in 1..=below {
                let v = self.values[self.at(j + t, j)].abs();
                if v > best_value {
                    best = t;
                    best_value = v;
                }
            }
            self.pivots[j] = j + best;
            if best_value == 0.0 || !best_value.is_finite() {
                return Err(Singular { column: j });
            }
            last = last.max((j + ku + best).min(n - 1));
            if best != 0 {
                for col in j..=last {
                    let (a, b) = (self.at(j, col), self.at(j + best, col));
                    self.values.swap(a, b);
                }
            }
            let pivot = self.values[self.at(j, j)];
            for t in 1..=below {
                let k = self.at(j + t, j);
                self.values[k] /= pivot;
            }
            for col in j + 1..=last {
                let a = self.values[self.at(j, col)];
                if a == 0.0 {
                    continue;
                }
                for t in 1..=below {
                    let l = self.values[self.at(j + t, j)];
                    let k = self.at(j + t, col);
                    self.values[k] -= l * a;
                }
            }
        }
        Ok(())
    }

    /// Solves A x = b in place with the factors.
    pub fn solve(&self, b: &mut [f64]) {
        let (n, kl) = (self.n, self.lower);
        for j in 0..n {
            let l = self.pivots[j];
            if l != j {
                b.swap(l, j);
            }
            let below = kl.min(n - 1 - j);
            let bj = b[j];
            for t in 1..=below {
                b[j + t] -= self.values[self.at(j + t, j)] * bj;
            }
        }
        let reach = self.lower + self.upper;
        for j in (0..n).rev() {
            b[j] /= self.values[self.at(j, j)];
            let bj = b[j];
            let first = j.saturating_sub(reach);
            for (i, bi) in b[first..j].iter_mut().enumerate() {
                *bi -= self.values[self.at(first + i, j)] * bj;
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // dense reference elimination reads clearest by index
mod tests {
    use super::*;

    /// Dense Gaussian elimination with partial pivoting, for comparison.
    fn dense_solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
        let n = b.len();
        for j in 0..n {
            let p = (j..n)
                .max_by(|&x, &y| a[x][j].abs().total_cmp(&a[y][j].abs()))
                .unwrap();
            a.swap(j, p);
            b.swap(j, p);
            for i in j + 1..n {
                let l = a[i][j] / a[j][j];
                for k in j..n {
                    a[i][k] -= l * a[j][k];
                }
                b[i] -= l * b[j];
            }
        }
        let mut x = vec![0.0; n];
        for j in (0..n).rev() {
            let s: f64 = (j + 1..n).map(|k| a[j][k] * x[k]).sum();
            x[j] = (b[j] - s) / a[j][j];
        }
        x
    }

    #[test]
    fn matches_dense_elimination_on_a_saddle_point_band() {
        // A band with zero diagonal entries (like a velocity-pressure system), which needs
        // row interchanges.
        let (n, kl, ku) = (40, 3, 2);
        let mut seed = 12345u64;
        let mut rand = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut dense = vec![vec![0.0; n]; n];
        let mut band = BandedMatrix::new();
        band.reset(n, kl, ku);
        for i in 0..n {
            for j in i.saturating_sub(kl)..(i + ku + 1).min(n) {
                let v = if i == j && i % 3 == 2 { 0.0 } else { rand() };
                dense[i][j] = v;
                band.add(i, j, v);
            }
        }
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let expected = dense_solve(dense, b.clone());
        band.factorise().expect("regular");
        let mut x = b;
        band.solve(&mut x);
        for i in 0..n {
            assert!(
                (x[i] - expected[i]).abs() < 1e-8 * (1.0 + expected[i].abs()),
                "{i}"
            );
        }
    }

    #[test]
    fn a_zero_column_is_reported_singular() {
        let mut band = BandedMatrix::new();
        band.reset(3, 1, 1);
        band.add(0, 0, 1.0);
        band.add(2, 2, 1.0);
        assert_eq!(band.factorise(), Err(Singular { column: 1 }));
    }
}
