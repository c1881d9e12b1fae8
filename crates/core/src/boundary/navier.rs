//! Where Navier-slip walls and obstacles act on the grid: the nodes that carry a surface's
//! drag, each standing for one cell face of it (`solver/incompressible/navier_slip.rs`
//! turns them into the drag μ·A/b).

use super::Boundaries;
use crate::math::Vector;

impl<const D: usize> Boundaries<D> {
    /// Whether any wall or obstacle has Navier slip.
    pub fn has_navier(&self) -> bool {
        self.walls.iter().any(|w| w.contact.slip_length().is_some())
            || self
                .obstacles
                .iter()
                .any(|o| o.contact.slip_length().is_some())
    }

    /// Calls `f(normal, slip_length, surface_velocity)` for every Navier wall and obstacle
    /// whose surface node `ijk` (at `x`, time `t`, cell `dx`) carries: a wall's node plane,
    /// and the nodes inside an obstacle less than a cell deep. A band one cell deep holds on
    /// average one node per dx^(D−1) of a plane at any angle, so each such node stands for
    /// dx^(D−1) of surface. The normal points out of the surface into the liquid.
    pub fn navier_surfaces(
        &self,
        ijk: [usize; 3],
        x: &Vector<D>,
        t: f64,
        dx: f64,
        mut f: impl FnMut(Vector<D>, f64, Vector<D>),
    ) {
        for wall in &self.walls {
            if let Some(b) = wall.contact.slip_length()
                && ijk[wall.axis] == wall.surface
                && let Some(n) = wall.normal_at::<D>(ijk)
            {
                f(n, b, Vector::<D>::zeros());
            }
        }
        for obstacle in &self.obstacles {
            let Some(b) = obstacle.contact.slip_length() else {
                continue;
            };
            let local = x - obstacle.velocity * t;
            let (phi, n) = obstacle.solid.distance_and_normal(&local);
            if phi <= 0.0 && phi > -dx {
                f(n, b, obstacle.velocity);
            }
        }
    }
}
