//! A free bimaterial strip (two bonded layers of different thermal expansion) under a
//! uniform temperature change bends to a constant curvature (Timoshenko 1925, "Analysis of
//! bi-metal thermostats"):
//!
//! κ = 6 Δε (1 + m)² / (h [3 (1 + m)² + (1 + m n)(m² + 1/(m n))]),
//!
//! with Δε = (α₂ − α₁) ΔT, m = t₁/t₂, n = E₁/E₂, h = t₁ + t₂; layer 1 below layer 2 along
//! the thickness axis. In 2D (plane strain) E → E/(1 − ν²) and α → (1 + ν) α; in 3D a
//! plate free on all edges bends biaxially, E → E/(1 − ν) (exact for equal ν).
//!
//! The measured curvature is a least-squares fit of the particles' deflection
//! u_t = a + b s + c s² − κ x²/2 (x along the strip from its symmetry plane, s across)
//! at the last frame, over the inner `fit_fraction` of the half length (away from the free
//! end's boundary layer).

use super::{Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory};
use crate::output::Comparison;
use crate::scene::{Issue, Scene};
use crate::section::Checks;
use serde::Deserialize;
use std::sync::Arc;

/// Parameters of the `bimaterial_strip` reference.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct BimaterialStripParams {
    /// Axis along the strip.
    pub length_axis: usize,
    /// Axis across the layers (layer 1 at lower coordinates).
    pub thickness_axis: usize,
    /// Coordinate of the strip's symmetry plane along `length_axis` (its mid-span).
    pub center: f64,
    /// Half length of the strip, m.
    pub half_length: f64,
    /// Thickness of layer 1 and layer 2, m.
    pub thicknesses: [f64; 2],
    /// Young's moduli of layer 1 and 2, Pa.
    pub youngs_moduli: [f64; 2],
    /// Poisson's ratios of layer 1 and 2.
    pub poisson_ratios: [f64; 2],
    /// Linear expansion coefficients of layer 1 and 2, 1/K.
    pub expansions: [f64; 2],
    /// Uniform temperature change, K.
    pub temperature_change: f64,
    /// Fraction of the half length (from the symmetry plane) the fit uses.
    #[serde(default = "default_fit_fraction")]
    pub fit_fraction: f64,
    /// 2D only: whether the layers' free strain acts out of the plane too (physical plane
    /// strain: α → (1 + ν) α). This code's 2D free strain (thermal expansion, shrinkage)
    /// acts in the plane only, so a scene that checks the solver against the model it
    /// solves sets `false` (then α stays α); the metrics compare with both.
    #[serde(default = "default_true")]
    pub out_of_plane_free_strain: bool,
}

fn default_true() -> bool {
    true
}

fn default_fit_fraction() -> f64 {
    0.6
}

