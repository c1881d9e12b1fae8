//! Reference solutions a run measures its error against (the scene's `reference` section).
//!
//! A reference is registered by the crate that owns its physics, as materials and physics
//! operators are: the core keeps the mechanics references it owns (vibrating bar, heavy
//! elastica, bimaterial strip, Kirsch plate, Poiseuille start-up); the plugins add theirs (Taylor bar, heat conduction,
//! Stefan, cure, capillary filling). An author writes a [`ReferenceLaw`] (generic over the
//! dimension, like a material's `ConstitutiveLaw`) and a parameter struct, and returns a
//! [`TypedReferenceFactory`] from `Plugin::references`.

mod bimaterial_strip;
mod cantilever_elastica;
mod kirsch_plate;
mod layered_strip;
mod peak_displacement;
mod poiseuille_slip;
mod poiseuille_startup;
mod vibrating_bar;

pub use bimaterial_strip::bimaterial_curvature;
pub use cantilever_elastica::heavy_elastica_tip_deflection;
pub use kirsch_plate::kirsch_stress_along_load;
pub use layered_strip::{Layer, LayeredStripParams, layered_strip_solution};
pub use poiseuille_slip::poiseuille_slip_startup_profile;
pub use poiseuille_startup::{poiseuille_startup_profile, poiseuille_startup_velocity};

use crate::output::Comparison;
use crate::particles::Particles;
use crate::scene::{Issue, Scene};
use crate::section::{typed_params, typed_section_schema};
use std::sync::Arc;

/// One output frame as a reference sees it.
#[derive(Clone, Copy)]
pub struct Frame<'a, const D: usize> {
    /// The particles (in storage order; `particles.id` maps to output order).
    pub particles: &'a Particles<D>,
    /// Simulated time of the frame.
    pub time: f64,
    /// Whether this is the run's last frame.
    pub last: bool,
}

/// What a reference author writes: the error measure of one run, accumulated frame by
/// frame. The value built from the scene is the state before any frame; every run starts
/// from a clone of it.
/// Its state is serde data, so a checkpoint keeps the error accumulated so far and a
/// resumed run reports the same error as an uninterrupted one.
pub trait ReferenceLaw:
    Clone + Send + Sync + serde::Serialize + serde::de::DeserializeOwned + 'static
{
    /// What the error measures, in words, for the metrics (`error_kind`).
    fn kind(&self) -> &'static str;
    /// Whether [`Frame::particles`] must carry each particle's initial position.
    fn needs_initial_positions(&self) -> bool {
        false
    }
    /// Takes one output frame into account (the first is the initial state at t = 0).
    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>);
    /// The error so far (`None` before anything was measured).
    fn error(&self) -> Option<f64>;
    /// Reference value, where the error compares two numbers.
    fn expected(&self) -> Option<f64> {
        None
    }
    /// Measured value, where the error compares two numbers.
    fn measured(&self) -> Option<f64> {
        None
    }
    /// Further quantities compared with reference values.
    fn comparisons(&self) -> Vec<Comparison> {
        Vec::new()
    }
}

