//! Checks a parsed scene against physics, geometry and the registered plugins, and generates
//! the bodies' particles (so "zero particles" and "outside the domain" are caught up front).

use super::budget::{self, Limits};
use super::lattice::{self, Region};
use super::{Issue, SceneError, deserialize_at, types::*};
use crate::material::Material;
use crate::physics::Physics;
use crate::plugin::Registry;
use crate::reference::Reference;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Particles generated for one body, dimension-erased (`dimension` numbers per particle).
#[derive(Clone, Debug, Default)]
pub struct BodyParticles {
    /// Index of the body in `scene.bodies`.
    pub body: usize,
    /// Positions, `dimension` numbers per particle.
    pub positions: Vec<f64>,
    /// Volume of each particle.
    pub volumes: Vec<f64>,
    /// Initial velocities, `dimension` numbers per particle.
    pub velocities: Vec<f64>,
    /// Particle spacing (for the GIMP particle size), metres.
    pub spacing: f64,
}

/// A scene that passed every check, with its materials built and particles generated.
pub struct ValidatedScene {
    /// The scene as parsed (defaults filled in).
    pub scene: Scene,
    /// The scene as a JSON value, defaults filled in; stored with the results.
    pub json: serde_json::Value,
    /// Built materials by name (only those bodies use).
    pub materials: BTreeMap<String, Arc<dyn Material>>,
    /// Particles of every body, in body order.
    pub bodies: Vec<BodyParticles>,
    /// Built physics operators by section name, in the order they run.
    pub physics: Vec<(String, Arc<dyn Physics>)>,
    /// The reference the run measures its error against, if the scene names one.
    pub reference: Option<Arc<dyn Reference>>,
}

impl ValidatedScene {
    /// Total particle count.
    pub fn particle_count(&self) -> usize {
        self.bodies.iter().map(|b| b.volumes.len()).sum()
    }
}

/// Particle fields the core can write, with their per-particle shape.
pub const CORE_FIELDS: &[&str] = &["x", "v", "stress", "F", "J", "mass", "volume", "material"];

/// Parses and validates scene text. `base_dir` resolves relative particle-file paths.
pub fn parse_scene(
    text: &str,
    registry: &Registry,
    base_dir: &Path,
) -> Result<ValidatedScene, SceneError> {
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| {
        SceneError::single(
            "$",
            format!(
                "not valid JSON: {e} (line {}, column {})",
                e.line(),
                e.column()
            ),
        )
    })?;
    parse_scene_value(value, registry, base_dir)
}

/// Validates a scene given as a JSON value (see [`parse_scene`]) within this process's
/// [`Limits::current`].
pub fn parse_scene_value(
    value: serde_json::Value,
    registry: &Registry,
    base_dir: &Path,
) -> Result<ValidatedScene, SceneError> {
    parse_scene_value_limited(value, registry, base_dir, &Limits::current())
}

/// Validates a scene given as a JSON value, refusing one whose estimated work exceeds
/// `limits` before any particle is generated.
pub fn parse_scene_value_limited(
    value: serde_json::Value,
    registry: &Registry,
    base_dir: &Path,
    limits: &Limits,
) -> Result<ValidatedScene, SceneError> {
    if !value.is_object() {
        return Err(SceneError::single("$", "a scene must be a JSON object"));
    }
    let scene: Scene = deserialize_at(&value, "$").map_err(|issue| SceneError {
        issues: vec![issue],
    })?;
    let mut v = Validator {
        issues: Vec::new(),
        dim: scene.dimension as usize,
    };
    v.check(&scene);
    v.issues.extend(budget::check(&scene, limits));
    let reference = if v.dim == 2 || v.dim == 3 {
        v.build_reference(&scene, registry)
    } else {
        None
    };
    let materials = v.build_materials(&scene, registry);
    let physics = v.build_physics(&scene, registry, &materials);
    v.check_output_fields(&scene, &materials, &physics);
    let bodies = if v.issues.is_empty() {
        v.generate_bodies(&scene, registry, base_dir)
    } else {
        Vec::new()
    };
    let count: usize = bodies.iter().map(|b| b.volumes.len()).sum();
    if count as u64 > limits.max_particles {
        v.err(
            "bodies",
            format!(
                "the bodies hold {count} particles; at most {} are allowed (limit `particles`)",
                limits.max_particles
            ),
        );
    }
    if !v.issues.is_empty() {
        return Err(SceneError { issues: v.issues });
    }
    let json = serde_json::to_value(&scene).unwrap_or(value);
    Ok(ValidatedScene {
        scene,
        json,
        materials,
        bodies,
        physics,
        reference,
    })
}

