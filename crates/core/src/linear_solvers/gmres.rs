//! Restarted GMRES(m), right-preconditioned by Jacobi, for a matrix-free operator on the
//! free unknowns (`inverse_diagonal[i] > 0`); fixed unknowns keep their value. Used where
//! the operator need not be symmetric (implicit mechanics with a non-symmetric tangent).

use super::conjugate_gradient::Solve;

/// Work space of a solve, allocated once and reused: `restart + 1` basis vectors of the
/// unknowns' length, and the small least-squares system.
pub struct GmresWork {
    basis: Vec<Vec<f64>>,
    hessenberg: Vec<f64>,
    cosines: Vec<f64>,
    sines: Vec<f64>,
    rhs: Vec<f64>,
    w: Vec<f64>,
    y: Vec<f64>,
    /// Preconditioned basis vectors M⁻¹ v_k (the solution is built from them).
    z_all: Vec<Vec<f64>>,
}

impl GmresWork {
    /// Space for `n` unknowns and a Krylov space of `restart` vectors between restarts.
    pub fn new(n: usize, restart: usize) -> Self {
        let m = restart.max(1);
        Self {
            basis: (0..=m).map(|_| vec![0.0; n]).collect(),
            hessenberg: vec![0.0; (m + 1) * m],
            cosines: vec![0.0; m],
            sines: vec![0.0; m],
            rhs: vec![0.0; m + 1],
            w: vec![0.0; n],
            y: vec![0.0; m],
            z_all: (0..m).map(|_| vec![0.0; n]).collect(),
        }
    }

    /// Resizes for `n` unknowns, keeping the allocations (an implicit step's unknowns change
    /// from step to step).
    pub fn resize(&mut self, n: usize) {
        for v in self.basis.iter_mut().chain(self.z_all.iter_mut()) {
            v.clear();
            v.resize(n, 0.0);
        }
        self.w.clear();
        self.w.resize(n, 0.0);
    }

    /// Unknowns this work space is sized for.
    pub fn len(&self) -> usize {
        self.w.len()
    }

    /// Whether it is sized for no unknowns.
    pub fn is_empty(&self) -> bool {
        self.w.is_empty()
    }

