//! The `bodies` section: a shape (box, sphere, cylinder, particle file, inflow) filled with
//! particles of one material, its holes and initial velocity; the types and their checks.
//! The particles themselves are generated in `body_particles`.

use super::Scene;
use super::validator::Validator;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A body: a shape filled with particles of one material.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Body {
    /// Name for people and diagnostics.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// Key into `materials`.
    pub material: String,
    /// Region the particles fill.
    pub shape: Shape,
    /// Particles per cell along each axis (1 to 8).
    #[serde(default = "default_ppc")]
    pub particles_per_cell: u32,
    /// Initial velocity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<InitialVelocity>,
    /// Regions cut out of the shape (voids, holes, notches): box, sphere or cylinder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub holes: Vec<Shape>,
    /// Keep only the particles inside the domain instead of refusing the scene; for
    /// symmetry models, where a slip wall on a domain face cuts the shape in half.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub clip_to_domain: bool,
    /// How a liquid meets this solid body while incompressible mechanics holds it in place
    /// (a fill stage): stick at 90° without it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held: Option<HeldSurface>,
}

/// The surface a held solid body shows the liquid (`scene::held_bodies`).
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HeldSurface {
    /// Contact condition of the liquid on the body: `stick` (no slip, the default),
    /// `slip` or `{"navier": {"slip_length": b}}`.
    #[serde(default = "stick")]
    pub condition: super::Contact,
    /// Static contact angle, degrees, of a liquid with surface tension on the body,
    /// measured through the liquid; 90° without it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_angle: Option<f64>,
}

fn stick() -> super::Contact {
    super::Contact::Stick
}

fn default_ppc() -> u32 {
    2
}

/// A region of space.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// Axis-aligned box.
    Box {
        /// Lower corner.
        min: Vec<f64>,
        /// Upper corner.
        max: Vec<f64>,
    },
    /// Sphere (a disk in 2D).
    Sphere {
        /// Centre.
        center: Vec<f64>,
        /// Radius (> 0).
        radius: f64,
    },
    /// Cylinder (3D): a disk of `radius` swept along `axis` for `length`, centred on `center`.
    Cylinder {
        /// Centre of the cylinder.
        center: Vec<f64>,
        /// Radius (> 0).
        radius: f64,
        /// Direction of the axis (normalised on use).
        axis: Vec<f64>,
        /// Length along the axis (> 0).
        length: f64,
    },
    /// Particles read from a file: CSV with columns `x,y[,z]` and optionally `volume`, or
    /// a result store of this program (its last frame).
    File {
        /// Path, relative to the scene file's folder.
        path: String,
        /// File format.
        format: ParticleFileFormat,
    },
    /// Liquid that enters through an inlet at a set flow rate (incompressible mechanics
    /// only): the particles wait at the inlet without mass until their layer enters.
    Inflow(super::inflow::Inflow),
}

/// Formats a particle file can have.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ParticleFileFormat {
    /// Comma-separated values with a header line naming the columns.
    Csv,
    /// A Zarr store written by `mpm run`.
    Zarr,
}

/// Initial velocity of a body.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum InitialVelocity {
    /// The same velocity everywhere.
    Uniform(Vec<f64>),
    /// First axial mode of a fixed–free bar: v = amplitude · sin(π s / (2 length)) along
    /// `axis`, with s the distance from `fixed_end`.
    BarMode {
        /// Peak velocity at the free end, m/s.
        amplitude: f64,
        /// Axis of the bar (0 = x).
        axis: usize,
        /// Coordinate of the fixed end along the axis.
        fixed_end: f64,
        /// Length of the bar.
        length: f64,
    },
    /// Rigid rotation about `center` (2D: angular velocity about z; 3D: a vector).
    Rotation {
        /// Centre of rotation.
        center: Vec<f64>,
        /// Angular velocity, rad/s: one number in 2D, a vector in 3D.
        angular_velocity: Vec<f64>,
    },
    /// A linear velocity field v = G·(x − center): rotation, shear or stretching at once
    /// (e.g. a drop's oscillation mode, v = a·(x, −y)).
    Affine {
        /// Point of zero velocity.
        center: Vec<f64>,
        /// Velocity gradient G, 1/s, row by row (D·D numbers: ∂v_i/∂x_j at i·D + j).
        gradient: Vec<f64>,
    },
}

