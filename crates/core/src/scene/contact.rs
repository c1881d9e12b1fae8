//! The `contact` section: pairs or groups of bodies (by `name`) that get grid velocity
//! fields of their own and the law that acts where two fields meet (multi-velocity-field
//! contact, Bardenhagen et al. 2000); the types and their checks. Bodies not named keep
//! the shared field. The solver side is `solver/multi_field.rs` and `solver/contact.rs`.

use super::validator::Validator;
use super::{Scene, Scheme};
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
}

impl ContactSection {
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
    }
}

fn ordered<'a>(a: &'a str, b: &'a str) -> (&'a str, &'a str) {
    if a <= b { (a, b) } else { (b, a) }
}
