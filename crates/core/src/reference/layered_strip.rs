//! A free strip of any number of bonded layers under a uniform temperature change bends to
//! a constant curvature, with a stress in each layer linear through its thickness
//! (classical laminated-beam theory, the multilayer form of Timoshenko's 1925 bimaterial
//! strip): away from the free ends the axial strain is ε(y) = ε₀ + κ y, and force and
//! moment balance, Σᵢ Eᵢ ∫ (ε₀ + κ y − αᵢ ΔT) (1, y) dy = 0, give ε₀ and κ. In 2D (plane
//! strain) E → E/(1 − ν²) and α → (1 + ν) α (the physical plane strain,
//! `solver.free_strain_2d: plane_strain`); in 3D a plate free on all edges bends
//! biaxially, E → E/(1 − ν) (exact for equal ν). The die/underfill/substrate stack of the
//! underfill examples cooled from the cure temperature is the case it was written for.
//!
//! Measured: the curvature as in `bimaterial_strip` (a least-squares fit of the particles'
//! deflection over the inner `fit_fraction` of the half length), and each layer's mean σ
//! along the strip over the same particles, against the closed form's mean
//! Eᵢ (ε₀ + κ ȳᵢ − αᵢ ΔT) at the layer's mid-plane ȳᵢ. In 2D also each layer's mean σzz,
//! the stress across the plane that holds εzz = 0: σzz = νᵢ σxx − Eᵢ αᵢ ΔT (σyy = 0 in
//! the strip), which only a run with `free_strain_2d: plane_strain` and laws that give σzz
//! reaches. With `generalized_plane_strain` every layer has the same ε_zz = ε_c, with no net
//! force along z: each layer's in-plane free strain becomes (1 + ν)αΔT − ν ε_c, its
//! σzz = ν σxx + E (ε_c − αΔT), and ε_c solves Σ tᵢ σ̄zzᵢ = 0 (linear in ε_c).

use super::bimaterial_strip::fit_curvature;
use super::{Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory};
use crate::output::Comparison;
use crate::scene::{Issue, Scene};
use crate::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// One layer of a [`LayeredStripParams`], from the bottom up.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Layer {
    /// Thickness, m.
    pub thickness: f64,
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson's ratio.
    pub poisson_ratio: f64,
    /// Linear expansion coefficient, 1/K.
    pub expansion: f64,
}

/// Parameters of the `layered_strip` reference.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct LayeredStripParams {
    /// Axis along the strip.
    pub length_axis: usize,
    /// Axis across the layers.
    pub thickness_axis: usize,
    /// Coordinate of the strip's symmetry plane along `length_axis` (its mid-span).
    pub center: f64,
    /// Half length of the strip, m.
    pub half_length: f64,
    /// Coordinate of the bottom face of the first layer along `thickness_axis`.
    pub bottom: f64,
    /// The layers from the bottom up (at least two).
    pub layers: Vec<Layer>,
    /// Uniform temperature change from the stress-free state, K.
    pub temperature_change: f64,
    /// Fraction of the half length (from the symmetry plane) the fit and the means use.
    #[serde(default = "default_fit_fraction")]
    pub fit_fraction: f64,
    /// In 2D: the strip is a section under generalized plane strain (one strain ε_zz for
    /// every layer, no net force along z; `solver.free_strain_2d:
    /// generalized_plane_strain`) instead of plane strain (ε_zz = 0).
    #[serde(default)]
    pub generalized_plane_strain: bool,
}

fn default_fit_fraction() -> f64 {
    0.6
}