impl Shape {
    /// Checks a body shape or hole at `path` (`bodies[0].shape`).
    pub(super) fn validate(&self, v: &mut Validator, path: &str) {
        match self {
            Shape::Box { min, max } => {
                v.box_corners(&format!("{path}.box"), min, max);
            }
            Shape::Sphere { center, radius } => {
                v.sphere(&format!("{path}.sphere"), center, *radius);
            }
            Shape::Cylinder {
                center,
                radius,
                axis,
                length,
            } => {
                let p = format!("{path}.cylinder");
                if v.dim != 3 {
                    v.err(&p, "cylinders are 3D shapes; use a sphere for a disk in 2D");
                }
                v.vector(&format!("{p}.center"), center);
                v.nonzero_vector(&format!("{p}.axis"), axis);
                v.positive(&format!("{p}.radius"), *radius);
                v.positive(&format!("{p}.length"), *length);
            }
            Shape::File { path: file, .. } => {
                if file.is_empty() {
                    v.err(format!("{path}.file.path"), "must not be empty");
                }
            }
            // Checked with its body (it needs the spacing and the scene).
            Shape::Inflow(_) => {}
        }
    }
}

impl Body {
    /// Checks a body at `path` (`bodies[0]`): its material exists in `s`, its shape, holes
    /// and initial velocity.
    pub(super) fn validate(&self, v: &mut Validator, path: &str, s: &Scene) {
        if !s.materials.contains_key(&self.material) {
            let known: Vec<&str> = s.materials.keys().map(String::as_str).collect();
            v.err(
                format!("{path}.material"),
                format!(
                    "no material named `{}` (scene has: {})",
                    self.material,
                    known.join(", ")
                ),
            );
        }
        if !(1..=8).contains(&self.particles_per_cell) {
            v.err(
                format!("{path}.particles_per_cell"),
                "must be between 1 and 8",
            );
        }
        self.shape.validate(v, &format!("{path}.shape"));
        if let Some(held) = &self.held {
            let p = format!("{path}.held");
            if !matches!(
                held.condition,
                super::Contact::Stick | super::Contact::Slip | super::Contact::Navier { .. }
            ) {
                v.err(
                    format!("{p}.condition"),
                    "a held body meets the liquid with `stick`, `slip` or `navier`",
                );
            }
            held.condition.validate(v, &format!("{p}.condition"));
            super::domain::validate_contact_angle(
                v,
                &format!("{p}.contact_angle"),
                held.contact_angle,
            );
        }
        if let Shape::Inflow(inflow) = &self.shape {
            let h = s.domain.cell_size / f64::from(self.particles_per_cell.clamp(1, 8));
            inflow.validate(v, &format!("{path}.shape.inflow"), s, h);
            if !self.holes.is_empty() {
                v.err(format!("{path}.holes"), "an inflow body has no holes");
            }
            if self.velocity.is_some() {
                v.err(
                    format!("{path}.velocity"),
                    "an inflow sets its particles' velocity as they enter: remove this",
                );
            }
            if self.clip_to_domain {
                v.err(
                    format!("{path}.clip_to_domain"),
                    "an inflow's inlet lies inside the domain: remove this",
                );
            }
        }
        for (k, hole) in self.holes.iter().enumerate() {
            if matches!(hole, Shape::Inflow(_)) {
                v.err(
                    format!("{path}.holes[{k}]"),
                    "a hole is a box, sphere or cylinder",
                );
                continue;
            }
            hole.validate(v, &format!("{path}.holes[{k}]"));
        }
        match &self.velocity {
            None => {}
            Some(InitialVelocity::Uniform(velocity)) => {
                v.vector(&format!("{path}.velocity.uniform"), velocity);
            }
            Some(InitialVelocity::BarMode {
                amplitude,
                axis,
                fixed_end,
                length,
            }) => {
                let p = format!("{path}.velocity.bar_mode");
                if !amplitude.is_finite() || !fixed_end.is_finite() {
                    v.err(&p, "amplitude and fixed_end must be finite");
                }
                if *axis >= v.dim {
                    v.err(format!("{p}.axis"), format!("must be below {}", v.dim));
                }
                v.positive(&format!("{p}.length"), *length);
            }
            Some(InitialVelocity::Rotation {
                center,
                angular_velocity,
            }) => {
                let p = format!("{path}.velocity.rotation");
                v.vector(&format!("{p}.center"), center);
                let want = if v.dim == 2 { 1 } else { 3 };
                if angular_velocity.len() != want || angular_velocity.iter().any(|x| !x.is_finite())
                {
                    v.err(
                        format!("{p}.angular_velocity"),
                        format!("needs {want} finite number(s) in {}D", v.dim),
                    );
                }
            }
            Some(InitialVelocity::Affine { center, gradient }) => {
                let p = format!("{path}.velocity.affine");
                v.vector(&format!("{p}.center"), center);
                if gradient.len() != v.dim * v.dim || gradient.iter().any(|x| !x.is_finite()) {
                    v.err(
                        format!("{p}.gradient"),
                        format!(
                            "needs {} finite numbers in {}D (row by row)",
                            v.dim * v.dim,
                            v.dim
                        ),
                    );
                }
            }
        }
    }
}
