//! Shape functions (kernels) that connect particles to grid nodes.
//!
//! A kernel is a zero-sized type so every transfer loop is monomorphised for it. Weights are
//! separable: the weight of a node is the product of one 1D weight per axis.

pub mod cpdi;
mod cubic;
mod gimp;
mod linear;
mod quadratic;

pub use cpdi::Cpdi;
pub use cubic::CubicBSpline;
pub use gimp::UniformGimp;
pub use linear::Linear;
pub use quadratic::QuadraticBSpline;

/// `x.floor()` without the libm call that baseline x86-64 (no SSE4.1) compiles it to; the
/// kernels call it for every particle and axis. Exact for |x| < 2^52.
#[inline(always)]
pub fn fast_floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x { t - 1.0 } else { t }
}

/// Most nodes a kernel touches along one axis (the cubic B-spline's 4).
pub const MAX_SPAN: usize = 4;

/// 1D weights of one particle along one axis.
#[derive(Clone, Copy, Debug, Default)]
pub struct AxisWeights {
    /// Index of the first node touched.
    pub base: isize,
    /// Weight of node `base + a` for `a < SPAN`.
    pub w: [f64; MAX_SPAN],
    /// Derivative of that weight with respect to the particle position, in grid units
    /// (divide by the cell size for physical units).
    pub dw: [f64; MAX_SPAN],
}

/// A separable shape function evaluated in grid units (cell size 1).
pub trait Kernel: Copy + Send + Sync + 'static {
    /// Nodes touched along one axis.
    const SPAN: usize;
    /// Name used in scene files (`solver.kernel`).
    const NAME: &'static str;
    /// `Some(c)` when the APIC inertia tensor is the constant `c·dx²·I` (B-splines); `None`
    /// when it must be computed per particle (linear, GIMP).
    const APIC_INERTIA: Option<f64>;
    /// Whether the weights depend on the particle's half size (GIMP, CPDI).
    const USES_PARTICLE_SIZE: bool = false;
    /// Whether the mechanics step interpolates through deformed particle domains (CPDI):
    /// then the step is `solver::cpdi`'s, and these point weights serve the rest.
    const DOMAINS: bool = false;

    /// Weights along one axis for a particle at grid coordinate `xi`; `half_size` is the
    /// particle's half width in cells (only GIMP uses it).
    fn weights(xi: f64, half_size: f64) -> AxisWeights;
}

/// Which kernel a scene asked for; the solver dispatches on it once per run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelKind {
    /// Tent functions, the original MPM.
    Linear,
    /// Uniform generalised interpolation (uGIMP).
    Gimp,
    /// Quadratic B-spline.
    QuadraticBSpline,
    /// Cubic B-spline.
    CubicBSpline,
    /// Convected particle domains.
    Cpdi,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_partition_of_unity<K: Kernel>(half_size: f64) {
        for i in 0..200 {
            let xi = 5.0 + i as f64 / 200.0 * 1.0;
            let aw = K::weights(xi, half_size);
            let sum: f64 = aw.w[..K::SPAN].iter().sum();
            let dsum: f64 = aw.dw[..K::SPAN].iter().sum();
            // Linear reproduction: sum_i w_i x_i = x_p.
            let first: f64 = (0..K::SPAN)
                .map(|a| aw.w[a] * (aw.base + a as isize) as f64)
                .sum();
            assert!((sum - 1.0).abs() < 1e-12, "{} sum {sum} at {xi}", K::NAME);
            assert!(dsum.abs() < 1e-12, "{} dsum {dsum}", K::NAME);
            assert!(
                (first - xi).abs() < 1e-12,
                "{} first moment {first} at {xi}",
                K::NAME
            );
            // Derivative of the weights agrees with finite differences.
            let h = 1e-6;
            let (p, m) = (K::weights(xi + h, half_size), K::weights(xi - h, half_size));
            if p.base == aw.base && m.base == aw.base {
                for a in 0..K::SPAN {
                    let fd = (p.w[a] - m.w[a]) / (2.0 * h);
                    assert!((fd - aw.dw[a]).abs() < 1e-5, "{} dw {a} at {xi}", K::NAME);
                }
            }
        }
    }

    #[test]
    fn fast_floor_matches_floor() {
        for x in [
            -2.5,
            -2.0,
            -0.5,
            -0.0,
            0.0,
            0.3,
            1.0,
            1.9999999,
            7.5,
            1e9 + 0.5,
        ] {
            assert_eq!(fast_floor(x), x.floor(), "{x}");
        }
    }

    #[test]
    fn kernels_are_partitions_of_unity_with_linear_reproduction() {
        check_partition_of_unity::<Linear>(0.0);
        check_partition_of_unity::<QuadraticBSpline>(0.0);
        check_partition_of_unity::<CubicBSpline>(0.0);
        check_partition_of_unity::<UniformGimp>(0.25);
        check_partition_of_unity::<UniformGimp>(0.5);
    }
}
