//! The logarithmic (Hencky) strain ε = ½ ln(Fe Feᵀ) of an elastic deformation Fe and its
//! derivative along a change δFe: what the consistent tangents of the finite-strain
//! plasticity laws that return in principal logarithmic strains (Johnson–Cook, Anand)
//! share. In the principal axes N of be = Fe Feᵀ, δε'ᵢⱼ = ½ (Nᵀ δbe N)ᵢⱼ (ln bᵢ − ln bⱼ) /
//! (bᵢ − bⱼ) (1/bᵢ on the diagonal), with δbe = δFe Feᵀ + Fe δFeᵀ.

use crate::math::{determinant, inverse, symmetric_eigen3};
use nalgebra::{Matrix3, Vector3};

/// The elastic trial state of a return in logarithmic strain: Fe = F·Fp⁻¹ and its strain.
pub struct ElasticTrial {
    /// J = det F.
    pub j: f64,
    /// F⁻¹.
    pub f_inv: Matrix3<f64>,
    /// Fe = F·Fp⁻¹.
    pub fe: Matrix3<f64>,
    /// Principal axes of Fe·Feᵀ (columns).
    pub axes: Matrix3<f64>,
    /// Deviatoric principal logarithmic strains, along `axes`.
    pub deviatoric: Vector3<f64>,
}

impl ElasticTrial {
    /// The trial von Mises (Kirchhoff) stress √(3/2)·|2μ·dev ε| at shear modulus `shear`.
    pub fn equivalent_stress(&self, shear: f64) -> f64 {
        (1.5 * (self.deviatoric * (2.0 * shear)).norm_squared()).sqrt()
    }

    /// Fp⁻¹ after a return to the deviatoric principal strains `returned` along the same
    /// axes: Fe ← A·Fe with A = exp(ε_returned − ε_trial), then Fp⁻¹ = F⁻¹·Fe.
    pub fn plastic_inverse_after(&self, returned: &Vector3<f64>) -> Matrix3<f64> {
        let change = (returned - self.deviatoric).map(f64::exp);
        let a = self.axes * Matrix3::from_diagonal(&change) * self.axes.transpose();
        self.f_inv * a * self.fe
    }
}

/// The elastic trial state of a return in logarithmic strain and its change along δF: what
/// a consistent tangent differentiates.
pub struct ElasticTrialChange {
    /// J = det F.
    pub j: f64,
    /// δJ.
    pub dj: f64,
    /// Deviatoric principal logarithmic strains.
    pub deviatoric: Vector3<f64>,
    /// The deviatoric trial strain e = dev ε, in the global frame.
    pub strain: Matrix3<f64>,
    /// δε, in the global frame.
    pub change: Matrix3<f64>,
}

impl ElasticTrialChange {
    /// The trial von Mises (Kirchhoff) stress, as [`ElasticTrial::equivalent_stress`].
    pub fn equivalent_stress(&self, shear: f64) -> f64 {
        (1.5 * (self.deviatoric * (2.0 * shear)).norm_squared()).sqrt()
    }
}

/// The trial state of 3×3 `f` with plastic part `fp_inv` and its change along `df` (δF);
/// `None` where det F ≤ 0.
pub fn elastic_trial_change(
    f: &Matrix3<f64>,
    df: &Matrix3<f64>,
    fp_inv: &Matrix3<f64>,
) -> Option<ElasticTrialChange> {
    let j = determinant::<3>(f);
    let f_inv = inverse::<3>(f).filter(|_| j > 0.0)?;
    let strain = log_strain_change(&(f * fp_inv), &(df * fp_inv));
    let volumetric = strain.principal.sum() / 3.0;
    let deviatoric = strain.principal.add_scalar(-volumetric);
    let axes = strain.axes;
    Some(ElasticTrialChange {
        j,
        dj: j * (f_inv * df).trace(),
        deviatoric,
        strain: axes * Matrix3::from_diagonal(&deviatoric) * axes.transpose(),
        change: strain.change,
    })
}

/// The trial state of 3×3 `f` with plastic part `fp_inv` (Fp⁻¹); `None` where det F ≤ 0
/// (the solver stops such a run; a law leaves the stress as it was).
pub fn elastic_trial(f: &Matrix3<f64>, fp_inv: &Matrix3<f64>) -> Option<ElasticTrial> {
    let j = determinant::<3>(f);
    let f_inv = inverse::<3>(f).filter(|_| j > 0.0)?;
    let fe = f * fp_inv;
    let (stretch2, axes) = symmetric_eigen3(&(fe * fe.transpose()));
    let log_strain = stretch2.map(|l| 0.5 * l.max(1e-300).ln());
    let volumetric = log_strain.sum() / 3.0;
    Some(ElasticTrial {
        j,
        f_inv,
        fe,
        axes,
        deviatoric: log_strain.add_scalar(-volumetric),
    })
}

/// The logarithmic strain of an elastic deformation and its change.
pub struct LogStrainChange {
    /// Principal logarithmic strains ½ ln bᵢ.
    pub principal: Vector3<f64>,
    /// Principal axes (columns), the same as the update's.
    pub axes: Matrix3<f64>,
    /// δε, in the global frame.
    pub change: Matrix3<f64>,
}

/// ε of `fe` and its change along `dfe` (see the module documentation).
pub fn log_strain_change(fe: &Matrix3<f64>, dfe: &Matrix3<f64>) -> LogStrainChange {
    let (stretch2, axes) = symmetric_eigen3(&(fe * fe.transpose()));
    let b = stretch2.map(|l| l.max(1e-300));
    let dbe_axes = axes.transpose() * (dfe * fe.transpose() + fe * dfe.transpose()) * axes;
    let mut d_log = Matrix3::zeros();
    for r in 0..3 {
        for c in 0..3 {
            d_log[(r, c)] = 0.5 * dbe_axes[(r, c)] * log_slope(b[r], b[c]);
        }
    }
    LogStrainChange {
        principal: b.map(|l| 0.5 * l.ln()),
        axes,
        change: axes * d_log * axes.transpose(),
    }
}

/// (ln a − ln b)/(a − b), also where a and b (both positive) nearly coincide.
fn log_slope(a: f64, b: f64) -> f64 {
    let r = a / b - 1.0;
    if r.abs() < 1e-8 {
        (1.0 - 0.5 * r) / b
    } else {
        r.ln_1p() / (r * b)
    }
}

/// The deviatoric part of a 3×3 tensor.
pub fn deviator(m: &Matrix3<f64>) -> Matrix3<f64> {
    m - Matrix3::identity() * (m.trace() / 3.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_change_is_the_difference_of_the_strain() {
        let fe = Matrix3::new(1.1, 0.2, 0.0, 0.05, 0.95, 0.1, 0.0, -0.1, 1.02);
        let dfe = Matrix3::new(0.3, -0.2, 0.1, 0.05, 0.4, -0.1, 0.2, 0.1, -0.3);
        let strain = |f: Matrix3<f64>| {
            let s = log_strain_change(&f, &Matrix3::zeros());
            s.axes * Matrix3::from_diagonal(&s.principal) * s.axes.transpose()
        };
        let h = 1e-6;
        let numeric = (strain(fe + dfe * h) - strain(fe - dfe * h)) / (2.0 * h);
        let analytic = log_strain_change(&fe, &dfe).change;
        assert!((analytic - numeric).norm() < 1e-7 * numeric.norm());
    }
}
