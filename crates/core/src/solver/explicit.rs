//! The explicit MPM step: P2G, grid update, G2P and stress update in the order the scene's
//! `solver.scheme` gives (USL, USF or MUSL), with the physics operators advancing between
//! the kinematic and the stress update. Dynamic mechanics is this mode; quasi-static
//! relaxation iterates its mechanical part.

use super::DimensionDispatch;
use super::mode::StepMode;
use super::particle_to_grid::ForceTerm;
use super::simulation::Simulation;
use super::stage_clock::StepStage;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::scene::Scheme;

/// Explicit dynamics: one mechanical step per time step, bounded by the CFL condition.
pub(super) struct Explicit;

impl<const D: usize, K: Kernel> StepMode<D, K> for Explicit
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        sim.mechanical_step(dt, true);
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        sim.mechanical_dt().min(sim.physics_dt)
    }
}

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// One explicit mechanical step with the scene's update scheme; with `physics`, the
    /// physics operators advance between the kinematic and the stress update.
    pub(super) fn mechanical_step(&mut self, dt: f64, physics: bool) {
        self.reorder_if_due();
        let start = std::time::Instant::now();
        self.bins.rebuild::<D, K>(&self.grid, &self.particles);
        self.clock.add(StepStage::Bin, start);
        let force = self.force_term();
        if self.contact.is_some() {
            // Validation allows contact with USL only.
            self.contact_step(dt, physics, force);
            return;
        }
        self.grid.clear();
        match self.settings.scheme {
            Scheme::Usl => {
                self.p2g(dt, true, force);
                self.grid_update(dt, true);
                self.g2p(dt, true, true, true);
                self.average_volume(true, dt);
                if physics {
                    self.advance_physics(dt, true);
                }
                self.update_stresses(dt);
            }
            Scheme::Usf => {
                self.p2g(dt, true, ForceTerm::None);
                self.grid_update(dt, false);
                self.g2p(dt, false, false, true);
                self.average_volume(false, dt);
                if physics {
                    self.advance_physics(dt, true);
                }
                self.update_stresses(dt);
                self.grid.clear();
                self.p2g(dt, true, force);
                self.grid_update(dt, true);
                self.g2p(dt, true, true, false);
            }
            Scheme::Musl => {
                self.p2g(dt, true, force);
                self.grid_update(dt, true);
                self.g2p(dt, true, false, false);
                // Map the new particle momentum back (mass is unchanged: same positions).
                self.grid.clear_momentum();
                self.p2g(dt, false, ForceTerm::None);
                self.grid_update(dt, false);
                let velocity_stats = self.kinematics;
                self.g2p(dt, false, true, true);
                self.kinematics.kinetic_energy = velocity_stats.kinetic_energy;
                self.average_volume(true, dt);
                if physics {
                    self.advance_physics(dt, true);
                }
                self.update_stresses(dt);
            }
        }
    }
}
