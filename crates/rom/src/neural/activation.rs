//! The custom hidden-layer activation: a fast branch-free tanh and the fused bias-add and
//! tanh candle op with its local derivative.

use candle_core::{CpuStorage, CustomOp2, DType, Layout, Shape, Tensor};
use rayon::prelude::*;

/// Rows per parallel task of the activation kernels.
const ROWS_PER_TASK: usize = 256;

/// tanh(x) = (1 − e)/(1 + e) with e = exp(−2|x|), copying the sign; absolute error ~3e-16.
/// Branch-free (see [`exp_nonpositive`]) so the activation loops vectorise; libm's `tanh`
/// was the largest single cost of training.
#[inline]
fn tanh(x: f64) -> f64 {
    let e = exp_nonpositive(-2.0 * x.abs());
    ((1.0 - e) / (1.0 + e)).copysign(x)
}

/// 1/n! for n = 0..=13, the Taylor coefficients of exp.
const INVERSE_FACTORIALS: [f64; 14] = {
    let mut c = [1.0; 14];
    let mut n = 1;
    while n < 14 {
        c[n] = c[n - 1] / n as f64;
        n += 1;
    }
    c
};

/// exp(y) for y ≤ 0 (y < −40 is treated as −40, which is below tanh's resolution): Cody–Waite
/// reduction y = k ln2 + r, |r| ≤ ln2/2, a degree-13 Taylor polynomial (truncation < 1e-17)
/// and 2^k assembled from bits.
#[inline]
fn exp_nonpositive(y: f64) -> f64 {
    const SHIFT: f64 = 6_755_399_441_055_744.0; // 1.5·2^52: adding it rounds to an integer
    const LN2_HI: f64 = 6.931_471_803_691_238e-1;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    let y = y.max(-40.0);
    let t = y * std::f64::consts::LOG2_E + SHIFT;
    let k = t - SHIFT;
    let r = (y - k * LN2_HI) - k * LN2_LO;
    // Estrin's scheme: short dependency chains, so consecutive elements overlap.
    let c = &INVERSE_FACTORIALS;
    let (r2, a) = (r * r, |i: usize| c[i] + c[i + 1] * r);
    let r4 = r2 * r2;
    let b0 = a(0) + a(2) * r2;
    let b1 = a(4) + a(6) * r2;
    let b2 = a(8) + a(10) * r2;
    let b3 = a(12);
    let p = (b0 + b1 * r4) + (b2 + b3 * r4) * (r4 * r4);
    let k_bits = t.to_bits().wrapping_sub(SHIFT.to_bits());
    p * f64::from_bits(k_bits.wrapping_add(1023) << 52)
}

/// The f64 values of a contiguous CPU tensor.
fn values<'a>(storage: &'a CpuStorage, layout: &Layout) -> candle_core::Result<&'a [f64]> {
    match (storage, layout.contiguous_offsets()) {
        (CpuStorage::F64(v), Some((start, end))) => Ok(&v[start..end]),
        _ => Err(candle_core::Error::Msg(
            "neural activation: expected a contiguous f64 tensor".into(),
        )),
    }
}

/// Hidden-layer activation y = tanh(z + b), z [rows, width], b [width], as one parallel pass:
/// candle's CPU backend runs `broadcast_add` and `tanh` single-threaded, with libm's slow
/// `tanh`. Only the local derivative, (1 − y²) ⊙ ∂y, is supplied (`bwd`); candle's autodiff
/// still chains it through the network. Equivalent to `z.broadcast_add(b)?.tanh()`.
pub(super) struct BiasTanh;

