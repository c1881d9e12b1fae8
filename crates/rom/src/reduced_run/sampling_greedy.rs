//! Mode-aware sample selection: particles picked one by one so that the projection's
//! normal matrix Σ JᵀJ (J = ∂g/∂q at a sample) is as well conditioned as it can be made,
//! a greedy D-optimal design (as DEIM and Q-DEIM pick interpolation points from the modes
//! rather than from the geometry). Farthest-point sampling spreads samples over the body but
//! can leave a mode all but unseen (a twist along a tower's axis, say), and the least squares
//! then blows that coordinate up.

use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;

/// `count` of the `eligible` particles picked greedily: each pick maximises det(A + JᵀJ) over
/// the particles left, A the normal matrix of the picks so far plus a small ridge, through
/// the determinant lemma det(A + JᵀJ) = det(A) det(I + J A⁻¹ Jᵀ). `jacobians` holds each
/// eligible particle's `dim × latent` Jacobian (row-major), in the order of `eligible`.
/// Returns particle indices, sorted.
pub fn greedy_samples(
    jacobians: &[f64],
    eligible: &[usize],
    dim: usize,
    latent: usize,
    count: usize,
) -> Vec<u32> {
    let n = eligible.len();
    let width = dim * latent;
    if n == 0 || count == 0 || jacobians.len() != n * width {
        return Vec::new();
    }
    // The ridge: a millionth of the mean diagonal of one particle's JᵀJ.
    let mean_diagonal = jacobians.iter().map(|v| v * v).sum::<f64>() / (n * latent) as f64;
    let ridge = 1e-6 * mean_diagonal.max(f64::MIN_POSITIVE);
    let mut normal = DMatrix::<f64>::identity(latent, latent) * ridge;
    let mut taken = vec![false; n];
    let mut chosen = Vec::with_capacity(count.min(n));
    while chosen.len() < count.min(n) {
        let Some(inverse) = normal.clone().cholesky().map(|c| c.inverse()) else {
            break;
        };
        let inverse = inverse.as_slice().to_vec();
        let best = jacobians
            .par_chunks_exact(width)
            .enumerate()
            .filter(|(i, _)| !taken[*i])
            .map(|(i, j)| (i, gain(j, &inverse, dim, latent)))
            .reduce(
                || (usize::MAX, f64::NEG_INFINITY),
                |a, b| {
                    if b.1 > a.1 || (b.1 == a.1 && b.0 < a.0) {
                        b
                    } else {
                        a
                    }
                },
            );
        if best.0 == usize::MAX {
            break;
        }
        taken[best.0] = true;
        chosen.push(eligible[best.0] as u32);
        let j = &jacobians[best.0 * width..(best.0 + 1) * width];
        for d in 0..dim {
            let row = &j[d * latent..(d + 1) * latent];
            for a in 0..latent {
                for b in 0..latent {
                    normal[(a, b)] += row[a] * row[b];
                }
            }
        }
    }
    chosen.sort_unstable();
    chosen
}

/// det(I + J A⁻¹ Jᵀ) for one particle's `dim × latent` Jacobian `j` (row-major) and A⁻¹
/// (`latent × latent`, column-major as nalgebra keeps it; symmetric, so either).
fn gain(j: &[f64], inverse: &[f64], dim: usize, latent: usize) -> f64 {
    if latent > 64 {
        return gain_large(j, inverse, dim, latent);
    }
    // B = A⁻¹ Jᵀ (latent × dim, on the stack), then M = J B (at most 3 × 3).
    let mut b = [0.0f64; 64 * 3];
    for d in 0..dim {
        let row = &j[d * latent..(d + 1) * latent];
        for a in 0..latent {
            let column = &inverse[a * latent..(a + 1) * latent];
            b[a * 3 + d] = column.iter().zip(row).map(|(x, y)| x * y).sum();
        }
    }
    let mut m = [[0.0f64; 3]; 3];
    for (r, m_row) in m.iter_mut().enumerate().take(dim) {
        let row = &j[r * latent..(r + 1) * latent];
        for (c, value) in m_row.iter_mut().enumerate().take(dim) {
            *value = (0..latent).map(|a| row[a] * b[a * 3 + c]).sum();
        }
    }
    determinant_plus_identity(&m, dim)
}

/// The same for more than 64 coordinates, with the product on the heap.
fn gain_large(j: &[f64], inverse: &[f64], dim: usize, latent: usize) -> f64 {
    let jm = DMatrix::from_row_slice(dim, latent, j);
    let inv = DMatrix::from_column_slice(latent, latent, inverse);
    let m = &jm * inv * jm.transpose();
    (DMatrix::identity(dim, dim) + m).determinant()
}

/// det(I + M) of the leading `dim × dim` block of `m`.
fn determinant_plus_identity(m: &[[f64; 3]; 3], dim: usize) -> f64 {
    let a = |r: usize, c: usize| m[r][c] + if r == c { 1.0 } else { 0.0 };
    match dim {
        1 => a(0, 0),
        2 => a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0),
        _ => {
            a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1))
                - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0))
                + a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0))
        }
    }
}

/// The condition number (largest over smallest eigenvalue) of the normal matrix Σ JᵀJ of
/// the `jacobians` (`dim × latent` each, row-major) of a run's samples: how strongly the
/// least-squares projection can amplify a misfit into one coordinate. Infinite when a
/// coordinate is unseen.
pub fn sample_condition(jacobians: &[f64], dim: usize, latent: usize) -> f64 {
    let mut normal = DMatrix::<f64>::zeros(latent, latent);
    for j in jacobians.chunks_exact(dim * latent) {
        for d in 0..dim {
            let row = &j[d * latent..(d + 1) * latent];
            for a in 0..latent {
                for b in 0..latent {
                    normal[(a, b)] += row[a] * row[b];
                }
            }
        }
    }
    let eigen = SymmetricEigen::new(normal).eigenvalues;
    let (lo, hi) = eigen.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| {
        (lo.min(v), hi.max(v))
    });
    if lo > 0.0 { hi / lo } else { f64::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn greedy_picks_see_every_coordinate() {
        // Four particles in 1D with two coordinates: two see only the first coordinate (one
        // strongly), two only the second. Two picks must take one of each, the strong first.
        let jacobians = [5.0, 0.0, 4.0, 0.0, 0.0, 1.0, 0.0, 0.5];
        let picks = greedy_samples(&jacobians, &[10, 11, 12, 13], 1, 2, 2);
        assert_eq!(picks, vec![10, 12]);
        assert!((sample_condition(&[5.0, 0.0, 0.0, 1.0], 1, 2) - 25.0).abs() < 1e-9);
        assert!(sample_condition(&[5.0, 0.0, 4.0, 0.0], 1, 2).is_infinite());
    }
}
