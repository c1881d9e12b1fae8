//! The `contact` section: pairs or groups of bodies (by `name`) that get grid velocity
//! fields of their own and the law that acts where two fields meet (multi-velocity-field
//! contact, Bardenhagen et al. 2000); the types and their checks. Bodies not named keep
//! the shared field. The solver side is `solver/multi_field.rs`, `solver/contact.rs` and
//! (bonded interfaces that can delaminate) `solver/cohesive.rs`.

use super::validator::Validator;
use super::{Scene, Scheme, Shape, Transfer};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Most grid velocity fields a scene may have: the shared one and up to this many less one
/// contact fields (each named body, or set of bodies sharing a name, is one field).
pub const MAX_CONTACT_FIELDS: usize = 16;

/// Contact between bodies: which bodies get their own grid velocity field and the law
/// between each two of them.
#[derive(Clone, Debug, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactSection {
    /// Pairs (or groups) of bodies and the law between every two of them. Two contact
    /// bodies no pair names, and a contact body against the bodies no pair names, stay
    /// bonded (one velocity where both have mass, as without contact).
    pub pairs: Vec<ContactPair>,
}

/// Two or more bodies, every two of which obey `law`.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactPair {
    /// Body names (`bodies[].name`); bodies that share a name share one field.
    pub bodies: Vec<String>,
    /// What happens where their fields meet and approach each other.
    pub law: ContactLaw,
    /// With a `cohesive` law: the region (box, sphere or cylinder) where the interface
    /// starts fully debonded (an initial crack); interface nodes inside it are frictional
    /// contact from the start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub precrack: Option<Shape>,
}

/// The law between two contact fields at a node where both have mass, they overlap (the
/// gap test) and they approach each other; separating fields are left free.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ContactLaw {
    /// The approaching normal component of the relative velocity is removed; sliding is
    /// free.
    Frictionless,
    /// Coulomb friction: the tangential correction is at most `coefficient` times the
    /// normal one.
    Friction {
        /// Coulomb friction coefficient (>= 0).
        coefficient: f64,
    },
    /// Stick while in contact: both fields take their centre-of-mass velocity.
    NoSlip,
    /// A bonded interface that can delaminate: the bodies are bonded wherever they touch at
    /// the start, until the traction the bond carries reaches the strength; then it softens
    /// linearly with the opening and, fully damaged, becomes Coulomb contact.
    Cohesive(CohesiveLaw),
}

/// A bilinear (rigid, then linearly softening) traction–separation law for a bonded
/// interface, with a power-law mixed-mode criterion.
///
/// An intact interface holds any traction below the strengths (no elastic compliance:
/// both bodies move as one) and any compression. Past the strength, the traction falls
/// linearly with the opening to zero at `2 G / strength`, so a pure mode dissipates its
/// fracture energy. Mixed mode: the damage is the power-law norm
/// `((δn/δnc)^α + (δt/δtc)^α)^(1/α)` of the openings over the final openings of each mode
/// (irreversible), which under proportional opening dissipates the energies of the
/// criterion `(G_I/G_Ic)^α + (G_II/G_IIc)^α = 1`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CohesiveLaw {
    /// Tensile strength of the interface, Pa (> 0).
    pub normal_strength: f64,
    /// Shear strength of the interface, Pa (> 0).
    pub shear_strength: f64,
    /// Mode I fracture energy G_Ic, J/m² (> 0).
    pub mode_i_energy: f64,
    /// Mode II fracture energy G_IIc, J/m² (> 0).
    pub mode_ii_energy: f64,
    /// Coulomb friction coefficient between the faces once debonded, and added to the
    /// shear strength under compression while bonded (>= 0; default 0).
    #[serde(default)]
    pub friction: f64,
    /// Exponent α of the power-law mixed-mode criterion (>= 1; default 2).
    #[serde(default = "default_mixed_mode_exponent")]
    pub mixed_mode_exponent: f64,
}

fn default_mixed_mode_exponent() -> f64 {
    2.0
}

impl CohesiveLaw {
    fn validate(&self, v: &mut Validator, path: &str) {
        for (name, value) in [
            ("normal_strength", self.normal_strength),
            ("shear_strength", self.shear_strength),
            ("mode_i_energy", self.mode_i_energy),
            ("mode_ii_energy", self.mode_ii_energy),
        ] {
            if !(value.is_finite() && value > 0.0) {
                v.err(
                    format!("{path}.{name}"),
                    format!("must be a finite number > 0 (got {value})"),
                );
            }
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            v.err(
                format!("{path}.friction"),
                format!("must be a finite number >= 0 (got {})", self.friction),
            );
        }
        if !(self.mixed_mode_exponent.is_finite() && self.mixed_mode_exponent >= 1.0) {
            v.err(
                format!("{path}.mixed_mode_exponent"),
                format!(
                    "must be a finite number >= 1 (got {})",
                    self.mixed_mode_exponent
                ),
            );
        }
    }
}

