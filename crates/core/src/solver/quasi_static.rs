//! Quasi-static mechanics: the physics operators advance a real time step, then damped
//! explicit iterations in pseudo time bring the body to equilibrium and to rest.

use super::DimensionDispatch;
use super::grid_to_particle::measure;
use super::mode::StepMode;
use super::simulation::Simulation;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector};

/// Quasi-static mechanics (`solver.mechanics.quasi_static`): the step is the physics
/// operators' (or the scene's fixed one); each step relaxes to equilibrium.
pub(super) struct QuasiStatic {
    pub(super) max_iterations: u32,
    pub(super) tolerance: f64,
    pub(super) damping: Option<f64>,
}

impl<const D: usize, K: Kernel> StepMode<D, K> for QuasiStatic
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        sim.advance_physics(dt, true);
        sim.relax(dt, self.max_iterations, self.tolerance, self.damping);
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        sim.physics_dt
    }
}

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Quasi-static mechanics: damped explicit iterations (pseudo-time, the clock stands at
    /// the end of the step) until the kinetic energy is a `tolerance` fraction of the strain
    /// energy; then the body is brought to rest. Not converging stops the run.
    pub(super) fn relax(
        &mut self,
        dt: f64,
        max_iterations: u32,
        tolerance: f64,
        damping: Option<f64>,
    ) {
        let saved_damping = self.settings.damping;
        let auto = || {
            let extent = (0..D)
                .map(|d| self.grid.cells[d] as f64 * self.grid.dx)
                .fold(0.0, f64::max);
            2.0 * std::f64::consts::PI * self.stresses.batch.max_wave_speed / extent.max(1e-300)
        };
        self.settings.damping = damping.unwrap_or_else(auto);
        self.relax_time = Some(self.time + dt);
        let mut peak = 0.0f64;
        let mut converged = false;
        let mut iterations = 0;
        while iterations < max_iterations {
            iterations += 1;
            let pseudo = self.settings.cfl * self.mechanical_dt();
            if !(pseudo.is_finite() && pseudo > 0.0) {
                break;
            }
            self.mechanical_step(pseudo, false);
            let kinetic = self.kinematics.kinetic_energy;
            if !kinetic.is_finite() || self.check(0.0).is_some() {
                break;
            }
            peak = peak.max(kinetic);
            let scale = self.stresses.batch.strain_energy.max(peak);
            if iterations >= 10 && kinetic <= tolerance * scale {
                converged = true;
                break;
            }
        }
        self.relax_time = None;
        self.settings.damping = saved_damping;
        // The relaxation's damping takes the rest of the kinetic energy with it.
        self.ledger.damping += self.kinematics.kinetic_energy;
        self.particles.velocity.fill(Vector::<D>::zeros());
        self.particles.affine.fill(Matrix::<D>::zeros());
        let stats = measure(&self.particles, self.settings.gravity);
        self.kinematics.kinetic_energy = 0.0;
        self.kinematics.max_speed = 0.0;
        self.kinematics.momentum = stats.momentum;
        self.report
            .record_max("quasi_static.iterations", iterations as f64);
        if !converged && self.check(0.0).is_none() {
            self.report.fail(crate::physics::PhysicsFault {
                field: "relaxation".into(),
                particle: None,
                value: iterations as f64,
                message: format!(
                    "quasi-static relaxation did not reach equilibrium in {max_iterations} iterations (raise solver.mechanics.quasi_static.max_iterations or the damping, or take smaller steps)"
                ),
            });
        }
    }
}
