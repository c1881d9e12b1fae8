//! Quadratic B-spline shape functions: C1, three nodes per axis, the usual APIC/MLS choice.

use super::{AxisWeights, Kernel, fast_floor};

/// Quadratic B-spline over three nodes per axis.
#[derive(Clone, Copy, Debug, Default)]
pub struct QuadraticBSpline;

impl Kernel for QuadraticBSpline {
    const SPAN: usize = 3;
    const NAME: &'static str = "bspline2";
    const APIC_INERTIA: Option<f64> = Some(0.25);

    #[inline(always)]
    fn weights(xi: f64, _half_size: f64) -> AxisWeights {
        let base = fast_floor(xi - 0.5);
        // Distance from the first node, in [0.5, 1.5).
        let fx = xi - base;
        let a = 1.5 - fx;
        let b = fx - 1.0;
        let c = fx - 0.5;
        AxisWeights {
            base: base as isize,
            w: [0.5 * a * a, 0.75 - b * b, 0.5 * c * c, 0.0],
            dw: [-a, -2.0 * b, c, 0.0],
        }
    }
}
