//! The neural deformation map g(X, q) = X + s ⊙ MLP([X̂, q̂]): a small tanh network trained
//! on full-order snapshots as an auto-decoder (weights and per-snapshot latent codes jointly),
//! after Chen et al., "Model reduction for the material point method on nonlinear manifolds".
//! Network, training and all derivatives use candle (CPU, f64) and its automatic
//! differentiation.

use crate::RomError;
use crate::file::NamedArray;
use crate::map::{PointMap, ReducedMap};
use candle_core::{CpuStorage, CustomOp2, DType, Device, Layout, Shape, Tensor, Var};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};
use rayon::prelude::*;
use std::path::Path;

/// Name of the activation stored in the description (the only one supported).
const ACTIVATION: &str = "tanh";
/// Rows (points over all snapshots of a step) per optimiser step, roughly.
const ROWS_PER_STEP: usize = 1024;
/// Final learning rate of the cosine schedule, relative to `learning_rate`.
const FINAL_LR_FRACTION: f64 = 0.05;

/// Training settings of the neural map.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct NeuralOptions {
    /// Neurons per hidden layer.
    pub width: usize,
    /// Number of hidden (tanh) layers.
    pub hidden_layers: usize,
    /// Passes over all snapshots.
    pub epochs: usize,
    /// Peak AdamW learning rate (cosine-decayed to 5% of it over training).
    pub learning_rate: f64,
    /// Points sampled per snapshot per batch.
    pub batch_points: usize,
    /// Seed of the weight initialisation and point sampling (training is deterministic).
    pub seed: u64,
}

impl Default for NeuralOptions {
    fn default() -> Self {
        Self {
            width: 64,
            hidden_layers: 3,
            epochs: 300,
            learning_rate: 2e-3,
            batch_points: 512,
            seed: 0,
        }
    }
}

/// g(X, q) = X + s ⊙ MLP([X̂, q̂]) with tanh activations (C∞, so F = ∂g/∂X is smooth);
/// X̂, q̂ are normalised inputs and s a per-axis output scale.
pub struct NeuralMap {
    dimension: usize,
    latent: usize,
    width: usize,
    hidden_layers: usize,
    centre: Vec<f64>,
    half_extent: Vec<f64>,
    latent_mean: Vec<f64>,
    latent_std: Vec<f64>,
    output_scale: Vec<f64>,
    /// (weight [out, in], bias [out]) per layer, hidden layers then the output layer.
    layers: Vec<(Tensor, Tensor)>,
}

/// Tiny seeded generator (splitmix64), so training needs no `rand` crate.
struct SplitMix(u64);

impl SplitMix {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    /// Uniform integer in 0..n (n ≥ 1).
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

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
struct BiasTanh;

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

/// Runs the MLP on `input` ([rows, dimension + latent]) giving [rows, dimension].
fn forward(layers: &[(Tensor, Tensor)], input: &Tensor) -> candle_core::Result<Tensor> {
    let mut h = input.clone();
    for (k, (w, b)) in layers.iter().enumerate() {
        h = h.matmul(&w.t()?)?;
        h = if k + 1 < layers.len() {
            h.apply_op2(b, BiasTanh)?
        } else {
            h.broadcast_add(b)?
        };
    }
    Ok(h)
}

fn training(message: impl Into<String>) -> RomError {
    RomError::Training(message.into())
}

/// Per-axis minimum and maximum of `points` (`dimension` numbers per point).
fn bounds(dimension: usize, points: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut lo = vec![f64::INFINITY; dimension];
    let mut hi = vec![f64::NEG_INFINITY; dimension];
    for p in points.chunks_exact(dimension) {
        for ((lo, hi), v) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
            *lo = lo.min(*v);
            *hi = hi.max(*v);
        }
    }
    (lo, hi)
}

/// Raises entries of `v` below `relative` × max(v) to that floor, or sets all to 1 if v ≡ 0.
fn floor_relative(v: &mut [f64], relative: f64) {
    let top = v.iter().cloned().fold(0.0, f64::max);
    let floor = if top > 0.0 { relative * top } else { 1.0 };
    v.iter_mut().for_each(|x| *x = x.max(floor));
}