impl ContactSection {
    /// The contact fields of `scene`: the key of each field (a body name, or `None` for the
    /// field of the bodies no pair names) in the solver's order, and the field of every body
    /// (by body index). Bodies named in pairs get one field per distinct name; fields past
    /// [`MAX_CONTACT_FIELDS`] (refused at validation) fold into the last.
    pub fn fields<'a>(&self, scene: &'a Scene) -> (Vec<Option<&'a str>>, Vec<u8>) {
        let named = |name: &str| {
            self.pairs
                .iter()
                .any(|p| p.bodies.iter().any(|b| b == name))
        };
        let mut keys: Vec<Option<&str>> = Vec::new();
        let mut of_body = Vec::with_capacity(scene.bodies.len());
        for body in &scene.bodies {
            let key = (!body.name.is_empty() && named(&body.name)).then_some(body.name.as_str());
            let field = keys.iter().position(|k| *k == key).unwrap_or_else(|| {
                keys.push(key);
                keys.len() - 1
            });
            of_body.push(field.min(MAX_CONTACT_FIELDS - 1) as u8);
        }
        keys.truncate(MAX_CONTACT_FIELDS);
        (keys, of_body)
    }

    /// Whether any pair is a bonded interface (`cohesive` law).
    pub fn has_cohesive(&self) -> bool {
        self.pairs
            .iter()
            .any(|p| matches!(p.law, ContactLaw::Cohesive(_)))
    }

    /// Checks the pairs against the scene's bodies and the solver settings contact
    /// supports (USL, dynamic mechanics).
    pub(super) fn validate(&self, v: &mut Validator, s: &Scene) {
        if self.pairs.is_empty() {
            v.err("contact.pairs", "name at least one pair of bodies");
        }
        let mut seen: Vec<(&str, &str, usize)> = Vec::new();
        let mut names: Vec<&str> = Vec::new();
        for (k, pair) in self.pairs.iter().enumerate() {
            let path = format!("contact.pairs[{k}]");
            if pair.bodies.len() < 2 {
                v.err(format!("{path}.bodies"), "name at least two bodies");
            }
            for (j, name) in pair.bodies.iter().enumerate() {
                let at = format!("{path}.bodies[{j}]");
                if name.is_empty() || !s.bodies.iter().any(|b| &b.name == name) {
                    v.err(&at, format!("no body named \"{name}\""));
                } else if pair.bodies[..j].contains(name) {
                    v.err(&at, format!("\"{name}\" is named twice in this pair"));
                }
                if !names.contains(&name.as_str()) {
                    names.push(name);
                }
                for other in &pair.bodies[..j] {
                    let key = ordered(name, other);
                    if let Some(&(_, _, first)) = seen.iter().find(|(a, b, _)| (*a, *b) == key)
                        && first != k
                    {
                        v.err(
                            &at,
                            format!(
                                "\"{other}\" and \"{name}\" already have a law in contact.pairs[{first}]"
                            ),
                        );
                    }
                    seen.push((key.0, key.1, k));
                }
            }
            if let ContactLaw::Friction { coefficient } = pair.law
                && !(coefficient.is_finite() && coefficient >= 0.0)
            {
                v.err(
                    format!("{path}.law.friction.coefficient"),
                    format!("must be a finite number >= 0 (got {coefficient})"),
                );
            }
            if let ContactLaw::Cohesive(law) = &pair.law {
                law.validate(v, &format!("{path}.law.cohesive"));
            }
            match (&pair.precrack, &pair.law) {
                (None, _) => {}
                (Some(_), law) if !matches!(law, ContactLaw::Cohesive(_)) => v.err(
                    format!("{path}.precrack"),
                    "only a `cohesive` law has a precrack",
                ),
                (Some(Shape::File { .. } | Shape::Inflow(_)), _) => v.err(
                    format!("{path}.precrack"),
                    "a precrack is a box, sphere or cylinder",
                ),
                (Some(shape), _) => shape.validate(v, &format!("{path}.precrack")),
            }
        }
        if names.len() + 1 > MAX_CONTACT_FIELDS {
            v.err(
                "contact.pairs",
                format!(
                    "{} bodies have fields of their own; at most {} are supported",
                    names.len(),
                    MAX_CONTACT_FIELDS - 1
                ),
            );
        }
        if s.solver.scheme != Scheme::Usl {
            v.err(
                "solver.scheme",
                "contact between bodies needs the `usl` update scheme",
            );
        }
        if !s.solver.mechanics.is_dynamic() {
            v.err(
                "solver.mechanics",
                "contact between bodies needs `dynamic` mechanics",
            );
        }
        if s.solver.transfer == Transfer::Xpic {
            v.err(
                "solver.transfer",
                "contact between bodies does not support `xpic` (each body's field would \
                 need its own extrapolation): use `pic`, `flip` or `apic`",
            );
        }
    }
}

fn ordered<'a>(a: &'a str, b: &'a str) -> (&'a str, &'a str) {
    if a <= b { (a, b) } else { (b, a) }
}