/// Timoshenko's curvature of a bimaterial strip from effective (plane strain, biaxial or
/// uniaxial) moduli and expansions of the two layers; positive when the strip bends
/// towards layer 1 (layer 2 expands more).
pub fn bimaterial_curvature(
    thicknesses: [f64; 2],
    moduli: [f64; 2],
    expansions: [f64; 2],
    temperature_change: f64,
) -> f64 {
    let [t1, t2] = thicknesses;
    let (m, n, h) = (t1 / t2, moduli[0] / moduli[1], t1 + t2);
    let mismatch = (expansions[1] - expansions[0]) * temperature_change;
    6.0 * mismatch * (1.0 + m).powi(2)
        / (h * (3.0 * (1.0 + m).powi(2) + (1.0 + m * n) * (m * m + 1.0 / (m * n))))
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct BimaterialStrip {
    p: BimaterialStripParams,
    expected: f64,
    /// 2D: the closed forms with and without the out-of-plane free strain.
    plane_forms: Option<[f64; 2]>,
    measured: Option<f64>,
}

impl BimaterialStrip {
    /// The closed-form curvature for dimension `d`.
    fn closed_form(p: &BimaterialStripParams, d: usize, out_of_plane: bool) -> f64 {
        let mut moduli = p.youngs_moduli;
        let mut expansions = p.expansions;
        for k in 0..2 {
            let nu = p.poisson_ratios[k];
            if d == 2 {
                moduli[k] /= 1.0 - nu * nu;
                if out_of_plane {
                    expansions[k] *= 1.0 + nu;
                }
            } else {
                moduli[k] /= 1.0 - nu;
            }
        }
        bimaterial_curvature(p.thicknesses, moduli, expansions, p.temperature_change)
    }
}

/// Solves the small symmetric system `a x = b` (Gaussian elimination with pivoting).
fn solve_small<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for col in 0..N {
        let pivot = (col..N).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let pivot_row = a[col];
        for row in col + 1..N {
            let f = a[row][col] / pivot_row[col];
            for (x, p) in a[row].iter_mut().zip(pivot_row).skip(col) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; N];
    for row in (0..N).rev() {
        let mut s = b[row];
        for k in row + 1..N {
            s -= a[row][k] * x[k];
        }
        x[row] = s / a[row][row];
    }
    Some(x)
}

/// The curvature of a strip along `ax` bending across `at`: −2 q of the least-squares fit
/// u_t = a + b s + c s² + q x² (+ r z² in 3D: a plate bends both ways) of the particles'
/// deflection, over those within `limit` of `center` (x = |x₀ − center|, s = x₀ across).
pub(super) fn fit_curvature<const D: usize>(
    particles: &crate::particles::Particles<D>,
    ax: usize,
    at: usize,
    center: f64,
    limit: f64,
) -> Option<f64> {
    const N: usize = 5;
    let mut ata = [[0.0; N]; N];
    let mut atb = [0.0; N];
    let third = (0..D).find(|&d| d != ax && d != at);
    for i in 0..particles.len() {
        let x0 = particles.initial_position[i];
        let x = (x0[ax] - center).abs();
        let z = third.map_or(0.0, |d| x0[d] - center);
        if x > limit || z.abs() > limit {
            continue;
        }
        let s = x0[at];
        let u = particles.position[i][at] - x0[at];
        let row = [1.0, s, s * s, x * x, z * z];
        for r in 0..N {
            for c in 0..N {
                ata[r][c] += row[r] * row[c];
            }
            atb[r] += row[r] * u;
        }
    }
    if third.is_none() {
        ata[4][4] = 1.0;
    }
    solve_small(ata, atb).map(|c| -2.0 * c[3])
}

impl ReferenceLaw for BimaterialStrip {
    fn kind(&self) -> &'static str {
        "relative error of the curvature of a bimaterial strip under a uniform temperature change (Timoshenko 1925)"
    }

    fn needs_initial_positions(&self) -> bool {
        true
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        if !frame.last {
            return;
        }
        let p = &self.p;
        self.measured = fit_curvature(
            frame.particles,
            p.length_axis,
            p.thickness_axis,
            p.center,
            p.fit_fraction * p.half_length,
        );
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
        let (Some(m), Some([physical, in_plane])) = (self.measured, self.plane_forms) else {
            return Vec::new();
        };
        let compare = |quantity: &str, reference: f64| Comparison {
            quantity: quantity.into(),
            measured: m,
            reference,
            relative_difference: (m - reference) / reference,
        };
        vec![
            compare("curvature_plane_strain_out_of_plane_free_strain", physical),
            compare("curvature_plane_strain_in_plane_free_strain", in_plane),
        ]
    }
}

fn build(
    p: BimaterialStripParams,
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
    for k in 0..2 {
        c.positive(&format!("thicknesses[{k}]"), p.thicknesses[k]);
        c.positive(&format!("youngs_moduli[{k}]"), p.youngs_moduli[k]);
        c.finite(&format!("expansions[{k}]"), p.expansions[k]);
        if !(p.poisson_ratios[k] > -1.0 && p.poisson_ratios[k] < 0.5) {
            c.error(&format!("poisson_ratios[{k}]"), "must lie in (-1, 0.5)");
        }
    }
    c.finite("temperature_change", p.temperature_change);
    if !(p.fit_fraction > 0.0 && p.fit_fraction <= 1.0) {
        c.error("fit_fraction", "must lie in (0, 1]");
    }
    c.finish()?;
    let expected = BimaterialStrip::closed_form(&p, d, d == 3 || p.out_of_plane_free_strain);
    let plane_forms = (d == 2).then(|| {
        [
            BimaterialStrip::closed_form(&p, d, true),
            BimaterialStrip::closed_form(&p, d, false),
        ]
    });
    if expected == 0.0 || !expected.is_finite() {
        let mut c = Checks::new(path);
        c.error(
            "temperature_change",
            "the layers' expansion mismatch times the temperature change must not be zero",
        );
        c.finish()?;
    }
    Ok(Arc::new(BimaterialStrip {
        p,
        expected,
        plane_forms,
        measured: None,
    }))
}

/// The `bimaterial_strip` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("bimaterial_strip", build))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_layers_give_the_textbook_curvature() {
        // m = n = 1: κ = 3 Δε / (2 h).
        let k = bimaterial_curvature([1e-3, 1e-3], [1e9, 1e9], [1e-5, 2e-5], 100.0);
        let expected = 1.5 * 1e-3 / 2e-3;
        assert!((k - expected).abs() < 1e-12 * expected, "{k} vs {expected}");
    }
}