impl NeuralMap {
    /// Trains on `snapshots` (S snapshots × P points × dimension current positions, row-major)
    /// of the points `reference` (P × dimension). `latent_init` (S × latent) are initial latent
    /// codes (e.g. POD coefficients), trained jointly with the weights and returned (S × latent).
    /// `log(epoch, mse)` is called once per epoch (epoch counting from 1) with the mean over
    /// sampled points of the squared position error |g − x|² in metres².
    pub fn train(
        dimension: usize,
        reference: &[f64],
        snapshots: &[f64],
        latent: usize,
        latent_init: &[f64],
        options: &NeuralOptions,
        log: &mut dyn FnMut(usize, f64),
    ) -> Result<(NeuralMap, Vec<f64>), RomError> {
        let d = dimension;
        if !(1..=3).contains(&d) {
            return Err(RomError::Option(format!(
                "dimension must be 1, 2 or 3, not {d}"
            )));
        }
        if latent == 0 {
            return Err(RomError::Option("the neural map needs latent ≥ 1".into()));
        }
        if options.width == 0 || options.hidden_layers == 0 || options.batch_points == 0 {
            return Err(RomError::Option(
                "neural width, hidden_layers and batch_points must be ≥ 1".into(),
            ));
        }
        if !(options.learning_rate.is_finite() && options.learning_rate > 0.0) {
            return Err(RomError::Option(format!(
                "neural learning_rate must be positive, not {}",
                options.learning_rate
            )));
        }
        if reference.is_empty() || !reference.len().is_multiple_of(d) {
            return Err(training(format!(
                "{} reference coordinates are not a positive multiple of dimension {d}",
                reference.len()
            )));
        }
        let p = reference.len() / d;
        if latent_init.is_empty() || !latent_init.len().is_multiple_of(latent) {
            return Err(training(format!(
                "{} initial latent values are not a positive multiple of latent {latent}",
                latent_init.len()
            )));
        }
        let s_count = latent_init.len() / latent;
        if snapshots.len() != s_count * p * d {
            return Err(training(format!(
                "{} snapshot values, expected {s_count} snapshots × {p} points × {d}",
                snapshots.len()
            )));
        }
        for (name, values) in [
            ("reference positions", reference),
            ("snapshot positions", snapshots),
            ("initial latent codes", latent_init),
        ] {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(training(format!("{name}: value {i} is not finite")));
            }
        }

        // Normalisation constants.
        let (lo, hi) = bounds(d, reference);
        let centre: Vec<f64> = lo.iter().zip(&hi).map(|(a, b)| 0.5 * (a + b)).collect();
        let mut half_extent: Vec<f64> = lo.iter().zip(&hi).map(|(a, b)| 0.5 * (b - a)).collect();
        floor_relative(&mut half_extent, 1e-6);
        let mut latent_mean = vec![0.0; latent];
        for code in latent_init.chunks_exact(latent) {
            latent_mean.iter_mut().zip(code).for_each(|(m, c)| *m += c);
        }
        latent_mean.iter_mut().for_each(|m| *m /= s_count as f64);
        let mut latent_std = vec![0.0; latent];
        for code in latent_init.chunks_exact(latent) {
            for ((v, c), m) in latent_std.iter_mut().zip(code).zip(&latent_mean) {
                *v += (c - m).powi(2);
            }
        }
        latent_std
            .iter_mut()
            .for_each(|v| *v = (*v / s_count as f64).sqrt());
        floor_relative(&mut latent_std, 1e-9);
        let mut output_scale = vec![0.0f64; d];
        for snap in snapshots.chunks_exact(p * d) {
            for (x, xr) in snap.chunks_exact(d).zip(reference.chunks_exact(d)) {
                for ((s, a), b) in output_scale.iter_mut().zip(x).zip(xr) {
                    *s = s.max((a - b).abs());
                }
            }
        }
        let top = output_scale
            .iter()
            .chain(&half_extent)
            .cloned()
            .fold(0.0, f64::max);
        output_scale.iter_mut().for_each(|v| *v = v.max(1e-6 * top));

        let mut map = NeuralMap {
            dimension: d,
            latent,
            width: options.width,
            hidden_layers: options.hidden_layers,
            centre,
            half_extent,
            latent_mean,
            latent_std,
            output_scale,
            layers: Vec::new(),
        };

        // Normalised data: inputs X̂ and targets (x − X)/s.
        let xhat = map.normalise_points(reference);
        let mut target = vec![0.0; snapshots.len()];
        for (t, (x, xr)) in target.chunks_exact_mut(d).zip(
            snapshots
                .chunks_exact(d)
                .zip(reference.chunks_exact(d).cycle()),
        ) {
            for (((t, a), b), s) in t.iter_mut().zip(x).zip(xr).zip(&map.output_scale) {
                *t = (a - b) / s;
            }
        }
        let qhat: Vec<f64> = latent_init
            .chunks_exact(latent)
            .flat_map(|c| map.normalise_latent(c))
            .collect();