/// The laminated-beam solution for layers `(thickness, modulus, expansion)` (effective
/// moduli and expansions) from the bottom at y = 0 up: the strain ε₀ at y = 0 and the
/// curvature κ (positive when the upper layers expand more, bending towards the bottom).
pub fn layered_strip_solution(layers: &[(f64, f64, f64)], temperature_change: f64) -> (f64, f64) {
    let (mut a, mut b, mut c, mut force, mut moment) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut y0 = 0.0;
    for &(t, e, alpha) in layers {
        let y1 = y0 + t;
        let (m0, m1, m2) = (
            t,
            (y1 * y1 - y0 * y0) / 2.0,
            (y1.powi(3) - y0.powi(3)) / 3.0,
        );
        a += e * m0;
        b += e * m1;
        c += e * m2;
        force += e * alpha * temperature_change * m0;
        moment += e * alpha * temperature_change * m1;
        y0 = y1;
    }
    let det = a * c - b * b;
    (
        (force * c - moment * b) / det,
        (a * moment - b * force) / det,
    )
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct LayeredStrip {
    p: LayeredStripParams,
    expected: f64,
    /// The closed form's mean stress of each layer, Pa.
    expected_stress: Vec<f64>,
    measured: Option<f64>,
    measured_stress: Vec<f64>,
    /// In 2D, the closed form's mean σzz of each layer, Pa (empty in 3D).
    #[serde(default)]
    expected_stress_zz: Vec<f64>,
    #[serde(default)]
    measured_stress_zz: Vec<f64>,
}

impl ReferenceLaw for LayeredStrip {
    fn kind(&self) -> &'static str {
        "relative error of the curvature of a layered strip under a uniform temperature change (laminated-beam theory)"
    }

    fn needs_initial_positions(&self) -> bool {
        true
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if !frame.last {
            return;
        }
        let p = &self.p;
        let particles = frame.particles;
        self.measured = fit_curvature(
            particles,
            p.length_axis,
            p.thickness_axis,
            p.center,
            p.fit_fraction * p.half_length,
        );
        let (ax, at) = (p.length_axis, p.thickness_axis);
        let limit = p.fit_fraction * p.half_length;
        let mut sums = vec![(0.0, 0.0, 0.0); p.layers.len()];
        for i in 0..particles.len() {
            let x0 = particles.initial_position[i];
            if (x0[ax] - p.center).abs() > limit {
                continue;
            }
            let mut top = p.bottom;
            for (k, layer) in p.layers.iter().enumerate() {
                let below = top;
                top += layer.thickness;
                if x0[at] > below && x0[at] < top {
                    sums[k].0 += particles.stress[i][(ax, ax)];
                    sums[k].1 += 1.0;
                    sums[k].2 += particles.stress_zz.get(i).copied().unwrap_or(0.0);
                }
            }
        }
        let mean = |s: f64, n: f64| if n > 0.0 { s / n } else { f64::NAN };
        self.measured_stress = sums.iter().map(|&(s, n, _)| mean(s, n)).collect();
        if !self.expected_stress_zz.is_empty() {
            self.measured_stress_zz = sums.iter().map(|&(_, n, zz)| mean(zz, n)).collect();
        }
    }

    fn error(&self) -> Option<f64> {
        self.measured
            .map(|m| (m - self.expected).abs() / self.expected.abs().max(1e-300))
    }

    fn expected(&self) -> Option<f64> {
        Some(self.expected)
    }

    fn measured(&self) -> Option<f64> {
        self.measured
    }

    fn comparisons(&self) -> Vec<Comparison> {
        let compare = |name: &str, measured: &[f64], expected: &[f64]| {
            measured
                .iter()
                .zip(expected)
                .enumerate()
                .map(|(k, (&m, &r))| Comparison {
                    quantity: format!("layer_{k}_mean_{name}"),
                    measured: m,
                    reference: r,
                    relative_difference: (m - r) / r,
                })
                .collect::<Vec<_>>()
        };
        let mut out = compare("stress", &self.measured_stress, &self.expected_stress);
        out.extend(compare(
            "stress_zz",
            &self.measured_stress_zz,
            &self.expected_stress_zz,
        ));
        out
    }
}

