//! The Rust types of a scene file; the JSON Schema in `api/` is generated from them.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One simulation: domain, solver settings, materials, bodies, obstacles, output and an
/// optional reference solution to report the error against.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Name of the run; the result store is `<out>/<name>.zarr`. Letters, digits, `-`, `_`, `.`.
    pub name: String,
    /// Free text for people.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// 2 (plane strain) or 3.
    pub dimension: u8,
    /// The background grid and its walls.
    pub domain: Domain,
    /// Time integration, kernel, transfer and update scheme.
    pub solver: Solver,
    /// Materials by name; each has a `type` provided by a plugin (`linear_elastic`, ...).
    pub materials: BTreeMap<String, serde_json::Value>,
    /// Bodies made of particles.
    pub bodies: Vec<Body>,
    /// Rigid obstacles acting on the grid.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub obstacles: Vec<Obstacle>,
    /// Physics beyond mechanics by name (`thermal`, `phase_change`, ...), each provided by a
    /// plugin; run in the order the plugins require (see `mpm plugins`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub physics: BTreeMap<String, serde_json::Value>,
    /// What is written and how often.
    #[serde(default)]
    pub output: Output,
    /// Criteria that stop a run which is going wrong.
    #[serde(default)]
    pub stop: StopCriteria,
    /// A reference solution, selected by its `type` among those the core and the plugins
    /// register; the run reports its error against it in `metrics.error`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<serde_json::Value>,
}

/// The background grid: an axis-aligned box of cubic cells.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Domain {
    /// Lower corner (one number per dimension), metres.
    pub min: Vec<f64>,
    /// Upper corner, metres.
    pub max: Vec<f64>,
    /// Cell edge length, metres.
    pub cell_size: f64,
    /// Walls on the faces of the box; faces without a wall are open.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub walls: Vec<Wall>,
}

/// A face of the domain box.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
pub enum Side {
    /// Lower x face.
    #[serde(rename = "x-")]
    XMin,
    /// Upper x face.
    #[serde(rename = "x+")]
    XMax,
    /// Lower y face.
    #[serde(rename = "y-")]
    YMin,
    /// Upper y face.
    #[serde(rename = "y+")]
    YMax,
    /// Lower z face (3D only).
    #[serde(rename = "z-")]
    ZMin,
    /// Upper z face (3D only).
    #[serde(rename = "z+")]
    ZMax,
}

impl Side {
    /// Axis (0, 1, 2) and whether this is the upper face.
    pub fn axis_and_upper(self) -> (usize, bool) {
        match self {
            Side::XMin => (0, false),
            Side::XMax => (0, true),
            Side::YMin => (1, false),
            Side::YMax => (1, true),
            Side::ZMin => (2, false),
            Side::ZMax => (2, true),
        }
    }
}

/// A wall on one or more faces of the domain: grid nodes within `thickness` cells of the
/// face are constrained.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Wall {
    /// Faces this wall covers.
    pub sides: Vec<Side>,
    /// How the wall constrains the grid velocity.
    pub condition: Contact,
    /// Node layers constrained, counted from the face inward: the wall surface lies
    /// `thickness - 1` cells inside the face (1: on the face). Stick walls also give the
    /// ghost nodes behind the surface mirrored velocities, so the clamp is exact there.
    #[serde(default = "default_wall_thickness")]
    pub thickness: u32,
}

fn default_wall_thickness() -> u32 {
    1
}

/// How a wall or obstacle acts on the grid velocity relative to its own velocity.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Contact {
    /// No relative motion at all (fixed or glued).
    Stick,
    /// The relative velocity component into the surface is removed; sliding and separation
    /// are free.
    Slip,
    /// Like slip, with Coulomb friction on the tangential velocity.
    Friction {
        /// Coulomb friction coefficient (>= 0).
        coefficient: f64,
    },
    /// A mirror plane (walls only): the body behaves as half of a body symmetric about the
    /// wall, so a half or quarter model gives the full model's answer. Unlike `slip` it
    /// holds the body in both directions and mirrors the grid behind the wall.
    Symmetry,
}

/// Kernel (shape function) names as used in scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum KernelName {
    /// Linear tent functions.
    Linear,
    /// Uniform GIMP.
    Gimp,
    /// Quadratic B-spline.
    Bspline2,
    /// Cubic B-spline.
    Bspline3,
}

/// How particle velocities come back from the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Transfer {
    /// Particle-in-cell: dissipative, stable.
    Pic,
    /// FLIP blended with PIC by `solver.flip_blend`.
    Flip,
    /// Affine particle-in-cell: keeps angular momentum and an affine velocity per particle.
    Apic,
}

/// When the stress is updated within a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Update stress first, from the grid velocity before the momentum update.
    Usf,
    /// Update stress last, from the updated grid velocity.
    Usl,
    /// Modified USL: the updated particle velocities are mapped back to the grid first.
    Musl,
}

