//! Validating a parsed scene: every section checks itself where its types are defined
//! (`domain`, `solver_settings`, `body`, `obstacle`, `output`); here are the order of the
//! stages and the checks that span sections (materials and physics built by their plugins,
//! the fields they read, the reference, output fields), then the work budget and the
//! bodies' particles (`body_particles`).

use super::budget::{self, Limits};
use super::validator::Validator;
use super::{BodyParticles, Mechanics, Scene, SceneError, deserialize_at};
use crate::material::Material;
use crate::physics::Physics;
use crate::plugin::Registry;
use crate::reference::Reference;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::Arc;

/// Why a wall's or an obstacle's contact angle is refused in a scene without surface tension.
const NO_TENSION_FOR_ANGLE: &str = "a contact angle acts on a liquid with surface tension, and no material here has one (give a `liquid` a `surface_tension`, or remove the angle)";

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
    /// The stages of a staged scene, each validated as a scene of its own (empty: the
    /// scene is one stage).
    pub stages: Vec<super::ValidatedStage>,
}

impl ValidatedScene {
    /// Total particle count.
    pub fn particle_count(&self) -> usize {
        self.bodies.iter().map(|b| b.volumes.len()).sum()
    }

    /// The time the run ends: the scene's end time, or the last stage's.
    pub fn end_time(&self) -> f64 {
        self.stages.last().map_or(self.scene.solver.end_time, |s| {
            s.scene.scene.solver.end_time
        })
    }
}

/// The per-particle output field of a scene with a bonded (`cohesive`) interface: the
/// largest damage (0 intact, 1 debonded) of the interface nodes around each particle.
pub const INTERFACE_DAMAGE: &str = "interface_damage";

/// The per-particle output field of a 2D scene: σzz, the stress across the plane (plane
/// strain), from the laws that give it (`ConstitutiveLaw::plane_strain_stress`).
pub const STRESS_ZZ: &str = "stress_zz";

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
        max_particles: limits.max_particles,
    };
    v.check(&scene);
    v.issues.extend(budget::check(&scene, limits, registry));
    let reference = if v.dim == 2 || v.dim == 3 {
        v.build_reference(&scene, registry)
    } else {
        None
    };
    let materials = v.build_materials(&scene, registry);
    let physics = v.build_physics(&scene, registry, &materials);
    v.check_output_fields(&scene, &materials, &physics);
    if scene.output.checkpoint.is_some() {
        for (name, p) in &physics {
            if let Some(what) = p.hidden_state() {
                v.err(
                    "output.checkpoint",
                    format!(
                        "physics `{name}` keeps {what} between steps, which checkpoints do not \
                         hold yet: a resumed run could not continue it (remove output.checkpoint)"
                    ),
                );
            }
        }
    }
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
    v.particles_outside_obstacles(&scene, &bodies, &materials);
    v.check_loads(&scene, &bodies);
    if !v.issues.is_empty() {
        return Err(SceneError { issues: v.issues });
    }
    let json = serde_json::to_value(&scene).unwrap_or(value);
    let stages = if scene.stages.is_empty() {
        Vec::new()
    } else {
        let mut base = json.clone();
        if let Some(object) = base.as_object_mut() {
            object.remove("stages");
        }
        super::stages::validate_stages(&base, &scene.stages, registry, base_dir, limits)
            .map_err(|issues| SceneError { issues })?
    };
    Ok(ValidatedScene {
        scene,
        json,
        materials,
        bodies,
        physics,
        reference,
        stages,
    })
}

