//! The `obstacles` section: rigid shapes moving at constant velocity that constrain the
//! grid nodes inside them; the types and their checks.

use super::Contact;
use super::validator::Validator;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A rigid obstacle moving at constant velocity; grid nodes inside it are constrained.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Obstacle {
    /// Name for people.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// Geometry at time 0.
    pub shape: ObstacleShape,
    /// Contact condition.
    pub condition: Contact,
    /// Velocity of the obstacle (one number per dimension); zero when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<Vec<f64>>,
    /// Static contact angle, degrees, of a liquid with surface tension on the obstacle,
    /// measured through the liquid (below 90 the liquid wets it and climbs it). Without it
    /// the liquid meets the obstacle at 90°.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_angle: Option<f64>,
}

/// Geometry of a rigid obstacle.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ObstacleShape {
    /// Half-space behind a plane: the solid side is opposite to `normal`.
    Plane {
        /// A point on the plane.
        point: Vec<f64>,
        /// Outward normal (pointing into the free side).
        normal: Vec<f64>,
    },
    /// Solid axis-aligned box.
    Box {
        /// Lower corner.
        min: Vec<f64>,
        /// Upper corner.
        max: Vec<f64>,
    },
    /// Solid sphere (disk in 2D).
    Sphere {
        /// Centre.
        center: Vec<f64>,
        /// Radius.
        radius: f64,
    },
    /// Solid cylinder (3D) around an axis through `center`: infinite, or `length` long
    /// and centred on `center`.
    Cylinder {
        /// A point on the axis (the centre of a finite cylinder).
        center: Vec<f64>,
        /// Axis direction.
        axis: Vec<f64>,
        /// Radius.
        radius: f64,
        /// Length along the axis, centred on `center`; infinite without it.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        length: Option<f64>,
    },
}

impl ObstacleShape {
    /// Whether the point `x` (one number per dimension) lies strictly inside the shape at
    /// its place at time 0.
    pub fn contains(&self, x: &[f64]) -> bool {
        // (x − origin)·direction and |x − origin|², without a temporary vector (validation
        // asks this of every particle).
        let along = |origin: &[f64], direction: &[f64]| {
            x.iter()
                .zip(origin)
                .zip(direction)
                .map(|((p, o), d)| (p - o) * d)
                .sum::<f64>()
        };
        let squared = |origin: &[f64]| {
            x.iter()
                .zip(origin)
                .map(|(p, o)| (p - o).powi(2))
                .sum::<f64>()
        };
        match self {
            ObstacleShape::Plane { point, normal } => along(point, normal) < 0.0,
            ObstacleShape::Box { min, max } => x
                .iter()
                .zip(min.iter().zip(max))
                .all(|(p, (lo, hi))| p > lo && p < hi),
            ObstacleShape::Sphere { center, radius } => squared(center) < radius * radius,
            ObstacleShape::Cylinder {
                center,
                axis,
                radius,
                length,
            } => {
                let norm = axis.iter().map(|a| a * a).sum::<f64>().sqrt();
                let on_axis = along(center, axis) / norm;
                squared(center) - on_axis * on_axis < radius * radius
                    && length.is_none_or(|l| on_axis.abs() < 0.5 * l)
            }
        }
    }
}

impl Obstacle {
    /// Checks an obstacle at `path` (`obstacles[0]`): shape, contact law, velocity.
    pub(super) fn validate(&self, v: &mut Validator, path: &str) {
        match &self.shape {
            ObstacleShape::Plane { point, normal } => {
                v.vector(&format!("{path}.shape.plane.point"), point);
                v.nonzero_vector(&format!("{path}.shape.plane.normal"), normal);
            }
            ObstacleShape::Box { min, max } => {
                v.box_corners(&format!("{path}.shape.box"), min, max);
            }
            ObstacleShape::Sphere { center, radius } => {
                v.sphere(&format!("{path}.shape.sphere"), center, *radius);
            }
            ObstacleShape::Cylinder {
                center,
                axis,
                radius,
                length,
            } => {
                let p = format!("{path}.shape.cylinder");
                if let Some(length) = length {
                    v.positive(&format!("{p}.length"), *length);
                }
                if v.dim != 3 {
                    v.err(
                        &p,
                        "cylinders are 3D obstacles; use a sphere for a disk in 2D",
                    );
                }
                v.vector(&format!("{p}.center"), center);
                v.nonzero_vector(&format!("{p}.axis"), axis);
                v.positive(&format!("{p}.radius"), *radius);
            }
        }
        self.condition.validate(v, &format!("{path}.condition"));
        if self.condition == Contact::Symmetry {
            v.err(
                format!("{path}.condition"),
                "symmetry applies to walls on the domain faces only",
            );
        }
        if let Some(velocity) = &self.velocity {
            v.vector(&format!("{path}.velocity"), velocity);
        }
        super::domain::validate_contact_angle(
            v,
            &format!("{path}.contact_angle"),
            self.contact_angle,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::ObstacleShape;

    #[test]
    fn contains_is_strictly_inside_each_shape() {
        let plane = ObstacleShape::Plane {
            point: vec![0.0, 1.0],
            normal: vec![0.0, 2.0],
        };
        assert!(plane.contains(&[5.0, 0.5]) && !plane.contains(&[5.0, 1.5]));
        let cube = ObstacleShape::Box {
            min: vec![0.0, 0.0],
            max: vec![1.0, 1.0],
        };
        assert!(cube.contains(&[0.5, 0.5]) && !cube.contains(&[1.0, 0.5]));
        let disk = ObstacleShape::Sphere {
            center: vec![0.0, 0.0],
            radius: 1.0,
        };
        assert!(disk.contains(&[0.6, 0.6]) && !disk.contains(&[0.8, 0.8]));
        let rod = ObstacleShape::Cylinder {
            center: vec![0.0, 0.0, 0.0],
            axis: vec![0.0, 0.0, 3.0],
            radius: 1.0,
            length: None,
        };
        assert!(rod.contains(&[0.5, 0.5, 100.0]) && !rod.contains(&[1.0, 0.5, 0.0]));
        let post = ObstacleShape::Cylinder {
            center: vec![0.0, 0.0, 1.0],
            axis: vec![0.0, 0.0, 3.0],
            radius: 1.0,
            length: Some(2.0),
        };
        assert!(post.contains(&[0.5, 0.5, 1.9]) && !post.contains(&[0.5, 0.5, 2.1]));
        assert!(post.contains(&[0.5, 0.5, 0.1]) && !post.contains(&[0.5, 0.5, -0.1]));
    }
}
