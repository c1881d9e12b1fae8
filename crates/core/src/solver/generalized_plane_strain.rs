//! Generalized plane strain (`solver.free_strain_2d: "generalized_plane_strain"`): a 2D
//! section of a long body whose strain along the held third direction is one constant ε₀
//! with no net force along it, Σₚ σzz·J·V₀ = 0, instead of zero (plane strain). A package's
//! cross-section is one: the die, underfill and substrate contract together along the
//! section's normal, so a shrinking underfill pulls on the die there instead of on a rigid
//! wall. Every particle whose law says `plane_strain_stress` gets the stretch
//! (1 + ε₀)/(1 + e) across the plane (e its free strain); the stress update solves for ε₀
//! each time it runs by secant steps on the net force, putting the laws' state back before
//! each retry (`stress_update.rs`). The laws' own tangents hold ε₀ fixed; the implicit
//! mode holds it through its difference probes and adds its coupling to the tangent as a
//! rank-one term (`implicit/out_of_plane.rs`).

use super::parallel::ordered_particle_sum;
use crate::math::{Matrix, determinant};
use crate::particles::MaterialGroup;

/// Largest number of stress evaluations per update.
const MAX_EVALUATIONS: usize = 30;

/// Net force across the plane, relative to the sum of its magnitudes, at which ε₀ is solved.
const TOLERANCE: f64 = 1e-8;

/// First step of ε₀ when no slope is known yet.
const PROBE: f64 = 1e-6;

/// The unknown ε₀ and what its solve keeps between updates.
#[derive(Default)]
pub(crate) struct GeneralizedPlaneStrain {
    /// ε₀ of the last update.
    pub strain: f64,
    /// d(net force)/dε₀ of the last solve (its last secant), 0 while unknown.
    pub slope: f64,
    /// The stretch each particle's law sees: (1 + ε₀) times the free strain's part.
    pub stretch: Vec<f64>,
    /// The groups' state at the update's start, put back before each retry.
    saved: Vec<Vec<f64>>,
    /// Most evaluations one solve took so far in this run (or since its resume).
    pub most_evaluations: usize,
    /// Whether a solve ended at [`MAX_EVALUATIONS`] with the force not balanced (it keeps
    /// its last ε₀); the run reports it (`generalized_plane_strain.unbalanced`).
    pub unbalanced: bool,
    /// ε₀ to evaluate at instead of solving (a difference probe of the implicit tangent,
    /// which perturbs F or ε₀ alone); `strain` and `slope` are then left as they are.
    pub held: Option<f64>,
}

/// Where the solve stands after an evaluation: the next ε₀ to try, or none when solved.
pub(crate) struct Step {
    /// The ε₀ last evaluated and its net force, for the secant.
    tried: (f64, f64),
    /// Evaluations so far.
    count: usize,
}

impl GeneralizedPlaneStrain {
    /// Keeps the groups' state as the update found it.
    pub fn save(&mut self, groups: &[MaterialGroup]) {
        let fields = groups.iter().flat_map(|g| g.state.iter());
        self.saved.resize_with(fields.clone().count(), Vec::new);
        for (saved, field) in self.saved.iter_mut().zip(fields) {
            saved.clear();
            saved.extend_from_slice(field);
        }
    }

    /// Puts back the state [`GeneralizedPlaneStrain::save`] kept.
    pub fn restore(&self, groups: &mut [MaterialGroup]) {
        let fields = groups.iter_mut().flat_map(|g| g.state.iter_mut());
        for (field, saved) in fields.zip(&self.saved) {
            field.copy_from_slice(saved);
        }
    }

    /// Sets each particle's stretch for `strain` (ε₀): (1 + ε₀)·`free[p]` (`free` empty: 1)
    /// where its group takes the free strain across the plane, else 1.
    pub fn fill(&mut self, strain: f64, free: &[f64], groups: &[MaterialGroup], n: usize) {
        self.stretch.resize(n, 1.0);
        for g in groups {
            for p in g.range.clone() {
                self.stretch[p] = if g.free_strain_across_plane {
                    (1.0 + strain) * free.get(p).copied().unwrap_or(1.0)
                } else {
                    1.0
                };
            }
        }
    }

    /// The net force across the plane, Σ σzz·J·V₀ (N; the particles' current areas times
    /// σzz), and the sum of its terms' magnitudes.
    pub fn force<const D: usize>(
        stress_zz: &[f64],
        deformation_gradient: &[Matrix<D>],
        volume0: &[f64],
    ) -> (f64, f64) {
        let n = stress_zz.len();
        let area = |p: usize| determinant(&deformation_gradient[p]) * volume0[p];
        let net = ordered_particle_sum(n, |p| stress_zz[p] * area(p));
        let scale = ordered_particle_sum(n, |p| (stress_zz[p] * area(p)).abs());
        (net, scale)
    }

    /// After evaluating `strain` with net force `force` (of magnitude sum `scale`): the next
    /// ε₀ to try, or `None` when the force is balanced (or the evaluations are spent); then
    /// [`GeneralizedPlaneStrain::strain`] holds the answer.
    pub fn next(
        &mut self,
        step: &mut Option<Step>,
        strain: f64,
        force: f64,
        scale: f64,
    ) -> Option<f64> {
        let count = step.as_ref().map_or(0, |s| s.count) + 1;
        let before = step.as_ref().map(|s| s.tried);
        *step = Some(Step {
            tried: (strain, force),
            count,
        });
        self.strain = strain;
        let balanced = force.abs() <= TOLERANCE * scale;
        if balanced || count >= MAX_EVALUATIONS {
            self.most_evaluations = self.most_evaluations.max(count);
            self.unbalanced |= !balanced;
            return None;
        }
        if let Some((e0, f0)) = before
            && strain != e0
            && force != f0
        {
            self.slope = (force - f0) / (strain - e0);
        }
        let next = if self.slope != 0.0 && self.slope.is_finite() {
            strain - force / self.slope
        } else {
            // No slope yet: a small probe toward less force (σzz grows with ε₀).
            strain - PROBE * force.signum()
        };
        (next.is_finite() && next != strain).then_some(next)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_secant_finds_the_strain_of_a_linear_force_and_of_a_kinked_one() {
        // A linear force 3e9·(ε − 2e-3) and one that softens past 1e-3 (a yielding layer).
        let laws: [&dyn Fn(f64) -> f64; 2] = [&|e| 3e9 * (e - 2e-3), &|e| {
            if e < 1e-3 {
                3e9 * e - 4e6
            } else {
                3e6 - 4e6 + 3e8 * (e - 1e-3)
            }
        }];
        for force in laws {
            let mut gps = GeneralizedPlaneStrain::default();
            let mut step = None;
            let mut strain = gps.strain;
            let mut evaluations = 0;
            while let Some(next) = {
                evaluations += 1;
                let f = force(strain);
                gps.next(&mut step, strain, f, 1e7)
            } {
                strain = next;
            }
            assert!(
                force(gps.strain).abs() <= 1e-10 * 1e7,
                "ε₀ {} leaves {}",
                gps.strain,
                force(gps.strain)
            );
            assert!(evaluations <= 8, "{evaluations} evaluations");
            assert_eq!(gps.most_evaluations, evaluations);
            assert!(!gps.unbalanced);
        }
    }
}
