//! Training of the neural map: input and output normalisation from the snapshots, seeded
//! Glorot initialisation, and AdamW over the weights and the per-snapshot latent codes
//! jointly (an auto-decoder) with a cosine learning-rate schedule.

use super::rng::SplitMix;
use super::{NeuralMap, NeuralOptions, forward};
use crate::RomError;
use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};

/// Rows (points over all snapshots of a step) per optimiser step, roughly.
const ROWS_PER_STEP: usize = 1024;
/// Final learning rate of the cosine schedule, relative to `learning_rate`.
const FINAL_LR_FRACTION: f64 = 0.05;

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
}
