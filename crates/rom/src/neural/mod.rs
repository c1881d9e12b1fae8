//! The neural deformation map g(X, q) = X + s ⊙ MLP([X̂, q̂]): a small tanh network trained
//! on full-order snapshots as an auto-decoder (weights and per-snapshot latent codes jointly),
//! after Chen et al., "Model reduction for the material point method on nonlinear manifolds".
//! Network, training and all derivatives use candle (CPU, f64) and its automatic
//! differentiation.
//!
//! [`NeuralMap`] and [`NeuralOptions`] are defined here with the network's forward pass; the
//! activation is in `activation`, training in `training`, the model file's arrays in
//! `arrays` and evaluation with derivatives at bound points in `bound`.

mod activation;
mod arrays;
mod bound;
mod rng;
mod training;

use activation::BiasTanh;
use candle_core::Tensor;

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

impl NeuralMap {
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

#[cfg(test)]
mod tests;