struct Validator {
    issues: Vec<Issue>,
    dim: usize,
}

impl Validator {
    fn err(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.issues.push(Issue::new(path, message));
    }

    fn positive(&mut self, path: &str, x: f64) {
        if !(x.is_finite() && x > 0.0) {
            self.err(path, format!("must be a finite number > 0 (got {x})"));
        }
    }

    fn vector(&mut self, path: &str, v: &[f64]) -> bool {
        if v.len() != self.dim {
            self.err(
                path,
                format!(
                    "needs {} numbers for a {}D scene (got {})",
                    self.dim,
                    self.dim,
                    v.len()
                ),
            );
            return false;
        }
        if v.iter().any(|x| !x.is_finite()) {
            self.err(path, "every number must be finite");
            return false;
        }
        true
    }

    fn nonzero_vector(&mut self, path: &str, v: &[f64]) {
        if self.vector(path, v) && v.iter().map(|x| x * x).sum::<f64>() == 0.0 {
            self.err(path, "must not be the zero vector");
        }
    }

    fn check(&mut self, s: &Scene) {
        if s.name.is_empty()
            || !s
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
            || s.name.starts_with('.')
        {
            self.err(
                "name",
                "must be non-empty and use only letters, digits, '-', '_' and '.' (not first)",
            );
        }
        if s.dimension != 2 && s.dimension != 3 {
            self.err("dimension", format!("must be 2 or 3 (got {})", s.dimension));
            return;
        }
        self.check_domain(&s.domain);
        self.check_solver(&s.solver);
        if s.materials.is_empty() {
            self.err("materials", "at least one material is needed");
        }
        if s.bodies.is_empty() {
            self.err("bodies", "at least one body is needed");
        }
        for (i, b) in s.bodies.iter().enumerate() {
            self.check_body(&format!("bodies[{i}]"), b, s);
        }
        for (i, o) in s.obstacles.iter().enumerate() {
            self.check_obstacle(&format!("obstacles[{i}]"), o);
        }
        if s.output.frames == 0 {
            self.err("output.frames", "must be at least 1");
        }
        if let Some(m) = s.stop.max_speed {
            self.positive("stop.max_speed", m);
        }
        self.positive("stop.max_energy_growth", s.stop.max_energy_growth);
        if !(s.stop.min_dt.is_finite() && s.stop.min_dt >= 0.0) {
            self.err("stop.min_dt", "must be a finite number >= 0");
        }
    }

