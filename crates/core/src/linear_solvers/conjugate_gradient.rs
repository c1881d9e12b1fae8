//! Jacobi-preconditioned conjugate gradients for a symmetric positive definite operator
//! given as a function (matrix-free), on the free unknowns only (shared by the physics
//! plugins: heat conduction, the underfill pressure): nodes where the inverse
//! diagonal is 0 (fixed temperature, or no material) keep their value.

/// How a solve ended.
#[derive(Clone, Copy, Debug)]
pub struct Solve {
    /// Iterations taken.
    pub iterations: u32,
    /// Whether the residual reached the tolerance.
    pub converged: bool,
}

/// Work vectors of the solve, one number per node each.
pub struct Work<'a> {
    /// Residual.
    pub r: &'a mut [f64],
    /// Preconditioned residual.
    pub z: &'a mut [f64],
    /// Search direction.
    pub p: &'a mut [f64],
    /// Operator times the search direction.
    pub ap: &'a mut [f64],
}

/// Solves `A x = b` for the free nodes (`inverse_diagonal[i] > 0`), starting from `x`,
/// with Jacobi preconditioning. Stops when ‖r‖ ≤ `tolerance`·‖b‖ on the free nodes.
pub fn solve(
    apply: impl FnMut(&[f64], &mut [f64]),
    inverse_diagonal: &[f64],
    b: &[f64],
    x: &mut [f64],
    work: Work<'_>,
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

/// [`solve`] with any symmetric positive definite preconditioner `precondition(r, z)`
/// (z = M⁻¹ r); `free[i] > 0` marks the free unknowns (the preconditioner must leave the
/// others at zero).
#[allow(clippy::too_many_arguments)]
pub fn solve_preconditioned(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]),
    free: &[f64],
    b: &[f64],
    x: &mut [f64],
    work: Work<'_>,
    tolerance: f64,
    max_iterations: u32,
) -> Solve {
    let Work { r, z, p, ap } = work;
    apply(x, ap);
    let mut b_norm2 = 0.0;
    for i in 0..x.len() {
        if free[i] > 0.0 {
            r[i] = b[i] - ap[i];
            b_norm2 += b[i] * b[i];
        } else {
            r[i] = 0.0;
        }
    }
    precondition(r, z);
    p.copy_from_slice(z);
    let target2 = tolerance * tolerance * b_norm2.max(1e-300);
    let mut rz: f64 = r.iter().zip(z.iter()).map(|(a, b)| a * b).sum();
    let mut r2: f64 = r.iter().map(|a| a * a).sum();
    let mut iterations = 0;
    while r2 > target2 && iterations < max_iterations {
        iterations += 1;
        apply(p, ap);
        let pap: f64 = p.iter().zip(ap.iter()).map(|(a, b)| a * b).sum();
        if pap <= 0.0 || !pap.is_finite() {
            break;
        }
        let alpha = rz / pap;
        r2 = 0.0;
        for i in 0..x.len() {
            if free[i] > 0.0 {
                x[i] += alpha * p[i];
                r[i] -= alpha * ap[i];
                r2 += r[i] * r[i];
            }
        }
        precondition(r, z);
        let rz_new: f64 = r.iter().zip(z.iter()).map(|(a, b)| a * b).sum();
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..x.len() {
            p[i] = z[i] + beta * p[i];
        }
    }
    Solve {
        iterations,
        converged: r2 <= target2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_small_laplacian_with_a_fixed_node() {
        // 1D: (2 I + L) x = b with x[0] fixed at 1; check the residual directly.
        let n = 20;
        let op = |x: &[f64], y: &mut [f64]| {
            for i in 0..n {
                let left = if i > 0 { x[i - 1] } else { 0.0 };
                let right = if i + 1 < n { x[i + 1] } else { 0.0 };
                y[i] = 4.0 * x[i] - left - right;
            }
        };
        let b: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut inv = vec![0.25; n];
        inv[0] = 0.0;
        let mut x = vec![0.0; n];
        x[0] = 1.0;
        let (mut r, mut z, mut p, mut ap) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let s = solve(
            op,
            &inv,
            &b,
            &mut x,
            Work {
                r: &mut r,
                z: &mut z,
                p: &mut p,
                ap: &mut ap,
            },
            1e-12,
            100,
        );
        assert!(s.converged);
        assert_eq!(x[0], 1.0);
        let mut y = vec![0.0; n];
        op(&x, &mut y);
        for i in 1..n {
            assert!((y[i] - b[i]).abs() < 1e-9, "{i}");
        }
    }
}
