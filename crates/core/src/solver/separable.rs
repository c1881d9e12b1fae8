//! P2G and G2P of one particle that use the tensor-product form of the kernels: a node's
//! weight is wx[a]·wy[b]·wz[c], so sums over the stencil are taken along z, then y, then x,
//! and the terms that are linear in the node offset (the APIC affine momentum, the APIC
//! matrix B) are built from running sums instead of a 3×3 product at every node.
//!
//! Same arithmetic as the plain loop over [`Stencil::for_each`] up to rounding; a
//! quarter to a third of its floating-point work per particle (the cube drop's P2G and G2P
//! were two thirds of its step).

use super::parallel::SharedSlice;
use super::stencil::Stencil;
use crate::kernels::Kernel;
use crate::math::{Matrix, Vector};

/// What one particle scatters: momentum `mv + q·(node − x_p)` (offsets in cells) times the
/// weight, plus `s·∇w` (grid units) when there is a stress term, plus `m·w` when `mass`.
pub(crate) struct Scatter<const D: usize> {
    /// Mass, scattered only when `Some`.
    pub mass: Option<f64>,
    /// Momentum of the particle (gravity folded in).
    pub mv: Vector<D>,
    /// Affine momentum per cell of offset.
    pub q: Matrix<D>,
    /// Force per unit weight gradient (grid units) times the step, when the standard force
    /// is folded into the momentum.
    pub s: Option<Matrix<D>>,
}

/// Adds one particle's scatter to the grid arrays.
///
/// # Safety
/// The caller has exclusive access to every node of the particle's stencil (the slab
/// colouring of P2G), and the stencil lies on the grid.
#[inline(always)]
pub(crate) unsafe fn scatter<const D: usize, K: Kernel>(
    stencil: &Stencil<D>,
    stride: &[usize; 3],
    what: &Scatter<D>,
    mass_out: SharedSlice<f64>,
    momentum_out: SharedSlice<Vector<D>>,
) {
    let span_z = if D == 3 { K::SPAN } else { 1 };
    let [ax, ay, az] = &stencil.axes;
    let mut offset = Vector::<D>::zeros();
    for d in 0..D {
        offset[d] = stencil.offset[d];
    }
    // Momentum at node offset (a, b, c) = p0 + a·q₀ + b·q₁ + c·q₂ (q's columns).
    let p0 = what.mv - what.q * offset;
    let q0 = what.q.column(0).into_owned();
    let q1 = what.q.column(1).into_owned();
    let q2 = if D == 3 {
        what.q.column(2).into_owned()
    } else {
        Vector::<D>::zeros()
    };
    let s0 = what.s.map(|s| s.column(0).into_owned());
    let s1 = what.s.map(|s| s.column(1).into_owned());
    let s2 = match what.s {
        Some(s) if D == 3 => Some(s.column(2).into_owned()),
        _ => None,
    };
    for a in 0..K::SPAN {
        let pa = p0 + q0 * a as f64;
        let (wa, da) = (ax.w[a], ax.dw[a]);
        for b in 0..K::SPAN {
            let pab = pa + q1 * b as f64;
            let (wab, dab_x, dab_y) = (wa * ay.w[b], da * ay.w[b], wa * ay.dw[b]);
            let row = stencil.base_index + a * stride[0] + b * stride[1];
            for c in 0..span_z {
                let (wz, dz) = (az.w[c], az.dw[c]);
                let w = wab * wz;
                let mut add = if D == 3 { pab + q2 * c as f64 } else { pab } * w;
                if let (Some(s0), Some(s1)) = (s0, s1) {
                    add += s0 * (dab_x * wz) + s1 * (dab_y * wz);
                    if let Some(s2) = s2 {
                        add += s2 * (wab * dz);
                    }
                }
                // SAFETY: exclusive access and bounds are the caller's guarantee.
                unsafe {
                    if let Some(m) = what.mass {
                        *mass_out.get(row + c) += w * m;
                    }
                    *momentum_out.get(row + c) += add;
                }
            }
        }
    }
}