fn build(
    p: LayeredStripParams,
    path: &str,
    scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let d = scene.dimension as usize;
    let mut c = Checks::new(path);
    c.axis("length_axis", p.length_axis, d);
    c.axis("thickness_axis", p.thickness_axis, d);
    if p.length_axis == p.thickness_axis {
        c.error("thickness_axis", "must differ from length_axis");
    }
    c.finite("center", p.center);
    c.positive("half_length", p.half_length);
    c.finite("bottom", p.bottom);
    if p.layers.len() < 2 {
        c.error("layers", "give at least two layers");
    }
    for (k, layer) in p.layers.iter().enumerate() {
        c.positive(&format!("layers[{k}].thickness"), layer.thickness);
        c.positive(&format!("layers[{k}].youngs_modulus"), layer.youngs_modulus);
        c.finite(&format!("layers[{k}].expansion"), layer.expansion);
        if !(layer.poisson_ratio > -1.0 && layer.poisson_ratio < 0.5) {
            c.error(
                &format!("layers[{k}].poisson_ratio"),
                "must lie in (-1, 0.5)",
            );
        }
    }
    c.finite("temperature_change", p.temperature_change);
    if !(p.fit_fraction > 0.0 && p.fit_fraction <= 1.0) {
        c.error("fit_fraction", "must lie in (0, 1]");
    }
    c.finish()?;
    if p.generalized_plane_strain && d != 2 {
        let mut c = Checks::new(path);
        c.error("generalized_plane_strain", "is for 2D scenes");
        c.finish()?;
    }
    let dt = p.temperature_change;
    // Effective layers for a strain `across` along z (2D): the in-plane expansion per
    // kelvin that gives (1 + ν)αΔT − ν·across.
    let effective = |across: f64| -> Vec<(f64, f64, f64)> {
        p.layers
            .iter()
            .map(|l| {
                let nu = l.poisson_ratio;
                if d == 2 {
                    let expansion = if dt != 0.0 {
                        (1.0 + nu) * l.expansion - nu * across / dt
                    } else {
                        (1.0 + nu) * l.expansion
                    };
                    (l.thickness, l.youngs_modulus / (1.0 - nu * nu), expansion)
                } else {
                    (l.thickness, l.youngs_modulus / (1.0 - nu), l.expansion)
                }
            })
            .collect()
    };
    // Each layer's mean σxx and σzz for a strain `across` along z.
    let layer_stresses = |across: f64| -> (f64, f64, Vec<f64>, Vec<f64>) {
        let layers = effective(across);
        let (strain, curvature) = layered_strip_solution(&layers, dt);
        let mut y = 0.0;
        let sxx: Vec<f64> = layers
            .iter()
            .map(|&(t, e, alpha)| {
                let mid = y + t / 2.0;
                y += t;
                e * (strain + curvature * mid - alpha * dt)
            })
            .collect();
        let szz = p
            .layers
            .iter()
            .zip(&sxx)
            .map(|(l, &s)| l.poisson_ratio * s + l.youngs_modulus * (across - l.expansion * dt))
            .collect();
        (strain, curvature, sxx, szz)
    };
    // ε_c: the net force along z is linear in it.
    let across = if p.generalized_plane_strain {
        let force = |across: f64| -> f64 {
            let (_, _, _, szz) = layer_stresses(across);
            p.layers
                .iter()
                .zip(&szz)
                .map(|(l, s)| l.thickness * s)
                .sum()
        };
        let (f0, f1) = (force(0.0), force(1e-3));
        -f0 * 1e-3 / (f1 - f0)
    } else {
        0.0
    };
    let (_, expected, expected_stress, szz) = layer_stresses(across);
    if expected == 0.0 || !expected.is_finite() {
        let mut c = Checks::new(path);
        c.error(
            "temperature_change",
            "the layers must bend: their expansions must differ and the temperature change must not be zero",
        );
        c.finish()?;
    }
    // σzz = ν σxx + E (ε_zz − α ΔT) with the layer's mean σxx (σyy = 0).
    let expected_stress_zz = if d == 2 { szz } else { Vec::new() };
    Ok(Arc::new(LayeredStrip {
        p,
        expected,
        expected_stress,
        measured: None,
        measured_stress: Vec::new(),
        expected_stress_zz,
        measured_stress_zz: Vec::new(),
    }))
}

/// The `layered_strip` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("layered_strip", build))
}

#[cfg(test)]
mod tests {
    use super::super::bimaterial_curvature;
    use super::*;

    #[test]
    fn two_layers_give_timoshenkos_curvature() {
        for (t, e, alpha) in [
            ([1e-3, 1e-3], [1e9, 1e9], [1e-5, 2e-5]),
            ([0.5e-3, 2e-3], [200e9, 70e9], [12e-6, 23e-6]),
        ] {
            let (_, k) =
                layered_strip_solution(&[(t[0], e[0], alpha[0]), (t[1], e[1], alpha[1])], 100.0);
            let expected = bimaterial_curvature(t, e, alpha, 100.0);
            assert!(
                (k - expected).abs() < 1e-10 * expected.abs(),
                "{k} vs {expected}"
            );
        }
    }

    #[test]
    fn the_stresses_balance_force_and_moment() {
        let layers = [
            (0.25e-3, 20e9, 15e-6),
            (0.05e-3, 8e9, 30e-6),
            (0.2e-3, 130e9, 2.6e-6),
        ];
        let dt = -125.0;
        let (e0, k) = layered_strip_solution(&layers, dt);
        let (mut force, mut moment, mut y) = (0.0, 0.0, 0.0);
        for (t, e, alpha) in layers {
            // Exact integrals of the linear stress over the layer.
            let (y0, y1) = (y, y + t);
            let s = |y: f64| e * (e0 + k * y - alpha * dt);
            force += (s(y0) + s(y1)) / 2.0 * t;
            moment += e
                * ((e0 - alpha * dt) * (y1 * y1 - y0 * y0) / 2.0
                    + k * (y1.powi(3) - y0.powi(3)) / 3.0);
            y = y1;
        }
        let scale = 130e9 * 2.6e-6 * 125.0 * 0.5e-3;
        assert!(force.abs() < 1e-9 * scale, "{force}");
        assert!(moment.abs() < 1e-9 * scale * 0.5e-3, "{moment}");
        // Cooled, the silicon on top shrinks least, so the top grows longer: κ > 0.
        assert!(k > 0.0);
    }
}
