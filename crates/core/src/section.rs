//! What every plugin-built scene section shares: its JSON Schema, reading it into a typed
//! parameter struct with JSON-path errors, and the common value checks.
//!
//! Materials (`materials.<name>`), physics operators (`physics.<name>`) and references
//! (`reference`) all use these, so neither of their modules depends on another.

use crate::scene::{Issue, deserialize_at};

/// The JSON Schema of a scene section's parameter struct, without the `$schema` key (it
/// is embedded in the scene schema).
pub fn section_schema<P: schemars::JsonSchema>() -> serde_json::Value {
    let mut schema = schemars::SchemaGenerator::default()
        .into_root_schema_for::<P>()
        .to_value();
    if let Some(obj) = schema.as_object_mut() {
        obj.remove("$schema");
    }
    schema
}

/// The schema of a section selected by its `type` key (a material or a reference): the
/// parameter struct's schema with `type` added as a required constant.
pub fn typed_section_schema<P: schemars::JsonSchema>(
    type_name: &str,
    what: &str,
) -> serde_json::Value {
    let mut schema = section_schema::<P>();
    if let Some(obj) = schema.as_object_mut() {
        if let Some(props) = obj.get_mut("properties").and_then(|p| p.as_object_mut()) {
            props.insert(
                "type".into(),
                serde_json::json!({ "const": type_name, "description": what }),
            );
        }
        if let Some(req) = obj.get_mut("required").and_then(|r| r.as_array_mut()) {
            req.insert(0, serde_json::json!("type"));
        } else {
            obj.insert("required".into(), serde_json::json!(["type"]));
        }
    }
    schema
}

/// Reads a section selected by its `type` key into `P` (the `type` key stripped), with the
/// JSON path of the first problem.
pub fn typed_params<P: serde::de::DeserializeOwned>(
    section: &serde_json::Value,
    path: &str,
) -> Result<P, Vec<Issue>> {
    let mut params = section.clone();
    if let Some(obj) = params.as_object_mut() {
        obj.remove("type");
    }
    deserialize_at(&params, path).map_err(|e| vec![e])
}

/// Collects the problems of one section, each at `section.field`.
pub struct Checks<'a> {
    path: &'a str,
    /// The problems found so far.
    pub issues: Vec<Issue>,
}

impl<'a> Checks<'a> {
    /// Checks of the section at JSON path `path`.
    pub fn new(path: &'a str) -> Self {
        Self {
            path,
            issues: Vec::new(),
        }
    }

    /// The JSON path of a field of the section (the section itself for an empty field).
    pub fn path_of(&self, field: &str) -> String {
        if field.is_empty() {
            self.path.to_string()
        } else {
            format!("{}.{field}", self.path)
        }
    }

    /// Records a problem with `field`.
    pub fn error(&mut self, field: &str, message: impl Into<String>) {
        let path = self.path_of(field);
        self.issues.push(Issue::new(path, message));
    }

    /// `field` must be a finite number > 0.
    pub fn positive(&mut self, field: &str, x: f64) {
        if !(x.is_finite() && x > 0.0) {
            self.error(field, format!("must be a finite number > 0 (got {x})"));
        }
    }

    /// `field` must be finite.
    pub fn finite(&mut self, field: &str, x: f64) {
        if !x.is_finite() {
            self.error(field, "must be finite");
        }
    }

    /// `field` must name an axis of a `dimension`-D scene.
    pub fn axis(&mut self, field: &str, axis: usize, dimension: usize) {
        if axis >= dimension {
            self.error(field, format!("must be below {dimension}"));
        }
    }

    /// The problems, if any.
    pub fn finish(self) -> Result<(), Vec<Issue>> {
        if self.issues.is_empty() {
            Ok(())
        } else {
            Err(self.issues)
        }
    }
}