/// What one particle gathers from the grid's velocities.
pub(crate) struct Gathered<const D: usize> {
    /// Σ w v.
    pub velocity: Vector<D>,
    /// Σ w v (node − x_p)ᵀ, offsets in cells (the APIC matrix B before D⁻¹); zero unless asked.
    pub affine: Matrix<D>,
    /// Σ v ∇wᵀ, gradients in grid units; zero unless asked.
    pub gradient: Matrix<D>,
}

/// Gathers one particle's velocity, and its APIC matrix B and velocity gradient when asked,
/// from the nodal velocities `v` of its stencil.
#[inline(always)]
pub(crate) fn gather<const D: usize, K: Kernel>(
    stencil: &Stencil<D>,
    stride: &[usize; 3],
    v: &[Vector<D>],
    affine: bool,
    gradient: bool,
) -> Gathered<D> {
    let span_z = if D == 3 { K::SPAN } else { 1 };
    let [ax, ay, az] = &stencil.axes;
    let zero = Vector::<D>::zeros();
    // Per x-layer a: t0 = Σ_b wy Σ_c wz v; ty = Σ_b b·wy Σ_c wz v; tz = Σ_b wy Σ_c c·wz v;
    // ty_grad = Σ_b dwy Σ_c wz v; tz_grad = Σ_b wy Σ_c dwz v.
    let mut velocity = zero;
    let mut bx = zero;
    let mut by = zero;
    let mut bz = zero;
    let mut gx = zero;
    let mut gy = zero;
    let mut gz = zero;
    for a in 0..K::SPAN {
        let (mut t0, mut ty, mut tz, mut tgy, mut tgz) = (zero, zero, zero, zero, zero);
        for b in 0..K::SPAN {
            let row = stencil.base_index + a * stride[0] + b * stride[1];
            let (mut s0, mut s1, mut sd) = (zero, zero, zero);
            for c in 0..span_z {
                let vi = v[row + c];
                s0 += vi * az.w[c];
                if D == 3 {
                    if affine {
                        s1 += vi * (az.w[c] * c as f64);
                    }
                    if gradient {
                        sd += vi * az.dw[c];
                    }
                }
            }
            let wy = ay.w[b];
            t0 += s0 * wy;
            if affine {
                ty += s0 * (wy * b as f64);
                tz += s1 * wy;
            }
            if gradient {
                tgy += s0 * ay.dw[b];
                tgz += sd * wy;
            }
        }
        let wx = ax.w[a];
        velocity += t0 * wx;
        if affine {
            bx += t0 * (wx * a as f64);
            by += ty * wx;
            bz += tz * wx;
        }
        if gradient {
            gx += t0 * ax.dw[a];
            gy += tgy * wx;
            gz += tgz * wx;
        }
    }
    let mut out = Gathered {
        velocity,
        affine: Matrix::<D>::zeros(),
        gradient: Matrix::<D>::zeros(),
    };
    if affine {
        // B = Σ w v (a, b, c)ᵀ − v_pic·offsetᵀ.
        let columns = [bx, by, bz];
        for (d, (column, offset)) in columns.iter().zip(stencil.offset).take(D).enumerate() {
            out.affine.set_column(d, &(column - velocity * offset));
        }
    }
    if gradient {
        for (d, column) in [gx, gy, gz].iter().take(D).enumerate() {
            out.gradient.set_column(d, column);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    //! The tensor-product transfers against the plain loop over the stencil.
    use super::*;
    use crate::grid::Grid;
    use crate::kernels::{CubicBSpline, Linear, QuadraticBSpline};

    /// A deterministic pseudo-random number in [-1, 1).
    fn noise(k: &mut u64) -> f64 {
        *k = k
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*k >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn vector<const D: usize>(k: &mut u64) -> Vector<D> {
        Vector::<D>::from_fn(|_, _| noise(k))
    }

    fn matrix<const D: usize>(k: &mut u64) -> Matrix<D> {
        Matrix::<D>::from_fn(|_, _| noise(k))
    }

    /// Largest difference between two arrays of vectors, relative to the largest entry.
    fn relative<const D: usize>(a: &[Vector<D>], b: &[Vector<D>]) -> f64 {
        let scale = a.iter().map(|v| v.amax()).fold(0.0, f64::max);
        let diff = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x - y).amax())
            .fold(0.0, f64::max);
        diff / scale
    }

    fn compare<const D: usize, K: Kernel>() {
        let mut k = 7u64;
        let cells = [8, 8, if D == 3 { 8 } else { 1 }];
        let mut grid = Grid::<D>::new(Vector::<D>::zeros(), cells, 0.5, false);
        let stride = grid.stride;
        for i in 0..grid.len() {
            grid.momentum[i] = vector::<D>(&mut k);
        }
        for _ in 0..50 {
            // A particle well inside the grid.
            let x = Vector::<D>::from_fn(|_, _| 2.0 + noise(&mut k).abs() * 0.9);
            let stencil = Stencil::<D>::new::<K>(&grid, &x, 0.0);
            // Gather.
            let g = gather::<D, K>(&stencil, &stride, &grid.momentum, true, true);
            let (mut v, mut b, mut grad) = (
                Vector::<D>::zeros(),
                Matrix::<D>::zeros(),
                Matrix::<D>::zeros(),
            );
            stencil.for_each::<K>(&stride, |i, w, dw, dpos| {
                let vi = grid.momentum[i];
                v += vi * w;
                b += (vi * w) * dpos.transpose();
                grad += vi * dw.transpose();
            });
            assert!((g.velocity - v).amax() < 1e-14, "{}", K::NAME);
            assert!((g.affine - b).amax() < 1e-14, "{}", K::NAME);
            assert!((g.gradient - grad).amax() < 1e-14, "{}", K::NAME);
            // Scatter, with and without mass and stress.
            let (m, mv, q, s) = (
                1.3,
                vector::<D>(&mut k),
                matrix::<D>(&mut k),
                matrix(&mut k),
            );
            for (with_mass, with_stress) in [(true, true), (false, false)] {
                let mut mass = vec![0.0; grid.len()];
                let mut momentum = vec![Vector::<D>::zeros(); grid.len()];
                let what = Scatter {
                    mass: with_mass.then_some(m),
                    mv,
                    q,
                    s: with_stress.then_some(s),
                };
                // SAFETY: one thread; the stencil is on the grid.
                unsafe {
                    scatter::<D, K>(
                        &stencil,
                        &stride,
                        &what,
                        SharedSlice::new(&mut mass),
                        SharedSlice::new(&mut momentum),
                    );
                }
                let mut mass_ref = vec![0.0; grid.len()];
                let mut momentum_ref = vec![Vector::<D>::zeros(); grid.len()];
                stencil.for_each::<K>(&stride, |i, w, grad, dpos| {
                    if with_mass {
                        mass_ref[i] += w * m;
                    }
                    momentum_ref[i] += (mv + q * dpos) * w;
                    if with_stress {
                        momentum_ref[i] += s * grad;
                    }
                });
                let mass_diff = mass.iter().zip(&mass_ref).map(|(a, b)| (a - b).abs());
                assert!(mass_diff.fold(0.0, f64::max) < 1e-15);
                assert!(relative(&momentum, &momentum_ref) < 1e-14, "{}", K::NAME);
                assert!(momentum_ref.iter().any(|v| v.amax() > 0.0));
            }
        }
    }

    #[test]
    fn tensor_product_transfers_match_the_stencil_loop() {
        compare::<2, QuadraticBSpline>();
        compare::<3, QuadraticBSpline>();
        compare::<2, CubicBSpline>();
        compare::<3, CubicBSpline>();
        compare::<2, Linear>();
        compare::<3, Linear>();
    }
}
