//! What the incompressible mode asks of the walls and obstacles about grid cells and nodes:
//! which cells are solid, where a stray particle's cell belongs, how far a point lies from
//! the nearest obstacle, and the nodes the surface-tension colour takes images at.

use super::{Boundaries, SolidImage};
use crate::math::Vector;

impl<const D: usize> Boundaries<D> {
    /// Whether the grid cell with lowest node `ijk` lies behind a wall surface.
    pub fn cell_is_behind_wall(&self, ijk: [usize; 3]) -> bool {
        self.walls.iter().any(|w| {
            if w.upper {
                ijk[w.axis] >= w.surface
            } else {
                ijk[w.axis] < w.surface
            }
        })
    }

    /// The cell with lowest node `ijk` moved across every wall it lies behind to the first
    /// cell in front of that wall (itself when it is behind none).
    pub fn cell_in_front_of_walls(&self, mut ijk: [usize; 3]) -> [usize; 3] {
        for w in &self.walls {
            if w.upper {
                ijk[w.axis] = ijk[w.axis].min(w.surface.saturating_sub(1));
            } else {
                ijk[w.axis] = ijk[w.axis].max(w.surface);
            }
        }
        ijk
    }

    /// Whether the grid cell with lowest node `ijk` and centre `centre` lies behind a wall
    /// surface or inside an obstacle (for the incompressible mode, whose pressure sees
    /// such cells as solid, not as free surface).
    pub fn cell_is_solid(&self, ijk: [usize; 3], centre: &Vector<D>) -> bool {
        self.cell_is_behind_wall(ijk) || self.obstacle_distance(centre) < 0.0
    }

    /// The least signed distance from `x` to the obstacles at their places at time 0
    /// (negative inside one, +∞ without obstacles).
    pub fn obstacle_distance(&self, x: &Vector<D>) -> f64 {
        self.nearest_obstacle(x).map_or(f64::INFINITY, |(d, _)| d)
    }

    /// The signed distance from `x` to the nearest obstacle at its place at time 0 and
    /// that obstacle's outward normal there (`None` without obstacles).
    pub fn nearest_obstacle(&self, x: &Vector<D>) -> Option<(f64, Vector<D>)> {
        self.obstacles
            .iter()
            .map(|o| o.solid.distance_and_normal(x))
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// The grid nodes inside obstacles (at their place at time 0) within `reach` cells of
    /// the surface, and those in front of it within `front` cells, each with its depth, the
    /// nearest obstacle's normal and its contact angle (for the surface-tension colour).
    pub fn solid_images(
        &self,
        grid: &crate::grid::Grid<D>,
        reach: f64,
        front: f64,
    ) -> Vec<SolidImage<D>> {
        let mut images = Vec::new();
        for node in 0..grid.len() {
            let x = grid.position(crate::grid::node_coords(&grid.stride, node));
            let nearest = self
                .obstacles
                .iter()
                .map(|o| (o.solid.distance_and_normal(&x), o))
                .min_by(|a, b| a.0.0.total_cmp(&b.0.0));
            if let Some(((distance, normal), obstacle)) = nearest
                && -distance <= reach * grid.dx
                && distance <= front * grid.dx
            {
                // A node on the surface up to round-off is on it.
                let depth = -distance * grid.inv_dx;
                let depth = if depth.abs() < 1e-6 { 0.0 } else { depth };
                let far = (depth > 0.0)
                    .then(|| obstacle.solid.exit(&x, &-normal, reach * grid.dx))
                    .flatten();
                images.push(SolidImage {
                    node,
                    depth,
                    normal,
                    contact_angle: obstacle.contact_angle,
                    far_depth: far.map_or(f64::INFINITY, |(t, _)| t * grid.inv_dx),
                    far_normal: far.map_or(Vector::<D>::zeros(), |(_, n)| n),
                });
            }
        }
        images
    }
}
