//! The JSON Schema of scene files: the core's scene structure with the sections every
//! registered plugin brings (materials, physics, references) filled in.

use mpm_core::plugin::Registry;

/// The JSON Schema of a scene file, with the material, physics and reference sections of
/// every registered plugin (and the core's references).
pub fn scene_schema(registry: &Registry) -> serde_json::Value {
    let mut schema = schemars::schema_for!(mpm_core::scene::Scene).to_value();
    let materials: Vec<serde_json::Value> = registry
        .material_types()
        .map(|t| registry.material(t).expect("listed").schema())
        .collect();
    if let Some(slot) = schema.pointer_mut("/properties/materials") {
        slot["additionalProperties"] = serde_json::json!({ "oneOf": materials });
    }
    let physics: serde_json::Map<String, serde_json::Value> = registry
        .physics_names()
        .map(|n| {
            let (_, f) = registry.physics(n).expect("listed");
            (n.to_string(), f.schema())
        })
        .collect();
    if let Some(slot) = schema.pointer_mut("/properties/physics") {
        slot["properties"] = serde_json::Value::Object(physics);
        slot["additionalProperties"] = serde_json::json!(false);
    }
    let references: Vec<serde_json::Value> = registry
        .reference_types()
        .map(|t| registry.reference(t).expect("listed").schema())
        .collect();
    if let Some(slot) = schema.pointer_mut("/properties/reference") {
        let description = slot.get("description").cloned();
        *slot = serde_json::json!({ "oneOf": references });
        if let Some(d) = description {
            slot["description"] = d;
        }
    }
    schema
}