/// Time integration and discretisation choices.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Solver {
    /// Simulated end time, seconds.
    pub end_time: f64,
    /// Shape functions.
    #[serde(default = "default_kernel")]
    pub kernel: KernelName,
    /// Particle velocity update.
    #[serde(default = "default_transfer")]
    pub transfer: Transfer,
    /// FLIP fraction in the FLIP/PIC blend (1 = pure FLIP). Used with `transfer: flip`.
    #[serde(default = "default_flip_blend")]
    pub flip_blend: f64,
    /// Use the MLS-MPM force (needs `transfer: apic`).
    #[serde(default)]
    pub mls: bool,
    /// Stress update scheme.
    #[serde(default = "default_scheme")]
    pub scheme: Scheme,
    /// Courant number: dt = cfl · cell_size / max(|v| + c). Used when `dt` is not given.
    #[serde(default = "default_cfl")]
    pub cfl: f64,
    /// Fixed time step, seconds. Refused when it exceeds `max_cfl` times the stable step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt: Option<f64>,
    /// Largest Courant number a fixed `dt` may reach before the run refuses it.
    #[serde(default = "default_max_cfl")]
    pub max_cfl: f64,
    /// Gravity (one number per dimension), m/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<Vec<f64>>,
    /// Viscous damping rate of the grid velocity, 1/s (0 = none); for reaching equilibrium.
    #[serde(default)]
    pub damping: f64,
    /// Reorder particles by cell every this many steps, for memory locality (0 = never).
    #[serde(default = "default_sort_interval")]
    pub sort_interval: u32,
    /// Volumetric anti-locking for near-incompressible materials.
    #[serde(default, skip_serializing_if = "AntiLocking::is_none")]
    pub anti_locking: AntiLocking,
    /// How mechanics advances: explicit dynamics (the default), not at all (physics only,
    /// particles stay put), or quasi-statically (relaxed to equilibrium every step).
    #[serde(default, skip_serializing_if = "Mechanics::is_dynamic")]
    pub mechanics: Mechanics,
}

/// How the mechanical part of a step is advanced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Mechanics {
    /// Explicit dynamics: the step is bounded by the wave speed (CFL).
    #[default]
    Dynamic,
    /// No mechanics: particles keep their place and carry no stress; the step is the
    /// physics' own stable step or `solver.dt`. For heat conduction and kinetics alone.
    Off,
    /// Quasi-static: after the physics of every step (of `solver.dt` or the physics' stable
    /// step), damped explicit iterations relax the body to equilibrium under the new free
    /// strains and loads. For slow processes (cure, cool-down) where inertia plays no part.
    QuasiStatic {
        /// Most relaxation iterations per step; a step that does not converge in them stops
        /// the run with a diagnostic.
        #[serde(default = "default_relax_iterations")]
        max_iterations: u32,
        /// Converged when the kinetic energy falls below this fraction of the strain energy
        /// (and of the largest kinetic energy of the step).
        #[serde(default = "default_relax_tolerance")]
        tolerance: f64,
        /// Velocity damping rate during relaxation, 1/s; default: critical damping of the
        /// lowest mode of the domain, 2π·c/(longest domain edge).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        damping: Option<f64>,
    },
}

impl Mechanics {
    /// Whether mechanics is explicit dynamics (the default).
    pub fn is_dynamic(&self) -> bool {
        *self == Mechanics::Dynamic
    }
}

fn default_relax_iterations() -> u32 {
    5000
}
fn default_relax_tolerance() -> f64 {
    1e-6
}

/// Volumetric anti-locking options.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum AntiLocking {
    /// Each particle keeps its own volume change.
    #[default]
    None,
    /// F-bar: the volume change is averaged over the neighbouring grid nodes.
    Fbar,
}

impl AntiLocking {
    /// Whether no anti-locking is asked for.
    pub fn is_none(&self) -> bool {
        *self == AntiLocking::None
    }
}

fn default_kernel() -> KernelName {
    KernelName::Bspline2
}
fn default_transfer() -> Transfer {
    Transfer::Apic
}
fn default_flip_blend() -> f64 {
    0.99
}
fn default_scheme() -> Scheme {
    Scheme::Usl
}
fn default_cfl() -> f64 {
    0.3
}
fn default_max_cfl() -> f64 {
    1.0
}
fn default_sort_interval() -> u32 {
    16
}

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
}

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
    /// Solid infinite cylinder (3D) around an axis through `center`.
    Cylinder {
        /// A point on the axis.
        center: Vec<f64>,
        /// Axis direction.
        axis: Vec<f64>,
        /// Radius.
        radius: f64,
    },
}

/// Output schedule and fields.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Number of frames after the initial one, evenly spaced over `end_time`.
    #[serde(default = "default_frames")]
    pub frames: u32,
    /// Particle fields to store: `x`, `v`, `stress`, `F`, `J`, `mass`, `volume`, `material`,
    /// plus any field a material declares.
    #[serde(default = "default_fields")]
    pub fields: Vec<String>,
}

fn default_frames() -> u32 {
    20
}
fn default_fields() -> Vec<String> {
    vec!["x".into(), "v".into()]
}

impl Default for Output {
    fn default() -> Self {
        Self {
            frames: default_frames(),
            fields: default_fields(),
        }
    }
}

/// Bounds that stop a run going wrong; NaN/inf and det F <= 0 always stop it.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StopCriteria {
    /// Largest particle speed allowed, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_speed: Option<f64>,
    /// Largest allowed growth of the total energy, as a fraction of the largest mechanical
    /// energy (kinetic + strain) seen so far.
    #[serde(default = "default_energy_growth")]
    pub max_energy_growth: f64,
    /// Smallest time step allowed before the run stops, seconds.
    #[serde(default = "default_min_dt")]
    pub min_dt: f64,
}

fn default_energy_growth() -> f64 {
    0.5
}
fn default_min_dt() -> f64 {
    1e-14
}

impl Default for StopCriteria {
    fn default() -> Self {
        Self {
            max_speed: None,
            max_energy_growth: default_energy_growth(),
            min_dt: default_min_dt(),
        }
    }
}