        // Parameters: Glorot-uniform weights, zero biases, codes as one [S, latent] variable.
        let dev = Device::Cpu;
        let mut rng = SplitMix(options.seed ^ 0x6a09_e667_f3bc_c908);
        let mut sizes = vec![d + latent];
        sizes.extend(std::iter::repeat_n(options.width, options.hidden_layers));
        sizes.push(d);
        let mut vars = Vec::new();
        let mut layers = Vec::new();
        for pair in sizes.windows(2) {
            let (fan_in, fan_out) = (pair[0], pair[1]);
            let a = (6.0 / (fan_in + fan_out) as f64).sqrt();
            let w: Vec<f64> = (0..fan_in * fan_out)
                .map(|_| a * (2.0 * rng.uniform() - 1.0))
                .collect();
            let w = Var::from_vec(w, (fan_out, fan_in), &dev)?;
            let b = Var::zeros(fan_out, DType::F64, &dev)?;
            layers.push((w.as_tensor().clone(), b.as_tensor().clone()));
            vars.push(w);
            vars.push(b);
        }
        let codes = Var::from_vec(qhat, (s_count, latent), &dev)?;
        vars.push(codes.clone());
        let params = ParamsAdamW {
            lr: options.learning_rate,
            weight_decay: 0.0,
            ..Default::default()
        };
        let mut optimiser = AdamW::new(vars, params)?;

        // Loss weights (s_i / s_max)², so the loss is the physical error over s_max².
        let s_max = map.output_scale.iter().cloned().fold(0.0, f64::max);
        let weights: Vec<f64> = map
            .output_scale
            .iter()
            .map(|s| (s / s_max).powi(2))
            .collect();
        let weights = Tensor::from_vec(weights, (1, d), &dev)?;

        let batch = options.batch_points.min(p);
        let group = (ROWS_PER_STEP / batch).clamp(1, s_count);
        let steps_per_epoch = s_count.div_ceil(group);
        let total_steps = (options.epochs * steps_per_epoch).max(1);
        let mut order: Vec<usize> = (0..s_count).collect();
        let mut points: Vec<usize> = (0..p).collect();
        let rows_max = group * batch;
        let mut inputs = Vec::with_capacity(rows_max * d);
        let mut targets = Vec::with_capacity(rows_max * d);
        let mut ids: Vec<u32> = Vec::with_capacity(rows_max);
        let mut step = 0;
        // glibc returns freed heap memory to the system once more than its trim threshold is
        // free; each step then page-faults its ~20 MB of tensors back in (half the run time).
        // Freeing one large mmap'd block raises that threshold to twice its size (the
        // documented dynamic mmap threshold of mallopt(3)); harmless with other allocators.
        drop(std::hint::black_box(vec![0u8; 31 << 20]));
        for epoch in 1..=options.epochs {
            for i in (1..s_count).rev() {
                order.swap(i, rng.below(i + 1));
            }
            let (mut sum, mut rows_seen) = (0.0, 0usize);
            for chunk in order.chunks(group) {
                inputs.clear();
                targets.clear();
                ids.clear();
                for &s in chunk {
                    // Partial Fisher–Yates: the first `batch` entries become a fresh sample.
                    if batch < p {
                        for i in 0..batch {
                            points.swap(i, i + rng.below(p - i));
                        }
                    }
                    for &pt in &points[..batch] {
                        inputs.extend_from_slice(&xhat[pt * d..(pt + 1) * d]);
                        let at = (s * p + pt) * d;
                        targets.extend_from_slice(&target[at..at + d]);
                        ids.push(s as u32);
                    }
                }
                let rows = ids.len();
                let x = Tensor::from_slice(&inputs, (rows, d), &dev)?;
                let t = Tensor::from_slice(&targets, (rows, d), &dev)?;
                let id = Tensor::from_slice(&ids, rows, &dev)?;
                let q = codes.as_tensor().index_select(&id, 0)?;
                let y = forward(&layers, &Tensor::cat(&[&x, &q], 1)?)?;
                let loss = ((y - t)?.sqr()?.broadcast_mul(&weights)?.sum_all()? / rows as f64)?;
                let value = loss.to_scalar::<f64>()?;
                if !value.is_finite() {
                    return Err(training(format!(
                        "neural training diverged in epoch {epoch}; lower the learning rate"
                    )));
                }
                let progress = step as f64 / total_steps as f64;
                let cosine = 0.5 * (1.0 + (std::f64::consts::PI * progress).cos());
                optimiser.set_learning_rate(
                    options.learning_rate
                        * (FINAL_LR_FRACTION + (1.0 - FINAL_LR_FRACTION) * cosine),
                );
                optimiser.backward_step(&loss)?;
                step += 1;
                sum += value * rows as f64;
                rows_seen += rows;
            }
            log(epoch, sum / rows_seen as f64 * s_max * s_max);
        }