impl Validator {
    /// Refuses a liquid body (incompressible mechanics) whose particles lie inside an
    /// obstacle at time 0: the projection takes the cells inside obstacles for solid, so
    /// those particles are held there and spoil the colour and the pressure around the
    /// obstacle (between two plates that dipped into such a pool the liquid rose 1–2.5 mm
    /// where Jurin says 4.1 mm). A body is cut around an obstacle with `holes`. A solid may overlap one on
    /// purpose: a stick box that grips a body and moves it.
    /// Held solid bodies (`held_bodies.rs`) are obstacles of their shapes for this check.
    fn particles_outside_obstacles(
        &mut self,
        s: &Scene,
        bodies: &[BodyParticles],
        materials: &BTreeMap<String, Arc<dyn Material>>,
    ) {
        if !matches!(s.solver.mechanics, Mechanics::Incompressible(_)) {
            return;
        }
        let dim = s.dimension as usize;
        let held: Vec<(String, crate::scene::Obstacle)> =
            super::held_bodies::held_obstacles(s, materials)
                .map(|(i, o)| (format!("bodies[{i}] (held)"), o))
                .collect();
        let obstacles = s
            .obstacles
            .iter()
            .enumerate()
            .map(|(k, o)| (format!("obstacles[{k}]"), o))
            .chain(held.iter().map(|(name, o)| (name.clone(), o)));
        let obstacles: Vec<_> = obstacles.collect();
        for body in bodies {
            let liquid = materials
                .get(&s.bodies[body.body].material)
                .is_some_and(|m| m.liquid_viscosity().is_some());
            if !liquid {
                continue;
            }
            for (name, obstacle) in &obstacles {
                let inside = body
                    .positions
                    .chunks_exact(dim)
                    .filter(|x| obstacle.shape.contains(x))
                    .count();
                if inside > 0 {
                    self.err(
                        format!("bodies[{}]", body.body),
                        format!("{inside} of its liquid particles lie inside {name} at time 0, which the pressure solve takes for solid; cut the body around it with `holes`"),
                    );
                }
            }
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
        s.domain.validate(self);
        s.solver.validate(self);
        self.check_total_lagrangian(s);
        self.check_cpdi(s);
        self.check_refinement(s);
        if let super::Mechanics::Incompressible(settings) = &s.solver.mechanics {
            let mut walled: Vec<super::Side> = s
                .domain
                .walls
                .iter()
                .flat_map(|w| w.sides.clone())
                .collect();
            walled.sort_by_key(|side| *side as usize);
            walled.dedup();
            if settings.outflow && walled.len() >= 2 * self.dim {
                self.err(
                    "solver.mechanics.incompressible.outflow",
                    "every domain face has a wall: no liquid can leave (take a side out of \
                     domain.walls, or remove this)",
                );
            }
        }
        self.check_navier_surfaces(s);
        if s.materials.is_empty() {
            self.err("materials", "at least one material is needed");
        }
        if s.bodies.is_empty() {
            self.err("bodies", "at least one body is needed");
        }
        for (i, b) in s.bodies.iter().enumerate() {
            b.validate(self, &format!("bodies[{i}]"), s);
        }
        for (i, o) in s.obstacles.iter().enumerate() {
            o.validate(self, &format!("obstacles[{i}]"));
        }
        if let Some(contact) = &s.contact {
            contact.validate(self, s);
        }
        s.output
            .validate(self, s.domain.cell_size, s.materials.keys());
        s.stop.validate(self);
    }

    /// Navier slip is a liquid's wall law: its drag reads the liquid's viscosity, which only
    /// the incompressible mode solves for.
    fn check_navier_surfaces(&mut self, s: &Scene) {
        if matches!(s.solver.mechanics, Mechanics::Incompressible(_)) {
            return;
        }
        let walls = s
            .domain
            .walls
            .iter()
            .enumerate()
            .map(|(i, w)| (format!("domain.walls[{i}].condition"), w.condition));
        let obstacles = s
            .obstacles
            .iter()
            .enumerate()
            .map(|(i, o)| (format!("obstacles[{i}].condition"), o.condition));
        for (path, condition) in walls.chain(obstacles) {
            if condition.slip_length().is_some() {
                self.err(
                    path,
                    "`navier` slip acts on liquids in incompressible mechanics \
                     (solver.mechanics: {\"incompressible\": {}}); use `slip`, `stick` or \
                     `friction` here",
                );
            }
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
        // A material no body is made of has no particles to check (a staged scene's
        // liquid after its particles became the underfill, or the underfill before).
        let used: BTreeSet<&str> = s.bodies.iter().map(|b| b.material.as_str()).collect();
        let used_materials = || {
            materials
                .iter()
                .filter(|(name, _)| used.contains(name.as_str()))
        };
        for (name, m) in used_materials() {
            for read in m.shared_reads() {
                if read.required && !created.contains(read.name) {
                    self.err(
                        format!("materials.{name}.type"),
                        format!("this material needs the particle field `{}`, which no physics in this scene creates", read.name),
                    );
                }
            }
        }
        let incompressible = matches!(s.solver.mechanics, Mechanics::Incompressible(_));
        let mut tension: Option<(&str, f64)> = None;
        for (name, m) in materials {
            let sigma = m.surface_tension();
            match tension {
                Some((first, value)) if sigma > 0.0 && sigma != value => self.err(
                    format!("materials.{name}.surface_tension"),
                    format!("one surface tension per scene: `{first}` has {value} N/m already (liquids against each other are not modelled)"),
                ),
                None if sigma > 0.0 => tension = Some((name.as_str(), sigma)),
                _ => {}
            }
        }
        if tension.is_none() {
            for (i, wall) in s.domain.walls.iter().enumerate() {
                if wall.contact_angle.is_some() {
                    self.err(
                        format!("domain.walls[{i}].contact_angle"),
                        NO_TENSION_FOR_ANGLE,
                    );
                }
            }
            for (i, obstacle) in s.obstacles.iter().enumerate() {
                if obstacle.contact_angle.is_some() {
                    self.err(
                        format!("obstacles[{i}].contact_angle"),
                        NO_TENSION_FOR_ANGLE,
                    );
                }
            }
            for (i, body) in s.bodies.iter().enumerate() {
                if body
                    .held
                    .as_ref()
                    .is_some_and(|h| h.contact_angle.is_some())
                {
                    self.err(
                        format!("bodies[{i}].held.contact_angle"),
                        NO_TENSION_FOR_ANGLE,
                    );
                }
            }
        }
        for (name, m) in used_materials() {
            let liquid = m.liquid_viscosity().is_some();
            if liquid && !incompressible && s.solver.mechanics != Mechanics::Off {
                self.err(
                    format!("materials.{name}.type"),
                    "a liquid has no equation of state: its pressure comes from `solver.mechanics: {\"incompressible\": {}}` (with `\"off\"` it stays where it is, as the gap a grid flow physics fills)",
                );
            }
        }
        // Solids in incompressible mechanics are held in place (held_bodies.rs).
        super::held_bodies::check(self, s, materials);
        if incompressible
            && !s.bodies.is_empty()
            && used_materials().all(|(_, m)| m.liquid_viscosity().is_none())
        {
            self.err(
                "solver.mechanics.incompressible",
                "incompressible mechanics moves liquids (a material with a viscosity and no equation of state, e.g. type `liquid`), and no body is made of one: solid bodies are only held in place",
            );
        }
        if matches!(
            s.solver.mechanics,
            Mechanics::Off | Mechanics::QuasiStatic { .. }
        ) && s.physics.is_empty()
        {
            self.err(
                "solver.mechanics",
                "only a scene with physics (a `physics` section) may turn mechanics off or make it quasi-static (implicit mechanics needs none)",
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
        if s.contact.as_ref().is_some_and(|c| c.has_cohesive()) {
            known.insert(INTERFACE_DAMAGE);
        }
        if s.dimension == 2 {
            known.insert(STRESS_ZZ);
        }
        let outflow = matches!(
            s.solver.mechanics,
            super::Mechanics::Incompressible(super::IncompressibleSettings { outflow: true, .. })
        );
        if outflow
            || s.bodies
                .iter()
                .any(|b| matches!(b.shape, super::Shape::Inflow(_)))
        {
            known.insert(super::INJECTED);
        }
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
}