/// A reference as the solver holds it (object-safe; every [`ReferenceLaw`] is one).
pub trait Reference: Send + Sync {
    /// A tracker for a new run, with nothing observed.
    fn start(&self) -> Box<dyn Reference>;
    /// See [`ReferenceLaw::kind`].
    fn kind(&self) -> &'static str;
    /// See [`ReferenceLaw::needs_initial_positions`].
    fn needs_initial_positions(&self) -> bool;
    /// Observes a 2D frame.
    fn observe_2d(&mut self, frame: Frame<'_, 2>);
    /// Observes a 3D frame.
    fn observe_3d(&mut self, frame: Frame<'_, 3>);
    /// See [`ReferenceLaw::error`].
    fn error(&self) -> Option<f64>;
    /// See [`ReferenceLaw::expected`].
    fn expected(&self) -> Option<f64>;
    /// See [`ReferenceLaw::measured`].
    fn measured(&self) -> Option<f64>;
    /// See [`ReferenceLaw::comparisons`].
    fn comparisons(&self) -> Vec<Comparison>;
    /// The state accumulated so far, for a checkpoint.
    fn save_state(&self) -> serde_json::Value;
    /// Takes back the state [`Reference::save_state`] gave.
    fn restore_state(&mut self, state: serde_json::Value) -> Result<(), String>;
}

impl<T: ReferenceLaw> Reference for T {
    fn start(&self) -> Box<dyn Reference> {
        Box::new(self.clone())
    }
    fn kind(&self) -> &'static str {
        ReferenceLaw::kind(self)
    }
    fn needs_initial_positions(&self) -> bool {
        ReferenceLaw::needs_initial_positions(self)
    }
    fn observe_2d(&mut self, frame: Frame<'_, 2>) {
        self.observe::<2>(frame)
    }
    fn observe_3d(&mut self, frame: Frame<'_, 3>) {
        self.observe::<3>(frame)
    }
    fn error(&self) -> Option<f64> {
        ReferenceLaw::error(self)
    }
    fn expected(&self) -> Option<f64> {
        ReferenceLaw::expected(self)
    }
    fn measured(&self) -> Option<f64> {
        ReferenceLaw::measured(self)
    }
    fn comparisons(&self) -> Vec<Comparison> {
        ReferenceLaw::comparisons(self)
    }
    fn save_state(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }
    fn restore_state(&mut self, state: serde_json::Value) -> Result<(), String> {
        *self = serde_json::from_value(state).map_err(|e| e.to_string())?;
        Ok(())
    }
}

/// Builds one reference type from the scene's `reference` section.
pub trait ReferenceFactory: Send + Sync {
    /// Value of the section's `type` key (`vibrating_bar`).
    fn type_name(&self) -> &'static str;
    /// JSON Schema of the whole section, `type` key included.
    fn schema(&self) -> serde_json::Value;
    /// Reads and checks the section against the scene (its dimension, say); issues carry
    /// full JSON paths below `path`.
    fn build(
        &self,
        section: &serde_json::Value,
        path: &str,
        scene: &Scene,
    ) -> Result<Arc<dyn Reference>, Vec<Issue>>;
}

/// Checks a typed reference section and builds the reference (see [`TypedReferenceFactory`]).
pub type BuildReferenceFn<P> = fn(P, &str, &Scene) -> Result<Arc<dyn Reference>, Vec<Issue>>;

/// A [`ReferenceFactory`] for a parameter struct `P` (serde + schemars): it strips the
/// `type` key, deserialises `P` with JSON-path errors, derives the schema, calls `build`.
pub struct TypedReferenceFactory<P> {
    type_name: &'static str,
    build: BuildReferenceFn<P>,
}

impl<P> TypedReferenceFactory<P> {
    /// A factory for reference type `type_name`.
    pub fn new(type_name: &'static str, build: BuildReferenceFn<P>) -> Self {
        Self { type_name, build }
    }
}

impl<P> ReferenceFactory for TypedReferenceFactory<P>
where
    P: serde::de::DeserializeOwned + schemars::JsonSchema + Send + Sync,
{
    fn type_name(&self) -> &'static str {
        self.type_name
    }

    fn schema(&self) -> serde_json::Value {
        typed_section_schema::<P>(self.type_name, "Reference type.")
    }

    fn build(
        &self,
        section: &serde_json::Value,
        path: &str,
        scene: &Scene,
    ) -> Result<Arc<dyn Reference>, Vec<Issue>> {
        (self.build)(typed_params(section, path)?, path, scene)
    }
}

/// The references the core owns (mechanics), present in every registry.
pub fn core_references() -> Vec<Box<dyn ReferenceFactory>> {
    vec![
        vibrating_bar::factory(),
        cantilever_elastica::factory(),
        bimaterial_strip::factory(),
        layered_strip::factory(),
        kirsch_plate::factory(),
        poiseuille_startup::factory(),
        peak_displacement::factory(),
    ]
}

/// A relative L2 error accumulated over frames: sqrt(Σ error² / Σ reference²).
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct RelativeL2 {
    numerator: f64,
    denominator: f64,
}

impl RelativeL2 {
    /// Adds one term: the squared error and the squared reference it is relative to.
    pub fn add(&mut self, error_squared: f64, reference_squared: f64) {
        self.numerator += error_squared;
        self.denominator += reference_squared;
    }

    /// The error so far (`None` while the reference sum is zero).
    pub fn value(&self) -> Option<f64> {
        (self.denominator > 0.0).then(|| (self.numerator / self.denominator).sqrt())
    }
}

/// A comparison of a measured quantity with its reference value.
pub fn compare(quantity: &str, measured: f64, reference: f64) -> Comparison {
    Comparison {
        quantity: quantity.into(),
        measured,
        reference,
        relative_difference: (measured - reference) / reference,
    }
}

