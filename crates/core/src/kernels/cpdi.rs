//! CPDI (convected particle domain interpolation; Sadeghirad, Brannon & Burghardt 2011 and
//! CPDI2, 2013): each particle is a parallelogram (2D) or parallelepiped (3D) domain that
//! deforms with its F, and its weight on a node is the linear tent function averaged over
//! that domain through the domain's corners. A stretched particle keeps reaching the nodes
//! its domain covers, so a body stretched to several times its length stays whole.
//!
//! For a domain with half vectors r₁…r_D (the columns of J = F·h·I, h the particle's half
//! width) and corners ξ_α = x + J s_α (s_α ∈ {−1, 1}^D), the domain average of the tent
//! function N_i, interpolated multilinearly from its corner values, is
//! w_i = 2^−D Σ_α N_i(ξ_α), and its domain-averaged gradient is ∇w_i = J⁻ᵀ 2^−D Σ_α N_i(ξ_α) s_α.
//! For a parallelogram these are CPDI2's quadrilateral formulas too (its corner weights are
//! then all 2^−D). The weights are a partition of unity with linear reproduction, and
//! Σ_i x_i ⊗ ∇w_i = I.

use super::{AxisWeights, Kernel, Linear};
use crate::math::{Matrix, Vector, inverse};

/// The CPDI kernel. [`crate::kernels::Kernel`]'s point weights are the linear tent's, for the
/// operators that interpolate at particle centres (binning, escape checks); the CPDI
/// mechanics step (`solver::cpdi`) uses [`domain_weights`]. Carries each particle's half
/// width so its domain can be built.
#[derive(Clone, Copy, Debug, Default)]
pub struct Cpdi;

impl Kernel for Cpdi {
    const SPAN: usize = 2;
    const NAME: &'static str = "cpdi2";
    const APIC_INERTIA: Option<f64> = None;
    const USES_PARTICLE_SIZE: bool = true;
    const DOMAINS: bool = true;

    #[inline(always)]
    fn weights(xi: f64, _half_size: f64) -> AxisWeights {
        Linear::weights(xi, 0.0)
    }
}

/// The box of grid nodes (lowest node, nodes per axis; unused axes 0 and 1) that a domain
/// centred at grid coordinate `centre` with half vectors `half` (columns, in cells) reaches.
#[inline]
pub fn domain_box<const D: usize>(
    centre: &Vector<D>,
    half: &Matrix<D>,
) -> ([isize; 3], [usize; 3]) {
    let mut low = [0isize; 3];
    let mut count = [1usize; 3];
    for d in 0..D {
        // Padded by a rounding margin so every corner's stencil lies in the box.
        let reach: f64 = (0..D).map(|e| half[(d, e)].abs()).sum::<f64>() * (1.0 + 1e-12) + 1e-12;
        let lo = super::fast_floor(centre[d] - reach);
        let hi = super::fast_floor(centre[d] + reach) + 1.0;
        low[d] = lo as isize;
        count[d] = (hi - lo) as usize + 1;
    }
    (low, count)
}