    fn check_domain(&mut self, d: &Domain) {
        let ok_min = self.vector("domain.min", &d.min);
        let ok_max = self.vector("domain.max", &d.max);
        self.positive("domain.cell_size", d.cell_size);
        if ok_min && ok_max {
            for a in 0..self.dim {
                if d.max[a] <= d.min[a] {
                    self.err(
                        format!("domain.max[{a}]"),
                        format!("must be greater than domain.min[{a}]"),
                    );
                }
            }
            if d.cell_size > 0.0 && d.cell_size.is_finite() {
                // The grid's size is bounded in `budget`.
                for a in 0..self.dim {
                    let cells = ((d.max[a] - d.min[a]) / d.cell_size).ceil();
                    if cells < 1.0 {
                        self.err(
                            "domain.cell_size",
                            format!("the domain must be at least one cell wide on axis {a}"),
                        );
                    }
                }
            }
        }
        for (i, w) in d.walls.iter().enumerate() {
            let path = format!("domain.walls[{i}]");
            if w.sides.is_empty() {
                self.err(format!("{path}.sides"), "name at least one side");
            }
            for (j, side) in w.sides.iter().enumerate() {
                if side.axis_and_upper().0 >= self.dim {
                    self.err(
                        format!("{path}.sides[{j}]"),
                        "z sides exist only in 3D scenes",
                    );
                }
            }
            if w.thickness == 0 {
                self.err(format!("{path}.thickness"), "must be at least 1");
            }
            // The wall's node layers must fit in the domain (the solver's cell count).
            let cells = |a: usize| ((d.max[a] - d.min[a]) / d.cell_size - 1e-9).ceil();
            let sized = ok_min && ok_max && d.cell_size.is_finite() && d.cell_size > 0.0;
            let axes = w.sides.iter().map(|s| s.axis_and_upper().0);
            if let Some(a) = axes
                .filter(|&a| a < self.dim && sized)
                .find(|&a| f64::from(w.thickness) > cells(a) + 1.0 || !cells(a).is_finite())
            {
                self.err(
                    format!("{path}.thickness"),
                    format!(
                        "{} layers do not fit in the domain's {} cells on axis {a}",
                        w.thickness,
                        cells(a)
                    ),
                );
            }
            self.check_contact(&format!("{path}.condition"), w.condition);
        }
    }

    fn check_contact(&mut self, path: &str, c: Contact) {
        if let Contact::Friction { coefficient } = c
            && !(coefficient.is_finite() && coefficient >= 0.0)
        {
            self.err(
                format!("{path}.friction.coefficient"),
                "must be a finite number >= 0",
            );
        }
    }

    fn check_solver(&mut self, s: &Solver) {
        self.positive("solver.end_time", s.end_time);
        if !(s.cfl > 0.0 && s.cfl <= 1.0) {
            self.err("solver.cfl", format!("must be in (0, 1] (got {})", s.cfl));
        }
        if !(0.0..=1.0).contains(&s.flip_blend) {
            self.err("solver.flip_blend", "must be in [0, 1]");
        }
        if s.mls && s.transfer != Transfer::Apic {
            self.err("solver.mls", "the MLS-MPM force needs `transfer: apic`");
        }
        if s.mls && !matches!(s.kernel, KernelName::Bspline2 | KernelName::Bspline3) {
            self.err(
                "solver.mls",
                "the MLS-MPM force needs a B-spline kernel (constant APIC inertia)",
            );
        }
        if s.mls && s.scheme != Scheme::Usl {
            self.err(
                "solver.mls",
                "the MLS-MPM force is a USL scheme: use `scheme: usl`",
            );
        }
        if let Some(dt) = s.dt {
            self.positive("solver.dt", dt);
        }
        self.positive("solver.max_cfl", s.max_cfl);
        if let Some(g) = &s.gravity {
            self.vector("solver.gravity", g);
        }
        if !(s.damping.is_finite() && s.damping >= 0.0) {
            self.err("solver.damping", "must be a finite number >= 0");
        }
        if let Mechanics::QuasiStatic {
            max_iterations,
            tolerance,
            damping,
        } = s.mechanics
        {
            let p = "solver.mechanics.quasi_static";
            if max_iterations == 0 {
                self.err(format!("{p}.max_iterations"), "must be at least 1");
            }
            if !(tolerance > 0.0 && tolerance < 1.0) {
                self.err(
                    format!("{p}.tolerance"),
                    format!("must lie in (0, 1) (got {tolerance})"),
                );
            }
            if let Some(d) = damping {
                self.positive(&format!("{p}.damping"), d);
            }
        }
    }

