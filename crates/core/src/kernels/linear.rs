//! Linear (tent) shape functions: the original MPM kernel, C0 across cell faces.

use super::{AxisWeights, Kernel, fast_floor};

/// Tent functions over two nodes per axis.
#[derive(Clone, Copy, Debug, Default)]
pub struct Linear;

impl Kernel for Linear {
    const SPAN: usize = 2;
    const NAME: &'static str = "linear";
    const APIC_INERTIA: Option<f64> = None;

    #[inline(always)]
    fn weights(xi: f64, _half_size: f64) -> AxisWeights {
        let base = fast_floor(xi);
        let fx = xi - base;
        AxisWeights {
            base: base as isize,
            w: [1.0 - fx, fx, 0.0, 0.0],
            dw: [-1.0, 1.0, 0.0, 0.0],
        }
    }
}
