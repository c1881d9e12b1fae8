//! Evaluation of the neural map at bound reference points: positions g(X, q), and the
//! derivatives F = ∂g/∂X and ∂g/∂q by candle's automatic differentiation, cached for the
//! matching second call.

use super::{NeuralMap, forward};
use crate::RomError;
use crate::map::{PointMap, ReducedMap};
use candle_core::{Device, Tensor, Var};

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