/// Fills `weight` and `gradient` (grid units: divide by the cell size) for every node of the
/// domain's box ([`domain_box`]), in box order (last axis fastest). Both slices hold at
/// least the box's node count; entries past it are left alone.
pub fn domain_weights<const D: usize>(
    centre: &Vector<D>,
    half: &Matrix<D>,
    low: [isize; 3],
    count: [usize; 3],
    weight: &mut [f64],
    gradient: &mut [Vector<D>],
) {
    let nodes = count[0] * count[1] * count[2];
    weight[..nodes].fill(0.0);
    gradient[..nodes].fill(Vector::<D>::zeros());
    let corners = 1usize << D;
    let scale = 1.0 / corners as f64;
    // Each corner's share of the gradient, J⁻ᵀ s 2^−D (zero for a collapsed domain).
    let inverse_transpose = inverse(half)
        .map(|m| m.transpose() * scale)
        .unwrap_or_else(Matrix::<D>::zeros);
    for a in 0..corners {
        let mut sign = Vector::<D>::zeros();
        for d in 0..D {
            sign[d] = if a >> d & 1 == 1 { 1.0 } else { -1.0 };
        }
        let corner = centre + half * sign;
        let share = inverse_transpose * sign;
        // The corner's linear stencil: 2 nodes per used axis, offsets into the box.
        let mut base = [0usize; 3];
        let mut tent = [[1.0f64, 0.0]; 3];
        for d in 0..D {
            let lo = super::fast_floor(corner[d]);
            let t = corner[d] - lo;
            base[d] = (lo as isize - low[d]) as usize;
            tent[d] = [1.0 - t, t];
        }
        let span = |d: usize| if d < D { 2 } else { 1 };
        for i in 0..span(0) {
            for j in 0..span(1) {
                let e0 = ((base[0] + i) * count[1] + base[1] + j) * count[2] + base[2];
                let wij = tent[0][i] * tent[1][j];
                for k in 0..span(2) {
                    let n = wij * tent[2][k];
                    weight[e0 + k] += n * scale;
                    gradient[e0 + k] += share * n;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The node of box entry `e` in grid coordinates.
    fn node<const D: usize>(low: [isize; 3], count: [usize; 3], e: usize) -> Vector<D> {
        let ijk = [
            e / (count[1] * count[2]),
            e / count[2] % count[1],
            e % count[2],
        ];
        Vector::<D>::from_fn(|d, _| (low[d] + ijk[d] as isize) as f64)
    }

    fn check<const D: usize>(centre: Vector<D>, half: Matrix<D>) {
        let (low, count) = domain_box(&centre, &half);
        let nodes = count[0] * count[1] * count[2];
        let mut w = vec![0.0; nodes];
        let mut g = vec![Vector::<D>::zeros(); nodes];
        domain_weights(&centre, &half, low, count, &mut w, &mut g);
        let sum: f64 = w.iter().sum();
        assert!((sum - 1.0).abs() < 1e-12, "sum {sum}");
        let (mut first, mut gsum) = (Vector::<D>::zeros(), Vector::<D>::zeros());
        let mut moment = Matrix::<D>::zeros();
        for e in 0..nodes {
            assert!(w[e] >= -1e-15);
            let x = node::<D>(low, count, e);
            first += x * w[e];
            gsum += g[e];
            moment += x * g[e].transpose();
        }
        assert!((first - centre).norm() < 1e-12, "first moment {first}");
        assert!(gsum.norm() < 1e-12, "gradient sum {gsum}");
        assert!(
            (moment - Matrix::<D>::identity()).norm() < 1e-12,
            "Σ x ⊗ ∇w = {moment}"
        );
    }

    /// Partition of unity, linear reproduction and a consistent gradient for undeformed,
    /// stretched, sheared and rotated domains in 2D and 3D.
    #[test]
    fn domain_weights_reproduce_linear_fields() {
        let c2 = Vector::<2>::new(5.3, 7.8);
        check(c2, Matrix::<2>::identity() * 0.25);
        check(c2, Matrix::<2>::new(1.4, 0.0, 0.0, 0.25));
        check(c2, Matrix::<2>::new(0.25, 0.6, 0.0, 0.25));
        let (s, c) = 0.7f64.sin_cos();
        check(c2, Matrix::<2>::new(c, -s, s, c) * 0.9);
        let c3 = Vector::<3>::new(4.1, 5.5, 6.95);
        check(c3, Matrix::<3>::identity() * 0.25);
        check(
            c3,
            Matrix::<3>::new(0.25, 0.3, 0.0, 0.0, 0.25, -0.2, 0.1, 0.0, 1.2),
        );
    }

    /// A vanishing domain is the linear kernel.
    #[test]
    fn a_point_domain_is_the_linear_kernel() {
        let centre = Vector::<2>::new(3.3, 4.6);
        let half = Matrix::<2>::identity() * 1e-9;
        let (low, count) = domain_box(&centre, &half);
        let mut w = vec![0.0; 9];
        let mut g = vec![Vector::<2>::zeros(); 9];
        domain_weights(&centre, &half, low, count, &mut w, &mut g);
        for (e, &we) in w.iter().enumerate().take(count[0] * count[1]) {
            let x = node::<2>(low, count, e);
            let tent = (1.0 - (centre[0] - x[0]).abs()).max(0.0)
                * (1.0 - (centre[1] - x[1]).abs()).max(0.0);
            assert!((we - tent).abs() < 1e-8, "{e}: {we} vs {tent}");
        }
    }
}
