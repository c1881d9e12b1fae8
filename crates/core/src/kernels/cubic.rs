//! Cubic B-spline shape functions: C2, four nodes per axis.

use super::{AxisWeights, Kernel, fast_floor};

/// Cubic B-spline over four nodes per axis.
#[derive(Clone, Copy, Debug, Default)]
pub struct CubicBSpline;

#[inline(always)]
fn n_and_dn(d: f64) -> (f64, f64) {
    let ad = d.abs();
    let s = d.signum();
    if ad < 1.0 {
        (
            0.5 * ad * ad * ad - ad * ad + 2.0 / 3.0,
            s * (1.5 * ad * ad - 2.0 * ad),
        )
    } else if ad < 2.0 {
        let t = 2.0 - ad;
        (t * t * t / 6.0, -s * 0.5 * t * t)
    } else {
        (0.0, 0.0)
    }
}

impl Kernel for CubicBSpline {
    const SPAN: usize = 4;
    const NAME: &'static str = "bspline3";
    const APIC_INERTIA: Option<f64> = Some(1.0 / 3.0);

    #[inline(always)]
    fn weights(xi: f64, _half_size: f64) -> AxisWeights {
        let base = fast_floor(xi) - 1.0;
        let mut out = AxisWeights {
            base: base as isize,
            ..Default::default()
        };
        for a in 0..4 {
            // d = x_p - x_i; weight derivative with respect to x_p.
            let (n, dn) = n_and_dn(xi - (base + a as f64));
            out.w[a] = n;
            out.dw[a] = dn;
        }
        out
    }
}
