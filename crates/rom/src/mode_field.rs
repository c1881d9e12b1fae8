//! The linear map x = X + Σ_k q_k·φ_k(X): each POD mode is a continuous field of the
//! reference position, stored as quadratic B-spline coefficients on a regular grid over the
//! training particles' box. Between particles it interpolates; its gradient (the
//! deformation gradient F = I + Σ_k q_k ∇φ_k) is continuous.

use crate::RomError;
use crate::map::{PointMap, ReducedMap};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The regular grid of B-spline coefficients, in the reference configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModeGrid {
    /// 2 or 3.
    pub dimension: usize,
    /// Position of node (0, 0, 0).
    pub origin: Vec<f64>,
    /// Node spacing, metres.
    pub spacing: f64,
    /// Nodes along each axis (1 along unused axes).
    pub nodes: [usize; 3],
}

/// Quadratic B-spline weights and derivatives (per unit of grid coordinate) along one axis.
#[inline(always)]
fn axis_weights(xi: f64) -> (isize, [f64; 3], [f64; 3]) {
    let base = (xi - 0.5).floor();
    let fx = xi - base;
    let a = 1.5 - fx;
    let b = fx - 1.0;
    let c = fx - 0.5;
    (
        base as isize,
        [0.5 * a * a, 0.75 - b * b, 0.5 * c * c],
        [-a, -2.0 * b, c],
    )
}

/// The nodes and weights of one point: up to 27 (node, weight, weight gradient).
struct Stencil {
    count: usize,
    node: [u32; 27],
    w: [f64; 27],
    dw: [[f64; 3]; 27],
}