        map.layers = layers
            .iter()
            .map(|(w, b)| (w.detach(), b.detach()))
            .collect();
        let trained = codes.as_tensor().flatten_all()?.to_vec1::<f64>()?;
        let codes_out = trained
            .chunks_exact(latent)
            .flat_map(|c| {
                c.iter()
                    .zip(map.latent_mean.iter().zip(&map.latent_std))
                    .map(|(v, (m, s))| v * s + m)
            })
            .collect();
        Ok((map, codes_out))
    }

    /// Normalised reference positions X̂ = (X − centre) / half_extent.
    fn normalise_points(&self, points: &[f64]) -> Vec<f64> {
        let d = self.dimension;
        let mut out = points.to_vec();
        for x in out.chunks_exact_mut(d) {
            for ((x, c), h) in x.iter_mut().zip(&self.centre).zip(&self.half_extent) {
                *x = (*x - c) / h;
            }
        }
        out
    }

    /// Normalised latent code q̂ = (q − mean) / std.
    fn normalise_latent(&self, q: &[f64]) -> Vec<f64> {
        q.iter()
            .zip(self.latent_mean.iter().zip(&self.latent_std))
            .map(|(v, (m, s))| (v - m) / s)
            .collect()
    }

    /// Description (JSON: dimension, latent, width, layers, activation, normalisation
    /// constants) and weights as float64 arrays, for the model file.
    pub fn to_arrays(&self) -> (serde_json::Value, Vec<NamedArray>) {
        let info = serde_json::json!({
            "kind": "neural",
            "dimension": self.dimension,
            "latent": self.latent,
            "width": self.width,
            "hidden_layers": self.hidden_layers,
            "activation": ACTIVATION,
            "centre": self.centre,
            "half_extent": self.half_extent,
            "latent_mean": self.latent_mean,
            "latent_std": self.latent_std,
            "output_scale": self.output_scale,
        });
        let mut arrays = Vec::new();
        for (k, (w, b)) in self.layers.iter().enumerate() {
            for (name, t) in [("weight", w), ("bias", b)] {
                // The tensors are contiguous f64 CPU tensors, so these conversions cannot fail.
                let data = t
                    .flatten_all()
                    .and_then(|t| t.to_vec1::<f64>())
                    .unwrap_or_default();
                arrays.push(NamedArray::new(
                    format!("neural.layer{k}.{name}"),
                    t.dims().to_vec(),
                    data,
                ));
            }
        }
        (info, arrays)
    }

    /// Inverse of [`NeuralMap::to_arrays`]; `path` only names the file in errors
    /// (`RomError::BadModel`) when arrays are missing, misshapen, or the description is wrong.
    pub fn from_arrays(
        path: &Path,
        info: &serde_json::Value,
        mut arrays: Vec<NamedArray>,
    ) -> Result<NeuralMap, RomError> {
        let bad = |message: String| RomError::BadModel {
            path: path.display().to_string(),
            message,
        };
        let count = |key: &str| {
            info.get(key)
                .and_then(|v| v.as_u64())
                .map(|v| v as usize)
                .filter(|&v| v >= 1)
                .ok_or_else(|| {
                    bad(format!(
                        "neural description: `{key}` is not a positive integer"
                    ))
                })
        };
        let dimension = count("dimension")?;
        let latent = count("latent")?;
        let width = count("width")?;
        let hidden_layers = count("hidden_layers")?;
        if dimension > 3 {
            return Err(bad(format!("neural description: dimension {dimension}")));
        }
        let activation = info.get("activation").and_then(|v| v.as_str());
        if activation != Some(ACTIVATION) {
            return Err(bad(format!(
                "neural description: activation {activation:?}, expected \"{ACTIVATION}\""
            )));
        }
        let vector = |key: &str, n: usize, positive: bool| -> Result<Vec<f64>, RomError> {
            let v: Option<Vec<f64>> = info
                .get(key)
                .and_then(|v| v.as_array())
                .and_then(|a| a.iter().map(|x| x.as_f64()).collect());
            match v {
                Some(v)
                    if v.len() == n
                        && v.iter().all(|x| x.is_finite() && (!positive || *x > 0.0)) =>
                {
                    Ok(v)
                }
                _ => Err(bad(format!(
                    "neural description: `{key}` is not {n} finite{} numbers",
                    if positive { " positive" } else { "" }
                ))),
            }
        };
        let centre = vector("centre", dimension, false)?;
        let half_extent = vector("half_extent", dimension, true)?;
        let latent_mean = vector("latent_mean", latent, false)?;
        let latent_std = vector("latent_std", latent, true)?;
        let output_scale = vector("output_scale", dimension, true)?;
        if arrays.len() < 2 * (hidden_layers + 1) {
            return Err(bad(format!(
                "{} arrays, a network of {hidden_layers} hidden layers needs {}",
                arrays.len(),
                2 * (hidden_layers + 1)
            )));
        }
        let mut sizes = vec![dimension + latent];
        sizes.extend(std::iter::repeat_n(width, hidden_layers));
        sizes.push(dimension);
        let mut layers = Vec::new();
        for (k, pair) in sizes.windows(2).enumerate() {
            let (fan_in, fan_out) = (pair[0], pair[1]);
            let name = format!("neural.layer{k}.weight");
            let w = crate::file::take(path, &mut arrays, &name, &[fan_out, fan_in])?;
            let name = format!("neural.layer{k}.bias");
            let b = crate::file::take(path, &mut arrays, &name, &[fan_out])?;
            if w.iter().chain(&b).any(|v| !v.is_finite()) {
                return Err(bad(format!("layer {k} has non-finite weights")));
            }
            let w = Tensor::from_vec(w, (fan_out, fan_in), &Device::Cpu)?;
            let b = Tensor::from_vec(b, fan_out, &Device::Cpu)?;
            layers.push((w, b));
        }
        Ok(NeuralMap {
            dimension,
            latent,
            width,
            hidden_layers,
            centre,
            half_extent,
            latent_mean,
            latent_std,
            output_scale,
            layers,
        })
    }
}

