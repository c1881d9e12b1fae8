//! Plugins: crates that add materials, physics operators and reference solutions to the
//! solver.
//!
//! A plugin is a value implementing [`Plugin`]; the `mpm` binary registers each one in a
//! [`Registry`] with one line. The core knows no plugin by name; its own mechanics
//! references are in every registry from the start.

use crate::material::Material;
use crate::physics::PhysicsFactory;
use crate::reference::ReferenceFactory;
use crate::scene::Issue;
use crate::section::{typed_params, typed_section_schema};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// A crate's entry point: its name and what it brings.
pub trait Plugin: Send + Sync {
    /// Short unique name (`elastic`).
    fn name(&self) -> &'static str;
    /// One line for `mpm plugins`.
    fn description(&self) -> &'static str;
    /// The material types this plugin provides.
    fn materials(&self) -> Vec<Box<dyn MaterialFactory>>;
    /// The physics operators this plugin provides (scene sections `physics.<name>`).
    fn physics(&self) -> Vec<Box<dyn PhysicsFactory>> {
        Vec::new()
    }
    /// The reference solutions this plugin provides (scene section `reference`, by `type`):
    /// the closed forms its physics is verified against.
    fn references(&self) -> Vec<Box<dyn ReferenceFactory>> {
        Vec::new()
    }
}

/// Builds one material type from its scene section (`materials.<name>`).
pub trait MaterialFactory: Send + Sync {
    /// Value of the section's `type` key (`neo_hookean`).
    fn type_name(&self) -> &'static str;
    /// JSON Schema of the whole section, `type` key included.
    fn schema(&self) -> serde_json::Value;
    /// Reads and checks the section; issues carry full JSON paths below `path`.
    fn build(
        &self,
        section: &serde_json::Value,
        path: &str,
    ) -> Result<Arc<dyn Material>, Vec<Issue>>;
}

/// Registration failures.
#[derive(Debug, thiserror::Error)]
pub enum RegistryError {
    /// Two plugins claim the same material type.
    #[error("material type `{0}` is provided by two plugins (`{1}` and `{2}`)")]
    DuplicateMaterial(String, String, String),
    /// Two plugins claim the same physics section.
    #[error("physics `{0}` is provided by two plugins (`{1}` and `{2}`)")]
    DuplicatePhysics(String, String, String),
    /// Two plugins (or a plugin and the core) claim the same reference type.
    #[error("reference type `{0}` is provided twice (by `{1}` and `{2}`)")]
    DuplicateReference(String, String, String),
    /// Two plugins with one name.
    #[error("plugin `{0}` is registered twice")]
    DuplicatePlugin(String),
}

/// Reads particles (positions, volumes) from a result store, given the path, the dimension
/// and the default particle spacing. The core cannot read Zarr itself (io knows no physics
/// and core knows no io), so the binary installs one.
pub type ParticleStoreReader =
    Box<dyn Fn(&Path, usize, f64) -> Result<(Vec<f64>, Vec<f64>), String> + Send + Sync>;

/// Owner name of the references the core provides itself.
pub const CORE: &str = "core";

/// All registered plugins and what they provide, with the core's own references.
pub struct Registry {
    plugins: Vec<Box<dyn Plugin>>,
    materials: BTreeMap<&'static str, (usize, Box<dyn MaterialFactory>)>,
    physics: Vec<(usize, Box<dyn PhysicsFactory>)>,
    /// Reference types with the name of the plugin (or [`CORE`]) that provides them.
    references: BTreeMap<&'static str, (&'static str, Box<dyn ReferenceFactory>)>,
    store_reader: Option<ParticleStoreReader>,
}

impl Default for Registry {
    fn default() -> Self {
        let references = crate::reference::core_references()
            .into_iter()
            .map(|f| (f.type_name(), (CORE, f)))
            .collect();
        Self {
            plugins: Vec::new(),
            materials: BTreeMap::new(),
            physics: Vec::new(),
            references,
            store_reader: None,
        }
    }
}