    /// Krylov vectors between restarts.
    pub fn restart(&self) -> usize {
        self.cosines.len()
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Solves `A x = b` for the free unknowns (`inverse_diagonal[i] > 0`), starting from `x`,
/// with Jacobi preconditioning; stops when the residual of the free unknowns is at most
/// `tolerance`·‖b‖ or after `max_iterations` operator applications.
pub fn solve(
    apply: impl FnMut(&[f64], &mut [f64]),
    inverse_diagonal: &[f64],
    b: &[f64],
    x: &mut [f64],
    work: &mut GmresWork,
    tolerance: f64,
    max_iterations: u32,
) -> Solve {
    solve_preconditioned(
        apply,
        super::jacobi(inverse_diagonal),
        inverse_diagonal,
        b,
        x,
        work,
        tolerance,
        max_iterations,
    )
}

/// [`solve`] with any right preconditioner `precondition(v, z)` (z = M⁻¹ v); `free[i] > 0`
/// marks the free unknowns (the preconditioner must leave the others at zero).
#[allow(clippy::too_many_arguments)]
pub fn solve_preconditioned(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]),
    free_mask: &[f64],
    b: &[f64],
    x: &mut [f64],
    work: &mut GmresWork,
    tolerance: f64,
    max_iterations: u32,
) -> Solve {
    let n = x.len();
    let m = work.restart();
    let free = |i: usize| free_mask[i] > 0.0;
    let b_norm = (0..n)
        .filter(|&i| free(i))
        .map(|i| b[i] * b[i])
        .sum::<f64>()
        .sqrt()
        .max(1e-300);
    let target = tolerance * b_norm;
    let mut iterations = 0u32;
    let GmresWork {
        basis,
        hessenberg,
        cosines,
        sines,
        rhs,
        w,
        y,
        z_all,
    } = work;
    let h = |i: usize, j: usize| i * m + j;
    loop {
        // r = b - A x on the free unknowns.
        apply(x, w);
        let r0 = &mut basis[0];
        for i in 0..n {
            r0[i] = if free(i) { b[i] - w[i] } else { 0.0 };
        }
        let beta = dot(r0, r0).sqrt();
        if beta <= target || !beta.is_finite() || iterations >= max_iterations {
            return Solve {
                iterations,
                converged: beta <= target,
            };
        }
        r0.iter_mut().for_each(|v| *v /= beta);
        rhs.fill(0.0);
        rhs[0] = beta;
        let mut k = 0;
        let mut residual = beta;
        while k < m && iterations < max_iterations && residual > target {
            iterations += 1;
            // w = A M⁻¹ v_k, then orthogonalise against the basis (modified Gram-Schmidt).
            let (head, tail) = basis.split_at_mut(k + 1);
            let next = &mut tail[0];
            precondition(&head[k], &mut z_all[k]);
            apply(&z_all[k], w);
            for (w, f) in w.iter_mut().zip(free_mask) {
                if *f <= 0.0 {
                    *w = 0.0;
                }
            }
            for (j, v) in head.iter().enumerate() {
                let c = dot(w, v);
                hessenberg[h(j, k)] = c;
                w.iter_mut().zip(v).for_each(|(a, b)| *a -= c * b);
            }
            let norm = dot(w, w).sqrt();
            hessenberg[h(k + 1, k)] = norm;
            if norm > 0.0 {
                next.iter_mut()
                    .zip(w.iter())
                    .for_each(|(a, b)| *a = b / norm);
            } else {
                next.fill(0.0);
            }
            // Apply the earlier rotations to the new column, then make a new one.
            for j in 0..k {
                let (a, b) = (hessenberg[h(j, k)], hessenberg[h(j + 1, k)]);
                hessenberg[h(j, k)] = cosines[j] * a + sines[j] * b;
                hessenberg[h(j + 1, k)] = -sines[j] * a + cosines[j] * b;
            }
            let (a, b) = (hessenberg[h(k, k)], hessenberg[h(k + 1, k)]);
            let r = a.hypot(b);
            let (c, s) = if r > 0.0 { (a / r, b / r) } else { (1.0, 0.0) };
            cosines[k] = c;
            sines[k] = s;
            hessenberg[h(k, k)] = r;
            hessenberg[h(k + 1, k)] = 0.0;
            rhs[k + 1] = -s * rhs[k];
            rhs[k] *= c;
            residual = rhs[k + 1].abs();
            k += 1;
            if norm == 0.0 || !residual.is_finite() {
                break;
            }
        }
        // x += M⁻¹ V y, with y from the triangular system.
        for i in (0..k).rev() {
            let mut sum = rhs[i];
            for j in i + 1..k {
                sum -= hessenberg[h(i, j)] * y[j];
            }
            let d = hessenberg[h(i, i)];
            y[i] = if d != 0.0 { sum / d } else { 0.0 };
        }
        for (j, z) in z_all.iter().take(k).enumerate() {
            x.iter_mut().zip(z).for_each(|(a, b)| *a += y[j] * b);
        }
        if !residual.is_finite() {
            return Solve {
                iterations,
                converged: false,
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_non_symmetric_system_with_a_fixed_unknown() {
        // 1D convection-diffusion (non-symmetric), x[0] fixed at 1.
        let n = 40;
        let op = |x: &[f64], y: &mut [f64]| {
            for i in 0..n {
                let left = if i > 0 { x[i - 1] } else { 0.0 };
                let right = if i + 1 < n { x[i + 1] } else { 0.0 };
                y[i] = 3.0 * x[i] - 1.5 * left - 0.5 * right;
            }
        };
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let mut inv = vec![1.0 / 3.0; n];
        inv[0] = 0.0;
        let mut x = vec![0.0; n];
        x[0] = 1.0;
        let mut work = GmresWork::new(n, 8);
        let s = solve(op, &inv, &b, &mut x, &mut work, 1e-12, 1000);
        assert!(s.converged, "{s:?}");
        assert_eq!(x[0], 1.0);
        let mut y = vec![0.0; n];
        op(&x, &mut y);
        for i in 1..n {
            assert!((y[i] - b[i]).abs() < 1e-9, "{i}: {} vs {}", y[i], b[i]);
        }
    }
}
