//! Liquid leaving through the domain faces that have no wall
//! (`solver.mechanics.incompressible.outflow: true`): the vents of a mould, the open end
//! of a channel.
//!
//! After G2P (and after the inlets let liquid in, inflow.rs), a liquid particle past an
//! open face leaves: it stops on the face with no mass and no volume and `injected` = −1,
//! so it never counts again and never re-enters; its volume adds to the physics figure
//! `incompressible.outflow_volume` (the running total, kept in the report so a resumed
//! run continues it). A step moves a particle less than a cell, so it leaves before its
//! stencil can reach the grid's edge; without `outflow` such a particle stops the run.

use super::super::DimensionDispatch;
use super::super::simulation::Simulation;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector};
use crate::particles::Particles;
use crate::scene::{INJECTED, Scene, Side};

/// Name of the physics figure with the volume that has left (m³; m² in 2D).
pub const OUTFLOW_VOLUME: &str = "incompressible.outflow_volume";

/// The open faces: per axis the lower and upper face's coordinate where it has no wall.
pub(in crate::solver) struct Outlets {
    lower: [Option<f64>; 3],
    upper: [Option<f64>; 3],
}

impl Outlets {
    /// The open faces of a scene with `outflow` on (`None` with it off).
    pub(in crate::solver) fn new(s: &Scene, dim: usize) -> Option<Self> {
        let crate::scene::Mechanics::Incompressible(settings) = s.solver.mechanics else {
            return None;
        };
        if !settings.outflow {
            return None;
        }
        let walled = |side: Side| s.domain.walls.iter().any(|w| w.sides.contains(&side));
        let faces = [
            (Side::XMin, Side::XMax),
            (Side::YMin, Side::YMax),
            (Side::ZMin, Side::ZMax),
        ];
        let mut outlets = Self {
            lower: [None; 3],
            upper: [None; 3],
        };
        for (a, (low, high)) in faces.into_iter().enumerate().take(dim) {
            outlets.lower[a] = (!walled(low)).then_some(s.domain.min[a]);
            outlets.upper[a] = (!walled(high)).then_some(s.domain.max[a]);
        }
        Some(outlets)
    }

    /// Moves `x` back onto the open face it crossed; whether it crossed one.
    fn crossed<const D: usize>(&self, x: &mut Vector<D>) -> bool {
        let mut out = false;
        for a in 0..D {
            if let Some(lo) = self.lower[a]
                && x[a] < lo
            {
                x[a] = lo;
                out = true;
            }
            if let Some(hi) = self.upper[a]
                && x[a] > hi
            {
                x[a] = hi;
                out = true;
            }
        }
        out
    }
}

/// Takes out the liquid particles that crossed an open face in this step.
pub(super) fn leave<const D: usize, K: Kernel>(sim: &mut Simulation<D, K>)
where
    dyn Material: DimensionDispatch<D>,
{
    let Some(outlets) = sim.inflow.as_ref().and_then(|f| f.outlets.as_ref()) else {
        return;
    };
    let gravity = sim.settings.gravity;
    let (kinematics, ledger) = (&mut sim.kinematics, &mut sim.ledger);
    let Particles {
        position,
        velocity,
        mass,
        volume0,
        stress,
        stress_zz,
        affine,
        velocity_gradient,
        shared,
        ..
    } = &mut sim.particles;
    let Some(injected) = shared.get_mut(INJECTED) else {
        return;
    };
    let mut gone = 0.0;
    for (i, flag) in injected.iter_mut().enumerate() {
        let x = position[i];
        if *flag > 0.5 && outlets.crossed(&mut position[i]) {
            // Out of the step's statistics (taken before it left) and off the books.
            let (m, v) = (mass[i], velocity[i]);
            kinematics.kinetic_energy -= 0.5 * m * v.norm_squared();
            kinematics.gravity_energy += m * gravity.dot(&x);
            kinematics.momentum -= v * m;
            ledger.openings -= m * (0.5 * v.norm_squared() - gravity.dot(&x));
            gone += volume0[i];
            *flag = -1.0;
            mass[i] = 0.0;
            volume0[i] = 0.0;
            velocity[i] = Vector::<D>::zeros();
            stress[i] = Matrix::<D>::zeros();
            if let Some(zz) = stress_zz.get_mut(i) {
                *zz = 0.0;
            }
            if let Some(b) = affine.get_mut(i) {
                *b = Matrix::<D>::zeros();
            }
            if let Some(l) = velocity_gradient.get_mut(i) {
                *l = Matrix::<D>::zeros();
            }
        }
    }
    let before = sim
        .report
        .maxima
        .iter()
        .find(|(name, _)| name == OUTFLOW_VOLUME)
        .map_or(0.0, |(_, v)| *v);
    sim.report.record_max(OUTFLOW_VOLUME, before + gone);
}