/// The issues `factory` finds with a reference `section` in a `dimension`-D scene, as
/// (JSON path, message) pairs (none when it builds); for the unit tests of the checks.
#[doc(hidden)]
pub fn section_issues(
    factory: &dyn ReferenceFactory,
    section: &serde_json::Value,
    dimension: usize,
) -> Vec<(String, String)> {
    match factory.build(section, "reference", &crate::scene::test_scene(dimension)) {
        Ok(_) => Vec::new(),
        Err(issues) => issues.into_iter().map(|i| (i.path, i.message)).collect(),
    }
}

/// Asserts that each `(overrides, path, words)` case, applied to the valid section `base`,
/// gives exactly one issue, at `path`, whose message contains `words` (2D scene).
#[doc(hidden)]
pub fn assert_each_names_its_path(
    factory: &dyn ReferenceFactory,
    base: &serde_json::Value,
    cases: &[(serde_json::Value, &str, &str)],
) {
    for (overrides, path, words) in cases {
        let mut section = base.clone();
        for (k, v) in overrides.as_object().expect("an object") {
            section[k] = v.clone();
        }
        let found = section_issues(factory, &section, 2);
        assert_eq!(found.len(), 1, "{overrides}: {found:?}");
        assert_eq!(found[0].0, *path, "{found:?}");
        assert!(found[0].1.contains(words), "{found:?}");
    }
}

/// Test particles for reference unit tests: positions, volumes and zeroed shared fields
/// named `fields` (no material groups).
#[doc(hidden)]
pub fn test_particles<const D: usize>(
    positions: &[[f64; D]],
    volumes: &[f64],
    fields: &[&'static str],
) -> Particles<D> {
    let n = positions.len();
    let mut shared = crate::physics::ParticleFields::default();
    for name in fields {
        shared.add(crate::physics::SharedFieldSpec { name, initial: 0.0 }, n);
    }
    Particles {
        position: positions
            .iter()
            .map(|p| crate::math::vector_from_slice(p))
            .collect(),
        velocity: vec![crate::math::Vector::<D>::zeros(); n],
        mass: vec![1.0; n],
        volume0: volumes.to_vec(),
        deformation_gradient: Vec::new(),
        stress: Vec::new(),
        stress_zz: Vec::new(),
        affine: Vec::new(),
        velocity_gradient: Vec::new(),
        half_size: Vec::new(),
        initial_position: Vec::new(),
        external_force: Vec::new(),
        id: (0..n as u32).collect(),
        contact_field: Vec::new(),
        groups: Vec::new(),
        shared,
    }
}

#[cfg(test)]
mod tests {
    use crate::plugin::{CORE, MaterialFactory, Plugin, Registry, RegistryError};
    use crate::reference::ReferenceFactory;

    /// A plugin that brings one reference of the core's under the same type name.
    struct Clash;

    impl Plugin for Clash {
        fn name(&self) -> &'static str {
            "clash"
        }
        fn description(&self) -> &'static str {
            "brings a second `vibrating_bar`"
        }
        fn materials(&self) -> Vec<Box<dyn MaterialFactory>> {
            Vec::new()
        }
        fn references(&self) -> Vec<Box<dyn ReferenceFactory>> {
            vec![super::vibrating_bar::factory()]
        }
    }

    #[test]
    fn the_core_references_are_in_every_registry_and_cannot_be_claimed_twice() {
        let mut registry = Registry::new();
        let core: Vec<&str> = registry.reference_types().collect();
        assert_eq!(
            core,
            [
                "bimaterial_strip",
                "cantilever_elastica",
                "kirsch_plate",
                "layered_strip",
                "peak_displacement",
                "poiseuille_startup",
                "vibrating_bar"
            ]
        );
        assert_eq!(registry.references_of(CORE).len(), 7);
        let catalogue = registry.catalogue();
        assert!(catalogue["core"]["references"]["vibrating_bar"]["properties"]["axis"].is_object());
        match registry.register(Box::new(Clash)) {
            Err(RegistryError::DuplicateReference(name, first, second)) => {
                assert_eq!(
                    (name.as_str(), first.as_str(), second.as_str()),
                    ("vibrating_bar", CORE, "clash")
                );
            }
            other => panic!("expected a duplicate reference, got {:?}", other.err()),
        }
    }
}