impl Registry {
    /// A registry with no plugin (the core's mechanics references only).
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a plugin and its material types.
    pub fn register(&mut self, plugin: Box<dyn Plugin>) -> Result<(), RegistryError> {
        if self.plugins.iter().any(|p| p.name() == plugin.name()) {
            return Err(RegistryError::DuplicatePlugin(plugin.name().into()));
        }
        let index = self.plugins.len();
        for factory in plugin.materials() {
            let name = factory.type_name();
            if let Some((other, _)) = self.materials.get(name) {
                return Err(RegistryError::DuplicateMaterial(
                    name.into(),
                    self.plugins[*other].name().into(),
                    plugin.name().into(),
                ));
            }
            self.materials.insert(name, (index, factory));
        }
        for factory in plugin.physics() {
            let name = factory.name();
            if let Some((other, _)) = self.physics.iter().find(|(_, f)| f.name() == name) {
                return Err(RegistryError::DuplicatePhysics(
                    name.into(),
                    self.plugins[*other].name().into(),
                    plugin.name().into(),
                ));
            }
            self.physics.push((index, factory));
        }
        for factory in plugin.references() {
            let name = factory.type_name();
            if let Some((other, _)) = self.references.get(name) {
                return Err(RegistryError::DuplicateReference(
                    name.into(),
                    (*other).into(),
                    plugin.name().into(),
                ));
            }
            self.references.insert(name, (plugin.name(), factory));
        }
        self.plugins.push(plugin);
        Ok(())
    }

    /// The factory for a material type.
    pub fn material(&self, type_name: &str) -> Option<&dyn MaterialFactory> {
        self.materials.get(type_name).map(|(_, f)| f.as_ref())
    }

    /// Registered material type names, sorted.
    pub fn material_types(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.materials.keys().copied()
    }

    /// The factory for a physics section, with its position in registration order (physics
    /// run in that order, so a plugin that reads another's fields registers after it).
    pub fn physics(&self, name: &str) -> Option<(usize, &dyn PhysicsFactory)> {
        self.physics
            .iter()
            .enumerate()
            .find(|(_, (_, f))| f.name() == name)
            .map(|(k, (_, f))| (k, f.as_ref()))
    }

    /// Registered physics section names, in registration order.
    pub fn physics_names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.physics.iter().map(|(_, f)| f.name())
    }

    /// Physics sections of one plugin with their schemas.
    pub fn physics_of(&self, plugin: &str) -> Vec<(&'static str, serde_json::Value)> {
        let Some(index) = self.plugins.iter().position(|p| p.name() == plugin) else {
            return Vec::new();
        };
        self.physics
            .iter()
            .filter(|(i, _)| *i == index)
            .map(|(_, f)| (f.name(), f.schema()))
            .collect()
    }

    /// The factory for a reference type.
    pub fn reference(&self, type_name: &str) -> Option<&dyn ReferenceFactory> {
        self.references.get(type_name).map(|(_, f)| f.as_ref())
    }

    /// Registered reference types, sorted.
    pub fn reference_types(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.references.keys().copied()
    }

    /// Reference types of one plugin (or of [`CORE`]) with their schemas.
    pub fn references_of(&self, owner: &str) -> Vec<(&'static str, serde_json::Value)> {
        self.references
            .iter()
            .filter(|(_, (o, _))| *o == owner)
            .map(|(name, (_, f))| (*name, f.schema()))
            .collect()
    }

    /// Registered plugins in registration order.
    pub fn plugins(&self) -> impl Iterator<Item = &dyn Plugin> {
        self.plugins.iter().map(|p| p.as_ref())
    }

    /// Everything registered, with the JSON Schema of every section, as `GET /v1/plugins`
    /// answers and `mpm plugins` prints it: `{plugins: [{name, description, materials,
    /// physics, references}], core: {references}}`, sections keyed by name.
    pub fn catalogue(&self) -> serde_json::Value {
        let keyed = |sections: Vec<(&'static str, serde_json::Value)>| {
            sections
                .into_iter()
                .map(|(name, schema)| (name.to_string(), schema))
                .collect::<serde_json::Map<_, _>>()
        };
        let plugins: Vec<serde_json::Value> = self
            .plugins()
            .map(|p| {
                serde_json::json!({
                    "name": p.name(),
                    "description": p.description(),
                    "materials": keyed(self.materials_of(p.name())),
                    "physics": keyed(self.physics_of(p.name())),
                    "references": keyed(self.references_of(p.name())),
                })
            })
            .collect();
        serde_json::json!({
            "plugins": plugins,
            "core": { "references": keyed(self.references_of(CORE)) },
        })
    }

    /// Installs the reader used for bodies made from a result store.
    pub fn set_particle_store_reader(&mut self, reader: ParticleStoreReader) {
        self.store_reader = Some(reader);
    }

    /// Reads a body's particles from a result store (see [`ParticleStoreReader`]).
    pub fn read_particle_store(
        &self,
        path: &Path,
        dim: usize,
        spacing: f64,
    ) -> Result<(Vec<f64>, Vec<f64>), String> {
        match &self.store_reader {
            Some(read) => read(path, dim, spacing),
            None => Err("this program cannot read particle stores (no reader installed)".into()),
        }
    }

    /// Material types of one plugin with their schemas.
    pub fn materials_of(&self, plugin: &str) -> Vec<(&'static str, serde_json::Value)> {
        let Some(index) = self.plugins.iter().position(|p| p.name() == plugin) else {
            return Vec::new();
        };
        self.materials
            .iter()
            .filter(|(_, (i, _))| *i == index)
            .map(|(name, (_, f))| (*name, f.schema()))
            .collect()
    }
}

