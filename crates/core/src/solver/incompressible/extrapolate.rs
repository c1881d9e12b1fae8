//! The projection's velocity change continued beyond the liquid cells (mod.rs step 3):
//! the nodes a B-spline reaches outside them get their neighbours' change, not free fall.

use crate::grid::{Grid, node_coords};
use crate::math::Vector;

/// Extrapolates the projection's velocity change to the nodes that carry P2G mass but
/// touch no liquid cell. A B-spline reaches one node beyond the corners of the cell a
/// particle lies in (quadratic and cubic alike), so such nodes lie above the free
/// surface and behind walls; left out they would keep the unprojected v* (free fall),
/// and G2P would hand that to the particles beside them every step. Each pass gives a
/// node still unset the mean of its already set neighbours (the 3^D - 1 around it),
/// reading only earlier passes, so the result does not depend on the node order: the
/// pressure acceleration ∇p/ρ continued at constant value over the kernel's reach, as
/// PIC/FLIP/APIC liquid solvers extrapolate the projected velocity into the air
/// (Zhu & Bridson 2005; Jiang et al. 2015). No node has such mass with the linear
/// kernel, so this changes nothing there.
pub(super) fn extrapolate_correction<const D: usize>(
    grid: &Grid<D>,
    correction: &mut [Vector<D>],
    layer: &mut [u8],
) {
    const PASSES: u8 = 2;
    let offsets = (0..D).fold(1, |n, _| n * 3);
    for pass in 1..=PASSES {
        let mut unset = false;
        for i in 0..grid.len() {
            if layer[i] != u8::MAX || grid.mass[i] <= 0.0 {
                continue;
            }
            let ijk = node_coords(&grid.stride, i);
            let mut sum = Vector::<D>::zeros();
            let mut count = 0usize;
            for k in 0..offsets {
                let mut rest = k;
                let mut j = 0usize;
                let mut inside = true;
                for (d, &at) in ijk.iter().enumerate().take(D) {
                    let step = (rest % 3) as isize - 1;
                    rest /= 3;
                    let n = at as isize + step;
                    if n < 0 || n >= grid.nodes[d] as isize {
                        inside = false;
                        break;
                    }
                    j += n as usize * grid.stride[d];
                }
                if inside && j != i && layer[j] < pass {
                    sum += correction[j];
                    count += 1;
                }
            }
            if count > 0 {
                correction[i] = sum / count as f64;
                layer[i] = pass;
            } else {
                unset = true;
            }
        }
        if !unset {
            break;
        }
    }
}