    /// Checks a body shape or hole; `path` names it (`bodies[0].shape`).
    fn check_shape(&mut self, path: &str, shape: &Shape) {
        match shape {
            Shape::Box { min, max } => {
                let p = format!("{path}.box");
                if self.vector(&format!("{p}.min"), min) && self.vector(&format!("{p}.max"), max) {
                    for a in 0..self.dim {
                        if max[a] <= min[a] {
                            self.err(format!("{p}.max[{a}]"), format!("must exceed min[{a}]"));
                        }
                    }
                }
            }
            Shape::Sphere { center, radius } => {
                self.vector(&format!("{path}.sphere.center"), center);
                self.positive(&format!("{path}.sphere.radius"), *radius);
            }
            Shape::Cylinder {
                center,
                radius,
                axis,
                length,
            } => {
                let p = format!("{path}.cylinder");
                if self.dim != 3 {
                    self.err(&p, "cylinders are 3D shapes; use a sphere for a disk in 2D");
                }
                self.vector(&format!("{p}.center"), center);
                self.nonzero_vector(&format!("{p}.axis"), axis);
                self.positive(&format!("{p}.radius"), *radius);
                self.positive(&format!("{p}.length"), *length);
            }
            Shape::File { path: file, .. } => {
                if file.is_empty() {
                    self.err(format!("{path}.file.path"), "must not be empty");
                }
            }
        }
    }

    fn check_body(&mut self, path: &str, b: &Body, s: &Scene) {
        if !s.materials.contains_key(&b.material) {
            let known: Vec<&str> = s.materials.keys().map(String::as_str).collect();
            self.err(
                format!("{path}.material"),
                format!(
                    "no material named `{}` (scene has: {})",
                    b.material,
                    known.join(", ")
                ),
            );
        }
        if !(1..=8).contains(&b.particles_per_cell) {
            self.err(
                format!("{path}.particles_per_cell"),
                "must be between 1 and 8",
            );
        }
        self.check_shape(&format!("{path}.shape"), &b.shape);
        for (k, hole) in b.holes.iter().enumerate() {
            self.check_shape(&format!("{path}.holes[{k}]"), hole);
        }
        match &b.velocity {
            None => {}
            Some(InitialVelocity::Uniform(v)) => {
                self.vector(&format!("{path}.velocity.uniform"), v);
            }
            Some(InitialVelocity::BarMode {
                amplitude,
                axis,
                fixed_end,
                length,
            }) => {
                let p = format!("{path}.velocity.bar_mode");
                if !amplitude.is_finite() || !fixed_end.is_finite() {
                    self.err(&p, "amplitude and fixed_end must be finite");
                }
                if *axis >= self.dim {
                    self.err(format!("{p}.axis"), format!("must be below {}", self.dim));
                }
                self.positive(&format!("{p}.length"), *length);
            }
            Some(InitialVelocity::Rotation {
                center,
                angular_velocity,
            }) => {
                let p = format!("{path}.velocity.rotation");
                self.vector(&format!("{p}.center"), center);
                let want = if self.dim == 2 { 1 } else { 3 };
                if angular_velocity.len() != want || angular_velocity.iter().any(|x| !x.is_finite())
                {
                    self.err(
                        format!("{p}.angular_velocity"),
                        format!("needs {want} finite number(s) in {}D", self.dim),
                    );
                }
            }
        }
    }

    fn check_obstacle(&mut self, path: &str, o: &Obstacle) {
        match &o.shape {
            ObstacleShape::Plane { point, normal } => {
                self.vector(&format!("{path}.shape.plane.point"), point);
                self.nonzero_vector(&format!("{path}.shape.plane.normal"), normal);
            }
            ObstacleShape::Box { min, max } => {
                let p = format!("{path}.shape.box");
                if self.vector(&format!("{p}.min"), min) && self.vector(&format!("{p}.max"), max) {
                    for a in 0..self.dim {
                        if max[a] <= min[a] {
                            self.err(format!("{p}.max[{a}]"), format!("must exceed min[{a}]"));
                        }
                    }
                }
            }
            ObstacleShape::Sphere { center, radius } => {
                self.vector(&format!("{path}.shape.sphere.center"), center);
                self.positive(&format!("{path}.shape.sphere.radius"), *radius);
            }
            ObstacleShape::Cylinder {
                center,
                axis,
                radius,
            } => {
                let p = format!("{path}.shape.cylinder");
                if self.dim != 3 {
                    self.err(
                        &p,
                        "cylinders are 3D obstacles; use a sphere for a disk in 2D",
                    );
                }
                self.vector(&format!("{p}.center"), center);
                self.nonzero_vector(&format!("{p}.axis"), axis);
                self.positive(&format!("{p}.radius"), *radius);
            }
        }
        self.check_contact(&format!("{path}.condition"), o.condition);
        if o.condition == Contact::Symmetry {
            self.err(
                format!("{path}.condition"),
                "symmetry applies to walls on the domain faces only",
            );
        }
        if let Some(v) = &o.velocity {
            self.vector(&format!("{path}.velocity"), v);
        }
    }