/// Checks a typed parameter section and builds the material (see [`TypedMaterialFactory`]).
pub type BuildFn<P> = fn(P, &str) -> Result<Arc<dyn Material>, Vec<Issue>>;

/// A [`MaterialFactory`] for a parameter struct `P` (serde + schemars): it strips the `type`
/// key, deserialises `P` with JSON-path errors, derives the schema, and calls `build`.
pub struct TypedMaterialFactory<P> {
    type_name: &'static str,
    build: BuildFn<P>,
}

impl<P> TypedMaterialFactory<P> {
    /// A factory for material type `type_name`.
    pub fn new(type_name: &'static str, build: BuildFn<P>) -> Self {
        Self { type_name, build }
    }
}

impl<P> MaterialFactory for TypedMaterialFactory<P>
where
    P: serde::de::DeserializeOwned + schemars::JsonSchema + Send + Sync,
{
    fn type_name(&self) -> &'static str {
        self.type_name
    }

    fn schema(&self) -> serde_json::Value {
        typed_section_schema::<P>(self.type_name, "Material type.")
    }

    fn build(
        &self,
        section: &serde_json::Value,
        path: &str,
    ) -> Result<Arc<dyn Material>, Vec<Issue>> {
        (self.build)(typed_params(section, path)?, path)
    }
}

/// Checks the usual elastic constants and returns every problem with its JSON path.
pub fn check_elastic_constants(
    path: &str,
    density: f64,
    youngs_modulus: f64,
    poisson_ratio: f64,
) -> Vec<Issue> {
    let mut issues = Vec::new();
    if !(density.is_finite() && density > 0.0) {
        issues.push(Issue::new(
            format!("{path}.density"),
            format!("must be a finite number > 0 (got {density})"),
        ));
    }
    if !(youngs_modulus.is_finite() && youngs_modulus > 0.0) {
        issues.push(Issue::new(
            format!("{path}.youngs_modulus"),
            format!("must be a finite number > 0 (got {youngs_modulus})"),
        ));
    }
    if !(poisson_ratio > -1.0 && poisson_ratio < 0.5) {
        issues.push(Issue::new(
            format!("{path}.poisson_ratio"),
            format!("must lie in (-1, 0.5) (got {poisson_ratio})"),
        ));
    }
    issues
}