impl ReducedMap for NeuralMap {
    fn dimension(&self) -> usize {
        self.dimension
    }

    fn latent(&self) -> usize {
        self.latent
    }

    fn bind(&self, reference: &[f64]) -> Result<Box<dyn PointMap + '_>, RomError> {
        let d = self.dimension;
        if !reference.len().is_multiple_of(d) {
            return Err(RomError::Option(format!(
                "{} reference coordinates are not a multiple of dimension {d}",
                reference.len()
            )));
        }
        if reference.iter().any(|v| !v.is_finite()) {
            return Err(RomError::Option(
                "reference positions are not finite".into(),
            ));
        }
        Ok(Box::new(BoundNeural {
            map: self,
            reference: reference.to_vec(),
            normalised: self.normalise_points(reference),
            cache: None,
        }))
    }
}

/// F and ∂g/∂q of the last derivative evaluation, kept for the matching second call.
struct Derivatives {
    q: Vec<f64>,
    which: Vec<u32>,
    gradients: Vec<f64>,
    jacobians: Vec<f64>,
}

/// A [`NeuralMap`] bound to reference points (their normalised coordinates precomputed).
struct BoundNeural<'a> {
    map: &'a NeuralMap,
    reference: Vec<f64>,
    normalised: Vec<f64>,
    cache: Option<Derivatives>,
}

impl BoundNeural<'_> {
    /// Checks arguments and builds the network input [which.len(), dimension + latent].
    fn input(&self, q: &[f64], which: &[u32], out: usize, per: usize) -> Result<Tensor, RomError> {
        let (d, l) = (self.map.dimension, self.map.latent);
        if q.len() != l {
            return Err(RomError::Option(format!(
                "{} latent values given, the neural map has {l}",
                q.len()
            )));
        }
        if out != which.len() * per {
            return Err(RomError::Option(format!(
                "output holds {out} values, expected {} points × {per}",
                which.len()
            )));
        }
        let n = self.reference.len() / d;
        if let Some(&i) = which.iter().find(|&&i| i as usize >= n) {
            return Err(RomError::Option(format!(
                "point {i} requested, only {n} are bound"
            )));
        }
        let qhat = self.map.normalise_latent(q);
        let mut data = Vec::with_capacity(which.len() * (d + l));
        for &i in which {
            let i = i as usize;
            data.extend_from_slice(&self.normalised[i * d..(i + 1) * d]);
            data.extend_from_slice(&qhat);
        }
        Ok(Tensor::from_vec(data, (which.len(), d + l), &Device::Cpu)?)
    }

    /// Computes (or reuses) F and ∂g/∂q at `q` for the points `which`: one forward pass,
    /// then one backward pass per output component, each giving row i for all points.
    fn derivatives(&mut self, q: &[f64], which: &[u32]) -> Result<&Derivatives, RomError> {
        let hit = matches!(&self.cache, Some(c) if c.q == q && c.which == which);
        if !hit {
            let (d, l) = (self.map.dimension, self.map.latent);
            let m = which.len();
            let mut gradients = vec![0.0; m * d * d];
            let mut jacobians = vec![0.0; m * d * l];
            if m > 0 {
                let input = Var::from_tensor(&self.input(q, which, m * d * d, d * d)?)?;
                let y = forward(&self.map.layers, input.as_tensor())?;
                for i in 0..d {
                    let grads = y.narrow(1, i, 1)?.sum_all()?.backward()?;
                    let g = grads
                        .get(input.as_tensor())
                        .ok_or_else(|| RomError::Network("no input gradient".into()))?
                        .flatten_all()?
                        .to_vec1::<f64>()?;
                    let s = self.map.output_scale[i];
                    for (pt, row) in g.chunks_exact(d + l).enumerate() {
                        let f = &mut gradients[pt * d * d + i * d..pt * d * d + (i + 1) * d];
                        for ((f, r), h) in f.iter_mut().zip(&row[..d]).zip(&self.map.half_extent) {
                            *f = s * r / h;
                        }
                        f[i] += 1.0;
                        let jac = &mut jacobians[pt * d * l + i * l..pt * d * l + (i + 1) * l];
                        for ((j, r), sd) in jac.iter_mut().zip(&row[d..]).zip(&self.map.latent_std)
                        {
                            *j = s * r / sd;
                        }
                    }
                }
            } else {
                self.input(q, which, 0, d * d)?;
            }
            self.cache = Some(Derivatives {
                q: q.to_vec(),
                which: which.to_vec(),
                gradients,
                jacobians,
            });
        }
        self.cache
            .as_ref()
            .ok_or_else(|| RomError::Network("derivative cache missing".into()))
    }
}

