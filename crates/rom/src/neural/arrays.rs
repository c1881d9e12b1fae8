//! The neural map in the model file: its description (JSON) and weights as named float64
//! arrays, written and read back with checks.

use super::NeuralMap;
use crate::RomError;
use crate::file::NamedArray;
use candle_core::{Device, Tensor};
use std::path::Path;

/// Name of the activation stored in the description (the only one supported).
const ACTIVATION: &str = "tanh";

impl NeuralMap {
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
