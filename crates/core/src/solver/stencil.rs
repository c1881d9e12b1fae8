//! Kernel weights of one particle in D dimensions and the loop over its stencil nodes.

use crate::grid::Grid;
use crate::kernels::{AxisWeights, Kernel};
use crate::math::Vector;

/// The weights of one particle on every axis, and the index of its first stencil node.
pub struct Stencil<const D: usize> {
    /// 1D weights along each axis (a single weight 1 along unused axes).
    pub axes: [AxisWeights; 3],
    /// Grid coordinate of the particle minus the base node, per axis.
    pub offset: [f64; 3],
    /// Grid index of the first stencil node.
    pub base_index: usize,
}

/// Whether a particle's stencil lies on the grid.
#[inline(always)]
pub fn stencil_fits<const D: usize, K: Kernel>(grid: &Grid<D>, x: &Vector<D>, half: f64) -> bool {
    for d in 0..D {
        let xi = (x[d] - grid.origin[d]) * grid.inv_dx;
        if !xi.is_finite() {
            return false;
        }
        let base = K::weights(xi, half).base;
        if base < 0 || base as usize + K::SPAN > grid.nodes[d] {
            return false;
        }
    }
    true
}

impl<const D: usize> Stencil<D> {
    /// Weights of a particle at `x` (the caller has checked that the stencil fits).
    #[inline(always)]
    pub fn new<K: Kernel>(grid: &Grid<D>, x: &Vector<D>, half: f64) -> Self {
        let mut axes = [AxisWeights::default(); 3];
        let mut offset = [0.0; 3];
        let mut base = [0usize; 3];
        for d in 0..3 {
            if d < D {
                let xi = (x[d] - grid.origin[d]) * grid.inv_dx;
                axes[d] = K::weights(xi, half);
                offset[d] = xi - axes[d].base as f64;
                base[d] = axes[d].base.max(0) as usize;
            } else {
                axes[d].w[0] = 1.0;
            }
        }
        Self {
            axes,
            offset,
            base_index: grid.index(base),
        }
    }

    /// Calls `f(node_index, weight, weight_gradient_in_grid_units, node_minus_particle_in_cells)`
    /// for every node of the stencil.
    #[inline(always)]
    pub fn for_each<K: Kernel>(
        &self,
        stride: &[usize; 3],
        mut f: impl FnMut(usize, f64, Vector<D>, Vector<D>),
    ) {
        let span_z = if D == 3 { K::SPAN } else { 1 };
        let [ax, ay, az] = &self.axes;
        for a in 0..K::SPAN {
            for b in 0..K::SPAN {
                for c in 0..span_z {
                    let w = ax.w[a] * ay.w[b] * az.w[c];
                    let mut grad = Vector::<D>::zeros();
                    let mut dpos = Vector::<D>::zeros();
                    grad[0] = ax.dw[a] * ay.w[b] * az.w[c];
                    grad[1] = ax.w[a] * ay.dw[b] * az.w[c];
                    dpos[0] = a as f64 - self.offset[0];
                    dpos[1] = b as f64 - self.offset[1];
                    if D == 3 {
                        grad[2] = ax.w[a] * ay.w[b] * az.dw[c];
                        dpos[2] = c as f64 - self.offset[2];
                    }
                    let index = self.base_index + a * stride[0] + b * stride[1] + c;
                    f(index, w, grad, dpos);
                }
            }
        }
    }
}