    /// Builds the scene's reference with the factory its `type` names.
    fn build_reference(&mut self, s: &Scene, registry: &Registry) -> Option<Arc<dyn Reference>> {
        let section = s.reference.as_ref()?;
        let Some(type_name) = section.get("type").and_then(|t| t.as_str()) else {
            self.err(
                "reference.type",
                "missing: a reference needs a `type` string",
            );
            return None;
        };
        let Some(factory) = registry.reference(type_name) else {
            let known: Vec<&str> = registry.reference_types().collect();
            self.err(
                "reference.type",
                format!(
                    "unknown reference type `{type_name}` (registered: {})",
                    known.join(", ")
                ),
            );
            return None;
        };
        match factory.build(section, "reference", s) {
            Ok(r) => Some(r),
            Err(issues) => {
                self.issues.extend(issues);
                None
            }
        }
    }

    fn build_materials(
        &mut self,
        s: &Scene,
        registry: &Registry,
    ) -> BTreeMap<String, Arc<dyn Material>> {
        let mut out = BTreeMap::new();
        for (name, section) in &s.materials {
            let path = format!("materials.{name}");
            let Some(type_name) = section.get("type").and_then(|t| t.as_str()) else {
                self.err(
                    format!("{path}.type"),
                    "missing: every material needs a `type` string",
                );
                continue;
            };
            let Some(factory) = registry.material(type_name) else {
                let known: Vec<&str> = registry.material_types().collect();
                self.err(
                    format!("{path}.type"),
                    format!(
                        "unknown material type `{type_name}` (registered: {})",
                        known.join(", ")
                    ),
                );
                continue;
            };
            match factory.build(section, &path) {
                Ok(m) => {
                    out.insert(name.clone(), m);
                }
                Err(issues) => self.issues.extend(issues),
            }
        }
        out
    }

    /// Builds the scene's physics sections in registry order and checks that every field an
    /// operator or a material reads is created by some operator.
    fn build_physics(
        &mut self,
        s: &Scene,
        registry: &Registry,
        materials: &BTreeMap<String, Arc<dyn Material>>,
    ) -> Vec<(String, Arc<dyn Physics>)> {
        let mut built = Vec::new();
        for (name, section) in &s.physics {
            let path = format!("physics.{name}");
            let Some((order, factory)) = registry.physics(name) else {
                let known: Vec<&str> = registry.physics_names().collect();
                self.err(
                    path,
                    format!(
                        "unknown physics `{name}` (registered: {})",
                        if known.is_empty() {
                            "none".to_string()
                        } else {
                            known.join(", ")
                        }
                    ),
                );
                continue;
            };
            match factory.build(section, &path, s) {
                Ok(p) => built.push((order, name.clone(), p)),
                Err(issues) => self.issues.extend(issues),
            }
        }
        built.sort_by_key(|(order, _, _)| *order);
        let created: BTreeSet<&str> = built
            .iter()
            .flat_map(|(_, _, p)| p.fields().into_iter().map(|f| f.name))
            .collect();
        for (_, name, p) in &built {
            for field in p.requires() {
                if !created.contains(field) {
                    self.err(
                        format!("physics.{name}"),
                        format!("needs the particle field `{field}`, which no physics in this scene creates (add the physics that provides it, e.g. `physics.thermal` for `temperature`)"),
                    );
                }
            }
        }
        for (name, m) in materials {
            for read in m.shared_reads() {
                if read.required && !created.contains(read.name) {
                    self.err(
                        format!("materials.{name}.type"),
                        format!("this material needs the particle field `{}`, which no physics in this scene creates", read.name),
                    );
                }
            }
        }
        if !s.solver.mechanics.is_dynamic() && s.physics.is_empty() {
            self.err(
                "solver.mechanics",
                "only a scene with physics (a `physics` section) may turn dynamics off",
            );
        }
        built.into_iter().map(|(_, n, p)| (n, p)).collect()
    }

