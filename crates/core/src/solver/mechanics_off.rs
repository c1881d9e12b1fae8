//! Mechanics off: only the physics operators advance (heat conduction on a body at rest,
//! say); the step is theirs or the scene's fixed one.

use super::DimensionDispatch;
use super::mode::StepMode;
use super::simulation::Simulation;
use crate::kernels::Kernel;
use crate::material::Material;

/// Physics operators only (`solver.mechanics: off`).
pub(super) struct MechanicsOff;

impl<const D: usize, K: Kernel> StepMode<D, K> for MechanicsOff
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        sim.advance_physics(dt, false);
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        sim.physics_dt
    }
}