impl PointMap for BoundNeural<'_> {
    fn len(&self) -> usize {
        self.reference.len() / self.map.dimension
    }

    fn positions(&mut self, q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError> {
        let d = self.map.dimension;
        let input = self.input(q, which, out.len(), d)?;
        if which.is_empty() {
            return Ok(());
        }
        let y = forward(&self.map.layers, &input)?
            .flatten_all()?
            .to_vec1::<f64>()?;
        for ((o, yv), &i) in out.chunks_exact_mut(d).zip(y.chunks_exact(d)).zip(which) {
            let x = &self.reference[i as usize * d..(i as usize + 1) * d];
            for (((o, x), s), y) in o.iter_mut().zip(x).zip(&self.map.output_scale).zip(yv) {
                *o = x + s * y;
            }
        }
        Ok(())
    }

    fn gradients(&mut self, q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError> {
        let d = self.map.dimension;
        if out.len() != which.len() * d * d {
            return Err(RomError::Option(format!(
                "gradient output holds {} values, expected {}",
                out.len(),
                which.len() * d * d
            )));
        }
        out.copy_from_slice(&self.derivatives(q, which)?.gradients);
        Ok(())
    }

    fn jacobians(&mut self, q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError> {
        let n = which.len() * self.map.dimension * self.map.latent;
        if out.len() != n {
            return Err(RomError::Option(format!(
                "jacobian output holds {} values, expected {n}",
                out.len()
            )));
        }
        out.copy_from_slice(&self.derivatives(q, which)?.jacobians);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Grid of n × n points on [0, 1]².
    fn grid(n: usize) -> Vec<f64> {
        let h = 1.0 / (n - 1) as f64;
        (0..n * n)
            .flat_map(|i| [(i % n) as f64 * h, (i / n) as f64 * h])
            .collect()
    }

    /// Smooth 2D snapshots x = X + a u₁(X) + a² u₂(X), one per amplitude.
    fn snapshots(reference: &[f64], amplitudes: &[f64]) -> Vec<f64> {
        let pi = std::f64::consts::PI;
        let mut out = Vec::new();
        for &a in amplitudes {
            for x in reference.chunks_exact(2) {
                let u = 0.1 * (pi * x[0]).sin() * (0.5 * pi * x[1]).cos();
                let v = 0.1 * (pi * x[1]).sin() + 0.05 * (pi * x[0] * x[1]).cos();
                out.push(x[0] + a * u + 0.3 * a * a * v);
                out.push(x[1] + a * v - 0.2 * a * u);
            }
        }
        out
    }

    /// A briefly trained small map of dimension `d`, for derivative and file tests.
    fn small_map(d: usize, latent: usize) -> NeuralMap {
        let p = 30;
        let mut rng = SplitMix(7);
        let reference: Vec<f64> = (0..p * d).map(|_| rng.uniform()).collect();
        let s = 4;
        let codes: Vec<f64> = (0..s * latent).map(|_| rng.uniform() - 0.5).collect();
        let snaps: Vec<f64> = (0..s)
            .flat_map(|k| {
                let c = codes[k * latent];
                reference
                    .iter()
                    .enumerate()
                    .map(move |(i, x)| x + 0.1 * c * (3.0 * x + i as f64).sin())
                    .collect::<Vec<_>>()
            })
            .collect();
        let options = NeuralOptions {
            width: 16,
            hidden_layers: 2,
            epochs: 5,
            ..Default::default()
        };
        let (map, _) = NeuralMap::train(
            d,
            &reference,
            &snaps,
            latent,
            &codes,
            &options,
            &mut |_, _| {},
        )
        .expect("training");
        map
    }

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

    #[test]
    fn neural_derivatives_match_finite_differences() {
        for (d, l) in [(2, 3), (3, 2)] {
            let map = small_map(d, l);
            let mut rng = SplitMix(11);
            let n = 12;
            let reference: Vec<f64> = (0..n * d).map(|_| 1.2 * rng.uniform() - 0.1).collect();
            let q: Vec<f64> = (0..l).map(|_| rng.uniform() - 0.5).collect();
            let which = [5u32, 0, 11, 3];
            let mut bound = map.bind(&reference).expect("bind");
            let m = which.len();
            let mut f = vec![0.0; m * d * d];
            let mut jac = vec![0.0; m * d * l];
            bound.gradients(&q, &which, &mut f).expect("gradients");
            bound.jacobians(&q, &which, &mut jac).expect("jacobians");
            let h = 1e-5;
            let (mut plus, mut minus) = (vec![0.0; m * d], vec![0.0; m * d]);
            let mut worst: f64 = 0.0;
            // ∂x/∂q by central differences in q.
            for k in 0..l {
                let mut qp = q.clone();
                qp[k] += h;
                bound.positions(&qp, &which, &mut plus).expect("positions");
                qp[k] -= 2.0 * h;
                bound.positions(&qp, &which, &mut minus).expect("positions");
                for pt in 0..m {
                    for i in 0..d {
                        let fd = (plus[pt * d + i] - minus[pt * d + i]) / (2.0 * h);
                        let ad = jac[pt * d * l + i * l + k];
                        worst = worst.max((fd - ad).abs() / ad.abs().max(1e-2));
                    }
                }
            }
            // ∂x/∂X by central differences of the reference point.
            for j in 0..d {
                let mut moved = reference.clone();
                let mut back = reference.clone();
                for &i in &which {
                    moved[i as usize * d + j] += h;
                    back[i as usize * d + j] -= h;
                }
                map.bind(&moved)
                    .and_then(|mut b| b.positions(&q, &which, &mut plus))
                    .expect("positions");
                map.bind(&back)
                    .and_then(|mut b| b.positions(&q, &which, &mut minus))
                    .expect("positions");
                for pt in 0..m {
                    for i in 0..d {
                        let fd = (plus[pt * d + i] - minus[pt * d + i]) / (2.0 * h);
                        let ad = f[pt * d * d + i * d + j];
                        worst = worst.max((fd - ad).abs() / ad.abs().max(1e-2));
                    }
                }
            }
            println!("d = {d}: worst relative derivative error {worst:.2e}");
            assert!(worst < 1e-6, "d = {d}: worst relative error {worst:e}");
            // A different subset after a cached one: fresh results, consistent with the first.
            let mut one = vec![0.0; d * l];
            bound.jacobians(&q, &[11], &mut one).expect("jacobians");
            assert_eq!(one, jac[2 * d * l..3 * d * l]);
        }
    }

    #[test]
    fn neural_fit_reproduces_snapshots() {
        let reference = grid(20);
        let amplitudes: Vec<f64> = (0..10).map(|k| -1.0 + 2.0 * k as f64 / 9.0).collect();
        let snaps = snapshots(&reference, &amplitudes);
        let options = NeuralOptions {
            width: 32,
            hidden_layers: 2,
            epochs: 1500,
            learning_rate: 5e-3,
            batch_points: 200,
            seed: 3,
        };
        let mut epochs = 0;
        let mut last = f64::NAN;
        let start = std::time::Instant::now();
        let (map, codes) = NeuralMap::train(
            2,
            &reference,
            &snaps,
            1,
            &amplitudes,
            &options,
            &mut |e, mse| {
                epochs = e;
                last = mse;
            },
        )
        .expect("training");
        let seconds = start.elapsed().as_secs_f64();
        assert_eq!(epochs, options.epochs);
        // Evaluate every snapshot at its trained code.
        let p = reference.len() / 2;
        let which: Vec<u32> = (0..p as u32).collect();
        let mut bound = map.bind(&reference).expect("bind");
        let mut x = vec![0.0; p * 2];
        let (mut err, mut disp) = (0.0, 0.0);
        for (s, code) in codes.iter().enumerate() {
            bound
                .positions(&[*code], &which, &mut x)
                .expect("positions");
            let snap = &snaps[s * p * 2..(s + 1) * p * 2];
            for ((a, b), r) in x.iter().zip(snap).zip(&reference) {
                err += (a - b).powi(2);
                disp += (b - r).powi(2);
            }
        }
        let relative = (err / disp).sqrt();
        println!(
            "fit: {seconds:.2} s, last epoch mse {last:.3e} m², relative RMS error {relative:.4}"
        );
        // Tolerance: RMS position error below 5% of the RMS displacement.
        assert!(relative < 0.05, "relative RMS error {relative}");
    }

    #[test]
    fn neural_round_trip_and_bad_models() {
        let map = small_map(2, 2);
        let (info, arrays) = map.to_arrays();
        // Training is deterministic for a given seed.
        assert_eq!(small_map(2, 2).to_arrays(), (info.clone(), arrays.clone()));
        let path = Path::new("model.safetensors");
        let back = NeuralMap::from_arrays(path, &info, arrays.clone()).expect("from_arrays");
        let reference = grid(5);
        let which: Vec<u32> = (0..25).collect();
        let (mut a, mut b) = (vec![0.0; 50], vec![0.0; 50]);
        let q = [0.3, -0.2];
        map.bind(&reference)
            .and_then(|mut m| m.positions(&q, &which, &mut a))
            .expect("positions");
        back.bind(&reference)
            .and_then(|mut m| m.positions(&q, &which, &mut b))
            .expect("positions");
        assert_eq!(a, b);
        let is_bad = |r: Result<NeuralMap, RomError>| matches!(r, Err(RomError::BadModel { .. }));
        let mut missing = arrays.clone();
        missing.remove(1);
        assert!(is_bad(NeuralMap::from_arrays(path, &info, missing)));
        let mut wrong = arrays.clone();
        wrong[0].shape.reverse();
        assert!(is_bad(NeuralMap::from_arrays(path, &info, wrong)));
        let mut info_bad = info.clone();
        info_bad["activation"] = "relu".into();
        assert!(is_bad(NeuralMap::from_arrays(
            path,
            &info_bad,
            arrays.clone()
        )));
        let mut info_bad = info.clone();
        info_bad["latent_std"] = serde_json::json!([1.0]);
        assert!(is_bad(NeuralMap::from_arrays(path, &info_bad, arrays)));
    }

    #[test]
    fn neural_bad_input_is_an_error() {
        let reference = grid(3);
        let codes = [0.0, 1.0];
        let snaps = snapshots(&reference, &codes);
        let options = NeuralOptions {
            epochs: 1,
            width: 4,
            ..Default::default()
        };
        let train = |r: &[f64], s: &[f64], l: usize, c: &[f64]| {
            NeuralMap::train(2, r, s, l, c, &options, &mut |_, _| {})
        };
        assert!(train(&reference, &snaps[1..], 1, &codes).is_err());
        assert!(train(&reference[1..], &snaps, 1, &codes).is_err());
        assert!(train(&reference, &snaps, 2, &codes[..1]).is_err());
        assert!(train(&reference, &snaps, 0, &codes).is_err());
        let mut nan = snaps.clone();
        nan[7] = f64::NAN;
        assert!(matches!(
            train(&reference, &nan, 1, &codes),
            Err(RomError::Training(_))
        ));
        let (map, _) = train(&reference, &snaps, 1, &codes).expect("training");
        assert!(map.bind(&reference[1..]).is_err());
        let mut bound = map.bind(&reference).expect("bind");
        let mut out = vec![0.0; 4];
        assert!(bound.positions(&[0.0, 1.0], &[0, 1], &mut out).is_err());
        assert!(bound.positions(&[0.0], &[0, 9], &mut out).is_err());
        assert!(bound.positions(&[0.0], &[0], &mut out).is_err());
        assert!(bound.gradients(&[0.0], &[0, 1], &mut out[..3]).is_err());
        assert!(bound.jacobians(&[0.0], &[0, 1], &mut out[..3]).is_err());
        assert!(bound.positions(&[0.0], &[], &mut []).is_ok());
        assert!(bound.gradients(&[0.0], &[], &mut []).is_ok());
    }

    /// Timing at the intended scale: `cargo test --release neural_benchmark -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn neural_benchmark() {
        let (s, p, latent) = (200, 2000, 8);
        let mut rng = SplitMix(1);
        let reference: Vec<f64> = (0..p * 2).map(|_| rng.uniform()).collect();
        let codes: Vec<f64> = (0..s * latent).map(|_| rng.uniform() - 0.5).collect();
        let mut snaps = Vec::with_capacity(s * p * 2);
        for c in codes.chunks_exact(latent) {
            for x in reference.chunks_exact(2) {
                let a: f64 = c
                    .iter()
                    .enumerate()
                    .map(|(k, v)| v * (k as f64 * x[0]).sin())
                    .sum();
                snaps.push(x[0] + 0.05 * a);
                snaps.push(x[1] + 0.05 * a * x[1]);
            }
        }
        let epochs = std::env::var("NEURAL_BENCH_EPOCHS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(300);
        let options = NeuralOptions {
            epochs,
            ..Default::default()
        };
        let start = std::time::Instant::now();
        let mut last = 0.0;
        NeuralMap::train(
            2,
            &reference,
            &snaps,
            latent,
            &codes,
            &options,
            &mut |e, mse| {
                last = mse;
                if e % 50 == 0 {
                    println!(
                        "epoch {e}: mse {mse:.3e}, {:.1} s",
                        start.elapsed().as_secs_f64()
                    );
                }
            },
        )
        .expect("training");
        println!("{} s, final mse {last:.3e}", start.elapsed().as_secs_f64());
    }
}