impl CustomOp2 for BiasTanh {
    fn name(&self) -> &'static str {
        "bias-tanh"
    }

    fn cpu_fwd(
        &self,
        z: &CpuStorage,
        z_layout: &Layout,
        b: &CpuStorage,
        b_layout: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (z, b) = (values(z, z_layout)?, values(b, b_layout)?);
        let width = b.len();
        if width == 0 || z_layout.dims().len() != 2 || z_layout.dims()[1] != width {
            return Err(candle_core::Error::Msg("bias-tanh: shape mismatch".into()));
        }
        let mut y = vec![0.0; z.len()];
        y.par_chunks_mut(ROWS_PER_TASK * width)
            .zip(z.par_chunks(ROWS_PER_TASK * width))
            .for_each(|(y, z)| {
                for (y, z) in y.chunks_exact_mut(width).zip(z.chunks_exact(width)) {
                    for ((y, z), b) in y.iter_mut().zip(z).zip(b) {
                        *y = tanh(z + b);
                    }
                }
            });
        Ok((CpuStorage::F64(y), z_layout.shape().clone()))
    }

    fn bwd(
        &self,
        _z: &Tensor,
        _b: &Tensor,
        y: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>)> {
        let grad_z = y.apply_op2_no_bwd(&grad.contiguous()?, &TanhGrad)?;
        // Column sums as a product with ones: candle's strided `sum(0)` is far slower.
        let ones = Tensor::ones((1, grad_z.dim(0)?), DType::F64, grad_z.device())?;
        let grad_b = ones.matmul(&grad_z)?.squeeze(0)?;
        Ok((Some(grad_z), Some(grad_b)))
    }
}

/// (1 − y²) ⊙ g for y = tanh(·): the local derivative of [`BiasTanh`], in parallel.
struct TanhGrad;

impl CustomOp2 for TanhGrad {
    fn name(&self) -> &'static str {
        "tanh-grad"
    }

    fn cpu_fwd(
        &self,
        y: &CpuStorage,
        y_layout: &Layout,
        g: &CpuStorage,
        g_layout: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (y, g) = (values(y, y_layout)?, values(g, g_layout)?);
        if y.len() != g.len() {
            return Err(candle_core::Error::Msg("tanh-grad: shape mismatch".into()));
        }
        let mut out = vec![0.0; y.len()];
        let chunk = 16 * 1024;
        out.par_chunks_mut(chunk)
            .zip(y.par_chunks(chunk).zip(g.par_chunks(chunk)))
            .for_each(|(o, (y, g))| {
                for ((o, y), g) in o.iter_mut().zip(y).zip(g) {
                    *o = (1.0 - y * y) * g;
                }
            });
        Ok((CpuStorage::F64(out), y_layout.shape().clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    #[test]
    fn neural_tanh_is_accurate() {
        let worst = (-400_000..=400_000)
            .map(|i| i as f64 * 1e-4 + 1.234e-6)
            .map(|x| (tanh(x) - x.tanh()).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-15, "worst tanh error {worst:e}");
    }

    #[test]
    fn neural_bias_tanh_matches_candle() -> candle_core::Result<()> {
        let dev = Device::Cpu;
        let z: Vec<f64> = (0..12).map(|i| 0.37 * i as f64 - 1.9).collect();
        let z = Var::from_vec(z, (4, 3), &dev)?;
        let b = Var::from_vec(vec![0.1, -0.2, 0.3], 3, &dev)?;
        let w: Vec<f64> = (0..12).map(|i| (i as f64).sin()).collect();
        let w = Tensor::from_vec(w, (4, 3), &dev)?;
        let ours = z.apply_op2(&b, BiasTanh)?;
        let theirs = z.broadcast_add(&b)?.tanh()?;
        let g_ours = (&ours * &w)?.sum_all()?.backward()?;
        let g_theirs = (&theirs * &w)?.sum_all()?.backward()?;
        let pairs = [
            (ours, theirs),
            (
                g_ours.get(&z).unwrap().clone(),
                g_theirs.get(&z).unwrap().clone(),
            ),
            (
                g_ours.get(&b).unwrap().clone(),
                g_theirs.get(&b).unwrap().clone(),
            ),
        ];
        for (a, c) in pairs {
            let diff = (a - c)?.abs()?.max_all()?.to_scalar::<f64>()?;
            assert!(diff < 1e-14, "custom activation differs by {diff:e}");
        }
        Ok(())
    }
}
