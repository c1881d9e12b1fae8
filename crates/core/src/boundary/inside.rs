//! Which obstacle a point has crossed into: for particles that a cut face let through
//! (the grid holds nodes, not the surface between them).

use super::Boundaries;
use crate::math::Vector;

/// A point inside an obstacle: how deep, the way out, and the obstacle's own motion.
#[derive(Clone, Copy, Debug)]
pub struct Inside<const D: usize> {
    /// Distance to the nearest surface point, m (positive).
    pub depth: f64,
    /// Outward unit normal at that surface point.
    pub normal: Vector<D>,
    /// The obstacle's velocity (rigid translation).
    pub velocity: Vector<D>,
}

impl<const D: usize> Boundaries<D> {
    /// Whether there are any obstacles (held bodies included).
    pub fn has_obstacles(&self) -> bool {
        !self.obstacles.is_empty()
    }

    /// The obstacle `x` lies deepest inside at time `t` (each obstacle at its place then),
    /// or `None` when `x` is inside none (on a surface counts as outside).
    pub fn inside_obstacle(&self, x: &Vector<D>, t: f64) -> Option<Inside<D>> {
        let mut deepest: Option<Inside<D>> = None;
        for obstacle in &self.obstacles {
            let local = x - obstacle.velocity * t;
            let (phi, normal) = obstacle.solid.distance_and_normal(&local);
            if phi < 0.0 && deepest.is_none_or(|d| -phi > d.depth) {
                deepest = Some(Inside {
                    depth: -phi,
                    normal,
                    velocity: obstacle.velocity,
                });
            }
        }
        deepest
    }
}