    fn check_output_fields(
        &mut self,
        s: &Scene,
        materials: &BTreeMap<String, Arc<dyn Material>>,
        physics: &[(String, Arc<dyn Physics>)],
    ) {
        if physics.len() < s.physics.len() {
            // A physics section failed to build: its fields are unknown, not wrong.
            return;
        }
        let mut known: BTreeSet<&str> = CORE_FIELDS.iter().copied().collect();
        for (_, p) in physics {
            for f in p.fields() {
                known.insert(f.name);
            }
        }
        for m in materials.values() {
            for f in m.state_fields() {
                known.insert(f.name);
            }
        }
        let mut seen = BTreeSet::new();
        for (i, f) in s.output.fields.iter().enumerate() {
            if !known.contains(f.as_str()) {
                let list: Vec<&str> = known.iter().copied().collect();
                self.err(
                    format!("output.fields[{i}]"),
                    format!("unknown field `{f}` (available: {})", list.join(", ")),
                );
            }
            if !seen.insert(f.as_str()) {
                self.err(
                    format!("output.fields[{i}]"),
                    format!("`{f}` is listed twice"),
                );
            }
        }
    }

    fn generate_bodies(
        &mut self,
        s: &Scene,
        registry: &Registry,
        base_dir: &Path,
    ) -> Vec<BodyParticles> {
        let dim = self.dim;
        let dx = s.domain.cell_size;
        let mut out = Vec::new();
        let mut domain = Region {
            lo: [0.0; 3],
            hi: [0.0; 3],
        };
        domain.lo[..dim].copy_from_slice(&s.domain.min);
        domain.hi[..dim].copy_from_slice(&s.domain.max);
        for (i, b) in s.bodies.iter().enumerate() {
            let path = format!("bodies[{i}]");
            let h = dx / b.particles_per_cell as f64;
            let mut body = BodyParticles {
                body: i,
                spacing: h,
                ..Default::default()
            };
            // Only the lattice points where particles may lie are visited (`budget`).
            let region = budget::body_region(&domain, dx, b.clip_to_domain);
            let bounds = lattice::bounding_box(dim, &b.shape).map(|r| r.intersect(&region));
            let bounds = bounds.unwrap_or(region);
            let filled = match &b.shape {
                Shape::Box { min, max } => lattice::fill_box(dim, min, max, h, &region, &mut body),
                Shape::Sphere { center, radius } => lattice::fill_lattice(
                    dim,
                    center,
                    *radius,
                    h,
                    [0.5; 3],
                    &bounds,
                    &mut body,
                    |r| r.iter().map(|x| x * x).sum::<f64>() <= radius * radius,
                ),
                Shape::Cylinder {
                    center,
                    radius,
                    axis,
                    length,
                } => {
                    let norm = axis.iter().map(|x| x * x).sum::<f64>().sqrt();
                    let a: Vec<f64> = axis.iter().map(|x| x / norm).collect();
                    let reach = (radius * radius + length * length / 4.0).sqrt();
                    // Along a coordinate axis, fit the layers to the length exactly: an odd
                    // number of layers puts one on the centre, an even number straddles it.
                    let mut offset = [0.5; 3];
                    if let Some(k) = a.iter().position(|x| (x.abs() - 1.0).abs() < 1e-12) {
                        let layers = (length / h).round() as i64;
                        if layers % 2 == 1 && ((layers as f64) * h - length).abs() < 1e-9 * length {
                            offset[k] = 0.0;
                        }
                    }
                    lattice::fill_lattice(dim, center, reach, h, offset, &bounds, &mut body, |r| {
                        let along: f64 = r.iter().zip(&a).map(|(x, y)| x * y).sum();
                        let r2: f64 = r.iter().map(|x| x * x).sum::<f64>() - along * along;
                        along.abs() <= length / 2.0 && r2 <= radius * radius
                    })
                }
                Shape::File { path: file, format } => {
                    let full: PathBuf = base_dir.join(file);
                    let loaded = match format {
                        ParticleFileFormat::Csv => read_csv_particles(&full, dim, h),
                        ParticleFileFormat::Zarr => registry.read_particle_store(&full, dim, h),
                    };
                    match loaded {
                        Ok((positions, volumes)) => {
                            body.positions = positions;
                            body.volumes = volumes;
                            Ok(())
                        }
                        Err(message) => {
                            self.err(format!("{path}.shape.file.path"), message);
                            continue;
                        }
                    }
                }
            };
            if let Err(message) = filled {
                self.err(format!("{path}.shape"), message);
                continue;
            }
            for (h_index, hole) in b.holes.iter().enumerate() {
                if matches!(hole, Shape::File { .. }) {
                    self.err(
                        format!("{path}.holes[{h_index}]"),
                        "a hole is a box, sphere or cylinder",
                    );
                    continue;
                }
                let keep: Vec<bool> = body
                    .positions
                    .chunks_exact(dim)
                    .map(|x| !shape_contains(hole, x))
                    .collect();
                retain_particles(&mut body, dim, &keep);
            }
            if b.clip_to_domain {
                let keep: Vec<bool> = body
                    .positions
                    .chunks_exact(dim)
                    .map(|x| (0..dim).all(|a| x[a] >= s.domain.min[a] && x[a] <= s.domain.max[a]))
                    .collect();
                retain_particles(&mut body, dim, &keep);
            }
            let n = body.volumes.len();
            if n == 0 {
                self.err(
                    format!("{path}.shape"),
                    "the shape holds zero particles (it is smaller than the particle spacing)",
                );
                continue;
            }
            // Every particle must lie in the domain (the grid is padded beyond it so every
            // kernel's stencil fits).
            let mut outside = None;
            for p in 0..n {
                for a in 0..dim {
                    let x = body.positions[p * dim + a];
                    if !(x >= s.domain.min[a] && x <= s.domain.max[a]) {
                        outside = Some((p, a, x));
                        break;
                    }
                }
                if outside.is_some() {
                    break;
                }
            }
            if let Some((p, a, x)) = outside {
                self.err(
                    format!("{path}.shape"),
                    format!(
                        "particle {p} lies at {x} on axis {a}, outside the domain [{}, {}]",
                        s.domain.min[a], s.domain.max[a]
                    ),
                );
                continue;
            }
            body.velocities = initial_velocities(dim, &body.positions, b.velocity.as_ref());
            out.push(body);
        }
        out
    }
}

