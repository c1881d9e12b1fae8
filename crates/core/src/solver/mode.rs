//! Time-integration modes: how a run advances one step. Every mode drives the same
//! [`Simulation`] state and stages; the run loop (`run_loop`) is shared. A new mode
//! (total-Lagrangian, staged) is a new file implementing [`StepMode`] and one arm
//! in [`for_scene`].

use super::DimensionDispatch;
use super::cpdi::Cpdi;
use super::explicit::Explicit;
use super::implicit::Implicit;
use super::incompressible::Incompressible;
use super::mechanics_off::MechanicsOff;
use super::quasi_static::QuasiStatic;
use super::refined::Refined;
use super::simulation::Simulation;
use super::total_lagrangian::TotalLagrangian;
use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::refinement::Levels;
use crate::scene::Mechanics;

/// One time-integration mode.
pub(crate) trait StepMode<const D: usize, K: Kernel>: Send {
    /// Advances physics and mechanics by `dt` (the run loop moves the clock).
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64);
    /// The largest stable step for the current state at Courant number 1 (infinite when
    /// nothing in the mode bounds it).
    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64;
    /// Writes what the mode keeps from step to step into a checkpoint (and drops caches it
    /// would rebuild after a resume, so the run goes on as a resumed one does).
    fn save(&mut self, _checkpoint: &mut Checkpoint) {}
    /// Sets [`Simulation`]'s `surface_energy` (and any other energy the mode stores) at
    /// the current positions, before a run or a stage takes its starting energy; nothing
    /// by default.
    fn measure_stored_energy(&mut self, _sim: &mut Simulation<D, K>) {}
    /// At the start of a stage, takes over what the stage before's mode saved at its end
    /// (`c`) when it was the same mode and the state still fits; nothing by default (a
    /// stage's mode starts afresh).
    fn take_over(&mut self, _sim: &Simulation<D, K>, _c: &Checkpoint) {}
    /// Takes back what [`StepMode::save`] wrote.
    fn restore(&mut self, _checkpoint: &Checkpoint) -> Result<(), CheckpointError> {
        Ok(())
    }
}

/// The mode the scene's `solver.mechanics` asks for.
pub(super) fn for_scene<const D: usize, K: Kernel>(
    mechanics: Mechanics,
    fbar: bool,
    refined: Option<Levels<D>>,
) -> Box<dyn StepMode<D, K>>
where
    dyn Material: DimensionDispatch<D>,
{
    if let Some(levels) = refined {
        // Validation allows refinement with dynamic mechanics only.
        return Box::new(Refined::new(levels));
    }
    match mechanics {
        Mechanics::Dynamic if K::DOMAINS => Box::new(Cpdi::<D>::default()),
        Mechanics::Dynamic => Box::new(Explicit),
        Mechanics::TotalLagrangian => Box::new(TotalLagrangian::<D>::default()),
        Mechanics::Off => Box::new(MechanicsOff),
        Mechanics::QuasiStatic {
            max_iterations,
            tolerance,
            damping,
        } => Box::new(QuasiStatic {
            max_iterations,
            tolerance,
            damping,
        }),
        Mechanics::Implicit(settings) => Box::new(Implicit::<D>::new(settings, fbar)),
        Mechanics::Incompressible(settings) => Box::new(Incompressible::new(settings)),
    }
}
