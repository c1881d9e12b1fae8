//! The stability suite's bonded-interface cases (`contact` pairs with a `cohesive` law):
//! two blocks bonded face to face and thrown apart, with a fracture energy so small that
//! the bond breaks at once and one so large that it never softens.

use crate::stability_case::{Case, Expected};
use serde_json::{Value, json};

/// Two rubber-like blocks (E 1e6 Pa, wave speed 32 m/s) bonded along y = 0.2 m, thrown
/// apart at 1 m/s each (a tensile wave of about 3e4 Pa reaches the interface), with a
/// cohesive interface of strength `strength` Pa and fracture energies `energy` J/m².
fn thrown_apart(strength: f64, energy: f64) -> Value {
    let rubber = json!({"type": "neo_hookean", "density": 1000.0, "youngs_modulus": 1e6,
                        "poisson_ratio": 0.3});
    json!({
        "name": "cohesive-blocks", "dimension": 2,
        "domain": {"min": [0, 0], "max": [1, 0.5], "cell_size": 0.025},
        "solver": {"end_time": 0.1, "cfl": 0.5},
        "materials": {"rubber": rubber},
        "bodies": [
            {"name": "lower", "material": "rubber",
             "shape": {"box": {"min": [0.3, 0.1], "max": [0.7, 0.2]}},
             "velocity": {"uniform": [0.0, -1.0]}},
            {"name": "upper", "material": "rubber",
             "shape": {"box": {"min": [0.3, 0.2], "max": [0.7, 0.3]}},
             "velocity": {"uniform": [0.0, 1.0]}}],
        "contact": {"pairs": [{"bodies": ["lower", "upper"], "law": {"cohesive": {
            "normal_strength": strength, "shear_strength": strength,
            "mode_i_energy": energy, "mode_ii_energy": energy}}}]},
        "output": {"frames": 1, "fields": ["x", "interface_damage"]}
    })
}

/// The bonded-interface cases, appended to the suite.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "cohesive-energy-1e-9",
            what: "bonded blocks thrown apart at 2 m/s, G_c 1e-9 J/m2: the bond breaks at once, the blocks fly apart",
            scene: thrown_apart(1e4, 1e-9),
            expected: Expected::Finished,
            check: None,
        },
        Case {
            name: "cohesive-energy-1e9",
            what: "the same with G_c 1e9 J/m2 and strength 1e6 Pa: the bond never softens, the blocks ring as one",
            scene: thrown_apart(1e6, 1e9),
            expected: Expected::Finished,
            check: None,
        },
    ]
}