/// Keeps the particles whose `keep` entry is true.
fn retain_particles(body: &mut BodyParticles, dim: usize, keep: &[bool]) {
    let mut k = 0;
    body.positions.retain(|_| {
        let inside = keep[k / dim];
        k += 1;
        inside
    });
    let mut k = 0;
    body.volumes.retain(|_| {
        let inside = keep[k];
        k += 1;
        inside
    });
}

/// Whether point `x` lies in a box, sphere or cylinder (never in a file shape).
fn shape_contains(shape: &Shape, x: &[f64]) -> bool {
    match shape {
        Shape::Box { min, max } => x
            .iter()
            .enumerate()
            .all(|(a, v)| *v >= min[a] && *v <= max[a]),
        Shape::Sphere { center, radius } => {
            x.iter()
                .zip(center)
                .map(|(a, c)| (a - c).powi(2))
                .sum::<f64>()
                <= radius * radius
        }
        Shape::Cylinder {
            center,
            radius,
            axis,
            length,
        } => {
            let norm = axis.iter().map(|a| a * a).sum::<f64>().sqrt();
            let r = x.iter().zip(center).map(|(a, c)| a - c);
            let along: f64 = r.clone().zip(axis).map(|(a, b)| a * b / norm).sum();
            let r2: f64 = r.map(|a| a * a).sum::<f64>() - along * along;
            along.abs() <= length / 2.0 && r2 <= radius * radius
        }
        Shape::File { .. } => false,
    }
}

