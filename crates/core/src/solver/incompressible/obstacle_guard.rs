//! Liquid particles that crossed into an obstacle are put back on its surface.
//!
//! The grid holds an obstacle at its nodes (grid_update.rs), not at its surface between
//! them: a particle in a cell the surface cuts moves with the velocity of nodes in front of
//! the surface as well as behind it, and can step through a curved or slanted face, the
//! more so where the volume source draws liquid towards the face (volume_source.rs): liquid
//! that ends up inside a held solder bump would cure there. After G2P each moving
//! particle found inside an obstacle (held bodies included) is moved along the outward
//! normal onto its surface, and the part of its velocity, relative to the obstacle, that
//! points into it is removed (as a slip surface does on the grid). Particles outside every
//! obstacle are untouched, so a scene whose particles keep out reads as before.
//!
//! The kinetic energy removed and the gravity energy the move changes are not booked in the
//! energy ledger: they are the method's correction, and show in the balance's drift.

use super::super::DimensionDispatch;
use super::super::simulation::Simulation;
use crate::kernels::Kernel;
use crate::material::Material;
use rayon::prelude::*;

/// Physics figure: the most liquid particles put back out of an obstacle in one step.
pub const PUT_BACK: &str = "incompressible.put_back";

/// Puts every moving particle inside an obstacle at the end of the step (time `t`) back on
/// its surface; records [`PUT_BACK`]. Nothing without obstacles.
pub(super) fn put_back<const D: usize, K: Kernel>(sim: &mut Simulation<D, K>, t: f64)
where
    dyn Material: DimensionDispatch<D>,
{
    if !sim.boundaries.has_obstacles() {
        return;
    }
    let boundaries = &sim.boundaries;
    let particles = &mut sim.particles;
    let mut count = 0;
    for group in particles.groups.iter().filter(|g| !g.held) {
        let range = group.range.clone();
        count += particles.position[range.clone()]
            .par_iter_mut()
            .zip(particles.velocity[range].par_iter_mut())
            .map(|(x, v)| {
                let Some(inside) = boundaries.inside_obstacle(x, t) else {
                    return 0;
                };
                let n = inside.normal;
                *x += n * inside.depth;
                let into = (*v - inside.velocity).dot(&n);
                if into < 0.0 {
                    *v -= n * into;
                }
                1
            })
            .sum::<usize>();
    }
    sim.report.record_max(PUT_BACK, count as f64);
}
