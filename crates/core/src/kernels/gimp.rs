//! Uniform GIMP (uGIMP): the linear kernel convolved with the particle's undeformed box,
//! which removes the cell-crossing noise of plain linear MPM.

use super::{AxisWeights, Kernel, fast_floor};

/// uGIMP over three nodes per axis; needs each particle's half width (at most half a cell).
#[derive(Clone, Copy, Debug, Default)]
pub struct UniformGimp;

/// Weight and derivative for node distance `d = x_p - x_i` and particle half width `l`
/// (both in cells).
#[inline(always)]
fn s_and_ds(d: f64, l: f64) -> (f64, f64) {
    let ad = d.abs();
    let s = d.signum();
    if ad < l {
        (1.0 - (d * d + l * l) / (2.0 * l), -d / l)
    } else if ad < 1.0 - l {
        (1.0 - ad, -s)
    } else if ad < 1.0 + l {
        let t = 1.0 + l - ad;
        (t * t / (4.0 * l), -s * t / (2.0 * l))
    } else {
        (0.0, 0.0)
    }
}

impl Kernel for UniformGimp {
    const SPAN: usize = 3;
    const NAME: &'static str = "gimp";
    const APIC_INERTIA: Option<f64> = None;
    const USES_PARTICLE_SIZE: bool = true;

    #[inline(always)]
    fn weights(xi: f64, half_size: f64) -> AxisWeights {
        let base = fast_floor(xi - half_size);
        let mut out = AxisWeights {
            base: base as isize,
            ..Default::default()
        };
        for a in 0..3 {
            let (w, dw) = s_and_ds(xi - (base + a as f64), half_size);
            out.w[a] = w;
            out.dw[a] = dw;
        }
        out
    }
}
