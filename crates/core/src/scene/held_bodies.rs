//! Solid bodies in incompressible mechanics: held in place and at rest where the scene puts
//! them, while the liquid flows around them. The liquid meets each one as an obstacle of the
//! body's shape, with the condition and contact angle of its `held` section (stick at 90°
//! without one), so a fill stage can run among the die, substrate and bumps that the later
//! stages of the same scene cure, cool and load.

use super::validator::Validator;
use super::{Body, Contact, Mechanics, Obstacle, ObstacleShape, Scene, Shape};
use crate::material::Material;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Whether incompressible mechanics holds bodies of `material` in place: a solid (a law
/// without a liquid viscosity) in a scene whose mechanics is incompressible.
pub fn holds(mechanics: &Mechanics, material: &dyn Material) -> bool {
    matches!(mechanics, Mechanics::Incompressible(_)) && material.liquid_viscosity().is_none()
}

/// The obstacle a held body stands for: its shape at rest, with its `held` condition and
/// contact angle.
/// `None` for a shape that has no obstacle form (a particle file, an inflow).
pub fn held_obstacle(body: &Body) -> Option<Obstacle> {
    let shape = match &body.shape {
        Shape::Box { min, max } => ObstacleShape::Box {
            min: min.clone(),
            max: max.clone(),
        },
        Shape::Sphere { center, radius } => ObstacleShape::Sphere {
            center: center.clone(),
            radius: *radius,
        },
        Shape::Cylinder {
            center,
            radius,
            axis,
            length,
        } => ObstacleShape::Cylinder {
            center: center.clone(),
            axis: axis.clone(),
            radius: *radius,
            length: Some(*length),
        },
        Shape::File { .. } | Shape::Inflow(_) => return None,
    };
    Some(Obstacle {
        name: body.name.clone(),
        shape,
        condition: body.held.as_ref().map_or(Contact::Stick, |h| h.condition),
        velocity: None,
        contact_angle: body.held.as_ref().and_then(|h| h.contact_angle),
    })
}

/// The obstacle of every held body of the scene, with the body's index, in body order.
pub fn held_obstacles<'a>(
    scene: &'a Scene,
    materials: &'a BTreeMap<String, Arc<dyn Material>>,
) -> impl Iterator<Item = (usize, Obstacle)> + 'a {
    scene
        .bodies
        .iter()
        .enumerate()
        .filter(|(_, b)| {
            materials
                .get(&b.material)
                .is_some_and(|m| holds(&scene.solver.mechanics, m.as_ref()))
        })
        .filter_map(|(i, b)| held_obstacle(b).map(|o| (i, o)))
}

/// The scene's obstacles followed by one per held body (in body order): what the grid's
/// boundaries hold in this scene.
pub fn obstacles_with_held(
    scene: &Scene,
    materials: &BTreeMap<String, Arc<dyn Material>>,
) -> Vec<Obstacle> {
    scene
        .obstacles
        .iter()
        .cloned()
        .chain(held_obstacles(scene, materials).map(|(_, o)| o))
        .collect()
}

/// Refuses what a held body cannot be: a shape without an obstacle form, holes (the
/// obstacle would fill them), an initial velocity (it stays at rest); and a `held` section
/// on a liquid body, which is never held.
pub(super) fn check(
    v: &mut Validator,
    scene: &Scene,
    materials: &BTreeMap<String, Arc<dyn Material>>,
) {
    for (i, body) in scene.bodies.iter().enumerate() {
        let Some(material) = materials.get(&body.material) else {
            continue;
        };
        let path = format!("bodies[{i}]");
        if material.liquid_viscosity().is_some() {
            if body.held.is_some() {
                v.err(
                    format!("{path}.held"),
                    "`held` is how the liquid meets a solid body that incompressible mechanics holds in place; this body is a liquid (set its angles on the walls, obstacles and solid bodies it meets)",
                );
            }
            continue;
        }
        if !holds(&scene.solver.mechanics, material.as_ref()) {
            continue;
        }
        const HELD: &str =
            "incompressible mechanics holds a solid body in place as an obstacle of its shape";
        if held_obstacle(body).is_none() {
            v.err(
                format!("{path}.shape"),
                format!("{HELD}: a box, sphere or cylinder (not a particle file or an inflow)"),
            );
        }
        if !body.holes.is_empty() {
            v.err(
                format!("{path}.holes"),
                format!("{HELD}, which would fill its holes: cut the body into boxes, spheres and cylinders instead"),
            );
        }
        if body.velocity.is_some() {
            v.err(
                format!("{path}.velocity"),
                format!("{HELD}, at rest: remove the velocity"),
            );
        }
    }
}
