//! Generalized plane strain in the implicit tangent. Every residual evaluation solves the
//! out-of-plane strain ε₀ for no net force across the plane, N(Δu, ε₀) = Σ σzz·J·V₀ = 0
//! (`generalized_plane_strain.rs`), so the residual Newton drives to zero is R(Δu, ε₀(Δu)).
//! Its tangent is the one at fixed ε₀ (the laws' derivatives, or differences with ε₀ held)
//! plus a rank-one term for ε₀'s response:
//!
//!   J v = K v − b (c·v) / k,  b = ∂R/∂ε₀,  c·v = ∂N/∂Δu · v,  k = ∂N/∂ε₀.
//!
//! b and k come from one probe of the stress update at ε₀ + h per linearisation. c follows
//! from the symmetry of a hyperelastic law's tangent: with P the first Piola stress of the
//! 3D law and s the stretch across the plane, ∂P_zz/∂F = ∂P/∂s, which for a 2D particle
//! reads ∂(J σzz)/∂F = (σ + s ∂σ/∂s) cof F, and s ∂σ/∂s = (1 + ε₀) ∂σ/∂ε₀. Without the term
//! Newton converges linearly wherever the section's contraction matters (a curing
//! underfill pulls die and substrate along z).

use super::super::DimensionDispatch;
use super::super::generalized_plane_strain::GeneralizedPlaneStrain;
use super::super::parallel::ordered_particle_sum;
use super::super::simulation::Simulation;
use super::super::stress_update::update_stress;
use super::residual::{a_bar, fold, project, scatter_with};
use super::workspace::Workspace;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, cofactor};

/// Difference step of the ε₀ probe (a strain).
const PROBE: f64 = 1e-7;

/// The rank-one term of the last linearisation.
#[derive(Default)]
pub(super) struct OutOfPlaneCoupling<const D: usize> {
    /// Whether the scene takes generalized plane strain and the probe found a stiffness.
    active: bool,
    /// b = ∂R/∂ε₀, the nodal force per unit ε₀ (folded and projected as the residual).
    force: Vec<f64>,
    /// Each particle's part of c: ∂N/∂Ā_p, dotted with the change δĀ_p of a direction.
    row: Vec<Matrix<D>>,
    /// k = ∂N/∂ε₀, N.
    stiffness: f64,
}

impl<const D: usize> OutOfPlaneCoupling<D> {
    /// c·v for a direction whose per-particle change of Ā is `change` (δĀ, or ∇v without
    /// F-bar); 0 when inactive.
    pub fn row_dot(&self, change: &[Matrix<D>]) -> f64 {
        if !self.active {
            return 0.0;
        }
        let row = &self.row;
        ordered_particle_sum(row.len(), |p| row[p].dot(&change[p]))
    }

    /// Adds −b (c·v)/k to a tangent product `out` (already folded and projected).
    pub fn add(&self, row_dot: f64, out: &mut [f64]) {
        if !self.active {
            return;
        }
        let factor = row_dot / self.stiffness;
        for (o, b) in out.iter_mut().zip(&self.force) {
            *o -= b * factor;
        }
    }
}

/// Measures the rank-one term at the iterate `linearise_at` saved (stress in
/// `work.stress_cur`, σzz in `work.zz_cur`) by one stress update at ε₀ + h, and puts the
/// iterate's stress, σzz and stretch back. Inactive without generalized plane strain.
pub(super) fn measure<const D: usize, K: Kernel>(
    sim: &mut Simulation<D, K>,
    work: &mut Workspace<D>,
    dt: f64,
) where
    dyn Material: DimensionDispatch<D>,
{
    let mut coupling = std::mem::take(&mut work.out_of_plane);
    coupling.active = false;
    let n = sim.particles.len();
    let strain = sim.stress_scratch.out_of_plane_strain();
    let takes = sim
        .particles
        .groups
        .iter()
        .any(|g| g.free_strain_across_plane);
    let (Some(strain), true, true) = (strain, takes, work.zz_cur.len() == n && n > 0) else {
        work.out_of_plane = coupling;
        return;
    };
    let p = &sim.particles;
    let (before, _) =
        GeneralizedPlaneStrain::force(&work.zz_cur, &p.deformation_gradient, &p.volume0);
    sim.stress_scratch
        .hold_out_of_plane_strain(Some(strain + PROBE), &sim.particles.groups);
    work.restore_state(sim);
    let stats = update_stress(&mut sim.particles, dt, &mut sim.stress_scratch);
    let p = &sim.particles;
    let (after, _) =
        GeneralizedPlaneStrain::force(&p.stress_zz, &p.deformation_gradient, &p.volume0);
    coupling.stiffness = (after - before) / PROBE;
    // b: the residual's scatter of Vₙ (∂σ/∂ε₀) cof(I + ∇Δu).
    let identity = Matrix::<D>::identity();
    let stress_cur = std::mem::take(&mut work.stress_cur);
    let grad_du = std::mem::take(&mut work.grad_du);
    let stress = &sim.particles.stress;
    coupling.force.resize(work.len(), 0.0);
    scatter_with(work, n, &mut coupling.force, |p| {
        (stress[p] - stress_cur[p]) / PROBE * cofactor(&(identity + grad_du[p]))
    });
    work.grad_du = grad_du;
    fold::<D>(&work.mirrors, &mut coupling.force);
    project(work, &mut coupling.force);
    // c: Vₙ (σ + (1 + ε₀) ∂σ/∂ε₀) cof(Ā) for the particles that take the stretch.
    coupling.row.clear();
    coupling.row.resize(n, Matrix::<D>::zeros());
    for group in sim.particles.groups.iter() {
        if !group.free_strain_across_plane {
            continue;
        }
        for p in group.range.clone() {
            let slope = (stress[p] - stress_cur[p]) / PROBE;
            coupling.row[p] = (stress_cur[p] + slope * (1.0 + strain))
                * cofactor(&a_bar(work, p))
                * work.volume_n[p];
        }
    }
    // Back to the iterate.
    sim.particles.stress.copy_from_slice(&stress_cur);
    sim.particles.stress_zz.copy_from_slice(&work.zz_cur);
    work.stress_cur = stress_cur;
    sim.stress_scratch
        .hold_out_of_plane_strain(None, &sim.particles.groups);
    coupling.active = stats.non_finite.is_none()
        && coupling.stiffness.is_finite()
        && coupling.stiffness > 0.0
        && coupling.force.iter().all(|b| b.is_finite());
    work.out_of_plane = coupling;
}