impl ModeGrid {
    /// A grid of spacing `spacing` covering `points` with room for the kernel at the edges.
    pub fn covering(dimension: usize, points: &[f64], spacing: f64) -> Result<Self, RomError> {
        if spacing.is_nan() || spacing <= 0.0 || !spacing.is_finite() {
            return Err(RomError::Option(format!(
                "mode grid spacing must be positive, got {spacing}"
            )));
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points.chunks_exact(dimension) {
            for d in 0..dimension {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let mut origin = vec![0.0; dimension];
        let mut nodes = [1usize; 3];
        for d in 0..dimension {
            // One node beyond the outermost particle's stencil on each side.
            origin[d] = lo[d] - 1.5 * spacing;
            nodes[d] = ((hi[d] - origin[d]) / spacing + 1.5).ceil() as usize + 1;
        }
        let count = nodes.iter().product::<usize>();
        if count > 50_000_000 {
            return Err(RomError::Option(format!(
                "a mode grid of spacing {spacing} m would have {count} nodes; use a coarser one"
            )));
        }
        Ok(Self {
            dimension,
            origin,
            spacing,
            nodes,
        })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.iter().product()
    }

    /// Whether the grid has no node (never for a built grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the whole kernel stencil of `x` lies on the grid.
    pub fn contains(&self, x: &[f64]) -> bool {
        (0..self.dimension).all(|d| {
            let xi = (x[d] - self.origin[d]) / self.spacing;
            let base = (xi - 0.5).floor();
            base >= 0.0 && base + 2.0 < self.nodes[d] as f64
        })
    }

    fn stencil(&self, x: &[f64]) -> Stencil {
        let dim = self.dimension;
        let inv = 1.0 / self.spacing;
        let mut axes = [(0isize, [1.0, 0.0, 0.0], [0.0; 3]); 3];
        let mut span = [1usize; 3];
        for d in 0..dim {
            axes[d] = axis_weights((x[d] - self.origin[d]) * inv);
            span[d] = 3;
        }
        let stride = [self.nodes[1] * self.nodes[2], self.nodes[2], 1];
        let mut s = Stencil {
            count: 0,
            node: [0; 27],
            w: [0.0; 27],
            dw: [[0.0; 3]; 27],
        };
        for a in 0..span[0] {
            for b in 0..span[1] {
                for c in 0..span[2] {
                    let idx = [a, b, c];
                    let mut node = 0usize;
                    let mut w = 1.0;
                    let mut grad = [1.0; 3];
                    for d in 0..3 {
                        let (base, ww, dw) = axes[d];
                        let i = if d < dim {
                            (base + idx[d] as isize) as usize
                        } else {
                            0
                        };
                        node += i * stride[d];
                        w *= ww[idx[d]];
                        for (e, g) in grad.iter_mut().enumerate() {
                            *g *= if e == d { dw[idx[d]] * inv } else { ww[idx[d]] };
                        }
                    }
                    s.node[s.count] = node as u32;
                    s.w[s.count] = w;
                    s.dw[s.count] = grad;
                    s.count += 1;
                }
            }
        }
        s
    }
}

/// POD modes as B-spline fields: the linear reduced map.
#[derive(Clone, Debug)]
pub struct LinearMap {
    /// The coefficient grid.
    pub grid: ModeGrid,
    /// Number of modes.
    pub latent: usize,
    /// Coefficients, `[node][mode][axis]`.
    pub coefficients: Vec<f64>,
}

/// How well the fitted fields reproduce the modes at the training particles.
#[derive(Clone, Copy, Debug)]
pub struct FitReport {
    /// RMS misfit over particles and modes, relative to the modes' RMS (which is 1).
    pub relative_rms: f64,
    /// Conjugate-gradient iterations taken.
    pub iterations: usize,
}

impl LinearMap {
    /// Fits B-spline fields of spacing `spacing` to `modes` (`[mode][particle][axis]`) given
    /// at `reference`, by least squares with a small smoothing term that fills nodes no
    /// particle reaches (conjugate gradients on the normal equations, all fields at once).
    pub fn fit(
        dimension: usize,
        reference: &[f64],
        modes: &[f64],
        latent: usize,
        spacing: f64,
    ) -> Result<(Self, FitReport), RomError> {
        let grid = ModeGrid::covering(dimension, reference, spacing)?;
        let particles = reference.len() / dimension;
        let width = latent * dimension;
        let nodes = grid.len();
        let stencils: Vec<Stencil> = reference
            .par_chunks_exact(dimension)
            .map(|x| grid.stencil(x))
            .collect();
        // Right-hand side Aᵀφ and the diagonal of AᵀA.
        let mut rhs = vec![0.0; nodes * width];
        let mut diag = vec![0.0; nodes];
        for (p, s) in stencils.iter().enumerate() {
            for k in 0..s.count {
                let node = s.node[k] as usize;
                diag[node] += s.w[k] * s.w[k];
                for m in 0..latent {
                    for d in 0..dimension {
                        rhs[node * width + m * dimension + d] +=
                            s.w[k] * modes[(m * particles + p) * dimension + d];
                    }
                }
            }
        }
        if width > 64 {
            return Err(RomError::Option(format!(
                "latent × dimension = {width} exceeds 64; use fewer modes"
            )));
        }
        let supported = diag.iter().filter(|v| **v > 0.0).count().max(1);
        let mean_diag = diag.iter().sum::<f64>() / supported as f64;
        // Smoothing: alpha times the grid graph Laplacian.
        let alpha = 1e-4 * mean_diag;
        let stride = [grid.nodes[1] * grid.nodes[2], grid.nodes[2], 1];
        let neighbours = |i: usize, f: &mut dyn FnMut(usize)| {
            let ijk = [
                i / stride[0],
                (i / stride[1]) % grid.nodes[1],
                i % grid.nodes[2],
            ];
            for d in 0..dimension {
                if ijk[d] > 0 {
                    f(i - stride[d]);
                }
                if ijk[d] + 1 < grid.nodes[d] {
                    f(i + stride[d]);
                }
            }
        };
        let mut inverse_diag = vec![0.0; nodes];
        for (i, inv) in inverse_diag.iter_mut().enumerate() {
            let mut count = 0usize;
            neighbours(i, &mut |_| count += 1);
            *inv = 1.0 / (diag[i] + alpha * count as f64);
        }
        let apply = |x: &[f64], out: &mut [f64]| {
            out.fill(0.0);
            let mut value = vec![0.0; width];
            for s in &stencils {
                value.fill(0.0);
                for k in 0..s.count {
                    let row = &x[s.node[k] as usize * width..][..width];
                    for (v, r) in value.iter_mut().zip(row) {
                        *v += s.w[k] * r;
                    }
                }
                for k in 0..s.count {
                    let row = &mut out[s.node[k] as usize * width..][..width];
                    for (o, v) in row.iter_mut().zip(&value) {
                        *o += s.w[k] * v;
                    }
                }
            }
            for i in 0..nodes {
                let xi = &x[i * width..(i + 1) * width];
                let mut acc = [0.0f64; 64];
                let acc = &mut acc[..width.min(64)];
                let mut count = 0.0;
                neighbours(i, &mut |j| {
                    count += 1.0;
                    for (a, xj) in acc.iter_mut().zip(&x[j * width..]) {
                        *a -= xj;
                    }
                });
                for (c, (a, xv)) in acc.iter().zip(xi).enumerate() {
                    out[i * width + c] += alpha * (count * xv + a);
                }
            }
        };
        let mut x = vec![0.0; nodes * width];
        for i in 0..nodes {
            for c in 0..width {
                x[i * width + c] = rhs[i * width + c] * inverse_diag[i];
            }
        }
        let iterations = block_cg(apply, &inverse_diag, &rhs, &mut x, width, 1e-10, 2000);
        let map = LinearMap {
            grid,
            latent,
            coefficients: x,
        };
        // Misfit at the particles.
        let mut err2 = 0.0;
        for (p, s) in stencils.iter().enumerate() {
            for m in 0..latent {
                for d in 0..dimension {
                    let mut v = 0.0;
                    for k in 0..s.count {
                        v += s.w[k]
                            * map.coefficients[s.node[k] as usize * width + m * dimension + d];
                    }
                    let e = v - modes[(m * particles + p) * dimension + d];
                    err2 += e * e;
                }
            }
        }
        let relative_rms = (err2 / (particles * latent) as f64).sqrt();
        Ok((
            map,
            FitReport {
                relative_rms,
                iterations,
            },
        ))
    }

    /// Values φ (and gradients ∇φ when `gradient` is given) of every mode at `x`:
    /// `value[m*dim + i]`, `gradient[(m*dim + i)*dim + j] = ∂φ_{m,i}/∂X_j`.
    fn evaluate(&self, x: &[f64], value: &mut [f64], gradient: Option<&mut [f64]>) {
        let dim = self.grid.dimension;
        let width = self.latent * dim;
        let s = self.grid.stencil(x);
        value.fill(0.0);
        for k in 0..s.count {
            let row = &self.coefficients[s.node[k] as usize * width..][..width];
            for (v, r) in value.iter_mut().zip(row) {
                *v += s.w[k] * r;
            }
        }
        if let Some(g) = gradient {
            g.fill(0.0);
            for k in 0..s.count {
                let row = &self.coefficients[s.node[k] as usize * width..][..width];
                for (c, r) in row.iter().enumerate() {
                    for j in 0..dim {
                        g[c * dim + j] += s.dw[k][j] * r;
                    }
                }
            }
        }
    }
}

/// Conjugate gradients for `width` right-hand sides at once (row-major `[node][column]`),
/// Jacobi-preconditioned; each column has its own step lengths. Returns the iterations.
fn block_cg(
    apply: impl Fn(&[f64], &mut [f64]),
    inverse_diag: &[f64],
    b: &[f64],
    x: &mut [f64],
    width: usize,
    tolerance: f64,
    max_iterations: usize,
) -> usize {
    let n = b.len();
    let mut r = vec![0.0; n];
    let mut z = vec![0.0; n];
    let mut p = vec![0.0; n];
    let mut ap = vec![0.0; n];
    apply(x, &mut ap);
    for i in 0..n {
        r[i] = b[i] - ap[i];
        z[i] = r[i] * inverse_diag[i / width];
    }
    p.copy_from_slice(&z);
    let column_dot = |a: &[f64], b: &[f64]| {
        let mut out = vec![0.0; width];
        for (i, (x, y)) in a.iter().zip(b).enumerate() {
            out[i % width] += x * y;
        }
        out
    };
    let b_norm = column_dot(b, b);
    let mut rz = column_dot(&r, &z);
    for it in 0..max_iterations {
        let r2 = column_dot(&r, &r);
        if r2
            .iter()
            .zip(&b_norm)
            .all(|(r, b)| *r <= tolerance * tolerance * b.max(1e-300))
        {
            return it;
        }
        apply(&p, &mut ap);
        let pap = column_dot(&p, &ap);
        let alpha: Vec<f64> = rz
            .iter()
            .zip(&pap)
            .map(|(a, b)| if *b > 0.0 { a / b } else { 0.0 })
            .collect();
        for i in 0..n {
            let c = i % width;
            x[i] += alpha[c] * p[i];
            r[i] -= alpha[c] * ap[i];
            z[i] = r[i] * inverse_diag[i / width];
        }
        let rz_new = column_dot(&r, &z);
        let beta: Vec<f64> = rz_new
            .iter()
            .zip(&rz)
            .map(|(a, b)| if *b > 0.0 { a / b } else { 0.0 })
            .collect();
        for i in 0..n {
            p[i] = z[i] + beta[i % width] * p[i];
        }
        rz = rz_new;
    }
    max_iterations
}

impl ReducedMap for LinearMap {
    fn dimension(&self) -> usize {
        self.grid.dimension
    }
    fn latent(&self) -> usize {
        self.latent
    }
    fn bind(&self, reference: &[f64]) -> Result<Box<dyn PointMap + '_>, RomError> {
        let dim = self.grid.dimension;
        if let Some(p) = reference
            .chunks_exact(dim)
            .position(|x| !self.grid.contains(x))
        {
            let x = &reference[p * dim..(p + 1) * dim];
            return Err(RomError::Mismatch {
                path: "bodies".into(),
                message: format!(
                    "particle {p} at {x:?} lies outside the region the model was trained on \
                     (mode grid from {:?}, spacing {} m)",
                    self.grid.origin, self.grid.spacing
                ),
            });
        }
        let width = self.latent * dim;
        let mut values = vec![0.0; reference.len() / dim * width];
        let mut gradients = vec![0.0; reference.len() / dim * width * dim];
        values
            .par_chunks_mut(width)
            .zip(gradients.par_chunks_mut(width * dim))
            .zip(reference.par_chunks_exact(dim))
            .for_each(|((v, g), x)| self.evaluate(x, v, Some(g)));
        Ok(Box::new(BoundLinear {
            dim,
            latent: self.latent,
            reference: reference.to_vec(),
            values,
            gradients,
        }))
    }
}

/// A linear map bound to points: mode values and gradients cached per point, so a step
/// costs a few multiply-adds per mode.
struct BoundLinear {
    dim: usize,
    latent: usize,
    reference: Vec<f64>,
    values: Vec<f64>,
    gradients: Vec<f64>,
}

impl BoundLinear {
    /// out_p = base_p + Σ_m c_m · block_p,m for every listed point, in parallel; `block` is
    /// the per-point cache (`stride` numbers per point, `width` per mode).
    fn combine(
        cache: &[f64],
        stride: usize,
        width: usize,
        coefficients: &[f64],
        which: &[u32],
        out: &mut [f64],
        base: impl Fn(usize, &mut [f64]) + Sync,
    ) {
        const CHUNK: usize = 512;
        out.par_chunks_mut(CHUNK * width)
            .zip(which.par_chunks(CHUNK))
            .for_each(|(out, which)| {
                for (o, &p) in out.chunks_exact_mut(width).zip(which) {
                    let p = p as usize;
                    base(p, o);
                    let block = &cache[p * stride..(p + 1) * stride];
                    for (c, values) in coefficients.iter().zip(block.chunks_exact(width)) {
                        for (o, v) in o.iter_mut().zip(values) {
                            *o += c * v;
                        }
                    }
                }
            });
    }
}

impl PointMap for BoundLinear {
    fn len(&self) -> usize {
        self.reference.len() / self.dim
    }
    fn positions(&mut self, q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError> {
        let dim = self.dim;
        let reference = &self.reference;
        Self::combine(
            &self.values,
            self.latent * dim,
            dim,
            q,
            which,
            out,
            |p, o| o.copy_from_slice(&reference[p * dim..(p + 1) * dim]),
        );
        Ok(())
    }
    fn velocities(
        &mut self,
        _q: &[f64],
        q_rate: &[f64],
        which: &[u32],
        out: &mut [f64],
    ) -> Result<(), RomError> {
        let dim = self.dim;
        Self::combine(
            &self.values,
            self.latent * dim,
            dim,
            q_rate,
            which,
            out,
            |_, o| o.fill(0.0),
        );
        Ok(())
    }
    fn gradients(&mut self, q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError> {
        let dim = self.dim;
        Self::combine(
            &self.gradients,
            self.latent * dim * dim,
            dim * dim,
            q,
            which,
            out,
            |_, o| {
                o.fill(0.0);
                for i in 0..dim {
                    o[i * dim + i] = 1.0;
                }
            },
        );
        Ok(())
    }
    fn jacobians(&mut self, _q: &[f64], which: &[u32], out: &mut [f64]) -> Result<(), RomError> {
        let (dim, latent) = (self.dim, self.latent);
        let width = latent * dim;
        for (o, &p) in out.chunks_exact_mut(width).zip(which) {
            let v = &self.values[p as usize * width..(p as usize + 1) * width];
            for i in 0..dim {
                for m in 0..latent {
                    o[i * latent + m] = v[m * dim + i];
                }
            }
        }
        Ok(())
    }
    fn gradient_rates(
        &mut self,
        _q: &[f64],
        q_rate: &[f64],
        which: &[u32],
        out: &mut [f64],
    ) -> Result<(), RomError> {
        let dim = self.dim;
        Self::combine(
            &self.gradients,
            self.latent * dim * dim,
            dim * dim,
            q_rate,
            which,
            out,
            |_, o| o.fill(0.0),
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a jittered lattice in [0, 1]², two per cell of 0.1.
    fn points() -> Vec<f64> {
        let mut p = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                let jitter = 0.01 * (((i * 7 + j * 13) % 5) as f64 - 2.0) / 2.0;
                p.push(0.025 + 0.05 * i as f64 + jitter);
                p.push(0.025 + 0.05 * j as f64 - jitter);
            }
        }
        p
    }

    #[test]
    fn fitted_fields_reproduce_smooth_modes_with_their_gradients() {
        // Two modes: a linear field (which quadratic B-splines hold exactly; the smoothing
        // term, 1e-4 of the mean diagonal, biases the fit by about 1e-5) and a smooth bending
        // field. Tolerances: 1e-4 for the linear one, 1% of the amplitude for the sine,
        // checked between the particles and on the gradient.
        let x = points();
        let n = x.len() / 2;
        let mut modes = vec![0.0; 2 * n * 2];
        for p in 0..n {
            let (a, b) = (x[2 * p], x[2 * p + 1]);
            modes[2 * p] = 0.3 * a + 0.1 * b;
            modes[2 * p + 1] = -0.2 * b;
            modes[(n + p) * 2] = (std::f64::consts::PI * b).sin();
            modes[(n + p) * 2 + 1] = 0.0;
        }
        let (map, report) = LinearMap::fit(2, &x, &modes, 2, 0.05).unwrap();
        assert!(report.relative_rms < 1e-3, "misfit {}", report.relative_rms);
        let probe = [0.4321, 0.6123];
        let mut value = vec![0.0; 4];
        let mut gradient = vec![0.0; 8];
        map.evaluate(&probe, &mut value, Some(&mut gradient));
        let (a, b) = (probe[0], probe[1]);
        assert!((value[0] - (0.3 * a + 0.1 * b)).abs() < 1e-4, "{value:?}");
        assert!((value[1] + 0.2 * b).abs() < 1e-4, "{value:?}");
        let g = &gradient;
        assert!(
            (g[0] - 0.3).abs() < 1e-3 && (g[1] - 0.1).abs() < 1e-3,
            "{g:?}"
        );
        let pi = std::f64::consts::PI;
        assert!((value[2] - (pi * b).sin()).abs() < 1e-2, "{}", value[2]);
        assert!(
            (gradient[5] - pi * (pi * b).cos()).abs() < 0.05 * pi,
            "{}",
            gradient[5]
        );
    }

    #[test]
    fn bound_map_matches_direct_evaluation_and_refuses_outside_points() {
        let x = points();
        let n = x.len() / 2;
        let modes: Vec<f64> = (0..2 * n).map(|i| x[i] * x[i]).collect();
        let (map, _) = LinearMap::fit(2, &x, &modes, 1, 0.05).unwrap();
        let probe = [0.3, 0.7, 0.55, 0.25];
        let mut bound = map.bind(&probe).unwrap();
        let mut out = vec![0.0; 4];
        bound.positions(&[0.5], &[1, 0], &mut out).unwrap();
        let mut value = vec![0.0; 2];
        map.evaluate(&probe[..2], &mut value, None);
        assert!((out[2] - (0.3 + 0.5 * value[0])).abs() < 1e-14);
        let mut v = vec![0.0; 2];
        bound.velocities(&[0.5], &[2.0], &[0], &mut v).unwrap();
        assert!((v[0] - 2.0 * value[0]).abs() < 1e-14);
        assert!(matches!(
            map.bind(&[3.0, 0.5]),
            Err(RomError::Mismatch { .. })
        ));
    }
}