fn initial_velocities(dim: usize, positions: &[f64], spec: Option<&InitialVelocity>) -> Vec<f64> {
    let n = positions.len() / dim;
    let mut v = vec![0.0; n * dim];
    for p in 0..n {
        let x = &positions[p * dim..(p + 1) * dim];
        let out = &mut v[p * dim..(p + 1) * dim];
        match spec {
            None => {}
            Some(InitialVelocity::Uniform(u)) => out.copy_from_slice(u),
            Some(InitialVelocity::BarMode {
                amplitude,
                axis,
                fixed_end,
                length,
            }) => {
                let s = x[*axis] - fixed_end;
                out[*axis] = amplitude * (std::f64::consts::PI * s / (2.0 * length)).sin();
            }
            Some(InitialVelocity::Rotation {
                center,
                angular_velocity,
            }) => {
                let r: Vec<f64> = (0..dim).map(|a| x[a] - center[a]).collect();
                if dim == 2 {
                    let w = angular_velocity[0];
                    out[0] = -w * r[1];
                    out[1] = w * r[0];
                } else {
                    let w = angular_velocity;
                    out[0] = w[1] * r[2] - w[2] * r[1];
                    out[1] = w[2] * r[0] - w[0] * r[2];
                    out[2] = w[0] * r[1] - w[1] * r[0];
                }
            }
        }
    }
    v
}

/// Reads particles from CSV: a header naming columns `x`, `y` (and `z` in 3D), optionally
/// `volume`; without it each particle gets `spacing^dim`.
pub fn read_csv_particles(
    path: &Path,
    dim: usize,
    spacing: f64,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let limits = Limits::current();
    let size = std::fs::metadata(path)
        .map_err(|e| format!("cannot read `{}`: {e}", path.display()))?
        .len();
    if size > limits.max_file_bytes {
        return Err(format!(
            "`{}` has {size} bytes; at most {} are read (limit `file_bytes`)",
            path.display(),
            limits.max_file_bytes
        ));
    }
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read `{}`: {e}", path.display()))?;
    let rows = text.lines().filter(|l| !l.trim().is_empty()).count();
    if rows.saturating_sub(1) as u64 > limits.max_particles {
        return Err(format!(
            "`{}` holds {} particles; at most {} are allowed (limit `particles`)",
            path.display(),
            rows - 1,
            limits.max_particles
        ));
    }
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        return Err(format!("`{}` is empty", path.display()));
    };
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |name: &str| cols.iter().position(|c| *c == name);
    let names = ["x", "y", "z"];
    let mut idx = Vec::new();
    for name in names.iter().take(dim) {
        idx.push(
            find(name).ok_or_else(|| {
                format!("`{}`: the header has no `{name}` column", path.display())
            })?,
        );
    }
    let vol_col = find("volume");
    let default_volume = spacing.powi(dim as i32);
    let (mut pos, mut vol) = (Vec::new(), Vec::new());
    for (line_no, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let get = |c: usize| -> Result<f64, String> {
            let s = fields.get(c).ok_or_else(|| {
                format!(
                    "`{}` line {}: missing column {}",
                    path.display(),
                    line_no + 1,
                    c + 1
                )
            })?;
            let x: f64 = s.parse().map_err(|_| {
                format!(
                    "`{}` line {}: `{s}` is not a number",
                    path.display(),
                    line_no + 1
                )
            })?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(format!(
                    "`{}` line {}: non-finite number",
                    path.display(),
                    line_no + 1
                ))
            }
        };
        for &c in &idx {
            pos.push(get(c)?);
        }
        let v = match vol_col {
            Some(c) => get(c)?,
            None => default_volume,
        };
        if v <= 0.0 {
            return Err(format!(
                "`{}` line {}: volume must be > 0",
                path.display(),
                line_no + 1
            ));
        }
        vol.push(v);
    }
    Ok((pos, vol))
}
