//! The `domain` section: the background grid's box and cell size, and the walls on its
//! faces; its types and its checks.

use super::validator::Validator;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

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
    /// Static contact angle, degrees, of a liquid with surface tension on this wall,
    /// measured through the liquid (below 90 the liquid wets the wall and climbs it).
    /// Without it the liquid meets the wall at 90°.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_angle: Option<f64>,
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
    /// Navier slip (liquids in incompressible mechanics only): like `slip` across the
    /// surface, and along it a viscous drag τ = −μ·v_t/b, so the liquid slides with
    /// v_t = b·∂v_t/∂n: between `stick` (b → 0) and `slip` (b → ∞). A moving contact line
    /// needs it on a resolved scale; `stick` holds the line still but for the grid's own slip.
    Navier {
        /// Slip length b, m (> 0).
        slip_length: f64,
    },
}

impl Domain {
    /// Checks the box, the cell size and the walls.
    pub(super) fn validate(&self, v: &mut Validator) {
        let ok_min = v.vector("domain.min", &self.min);
        let ok_max = v.vector("domain.max", &self.max);
        v.positive("domain.cell_size", self.cell_size);
        if ok_min && ok_max {
            for a in 0..v.dim {
                if self.max[a] <= self.min[a] {
                    v.err(
                        format!("domain.max[{a}]"),
                        format!("must be greater than domain.min[{a}]"),
                    );
                }
            }
            if self.cell_size > 0.0 && self.cell_size.is_finite() {
                // The grid's size is bounded in `budget`.
                for a in 0..v.dim {
                    let cells = ((self.max[a] - self.min[a]) / self.cell_size).ceil();
                    if cells < 1.0 {
                        v.err(
                            "domain.cell_size",
                            format!("the domain must be at least one cell wide on axis {a}"),
                        );
                    }
                }
            }
        }
        for (i, w) in self.walls.iter().enumerate() {
            let path = format!("domain.walls[{i}]");
            if w.sides.is_empty() {
                v.err(format!("{path}.sides"), "name at least one side");
            }
            for (j, side) in w.sides.iter().enumerate() {
                if side.axis_and_upper().0 >= v.dim {
                    v.err(
                        format!("{path}.sides[{j}]"),
                        "z sides exist only in 3D scenes",
                    );
                }
            }
            if w.thickness == 0 {
                v.err(format!("{path}.thickness"), "must be at least 1");
            }
            // The wall's node layers must fit in the domain (the solver's cell count).
            let cells = |a: usize| ((self.max[a] - self.min[a]) / self.cell_size - 1e-9).ceil();
            let sized = ok_min && ok_max && self.cell_size.is_finite() && self.cell_size > 0.0;
            let axes = w.sides.iter().map(|s| s.axis_and_upper().0);
            if let Some(a) = axes
                .filter(|&a| a < v.dim && sized)
                .find(|&a| f64::from(w.thickness) > cells(a) + 1.0 || !cells(a).is_finite())
            {
                v.err(
                    format!("{path}.thickness"),
                    format!(
                        "{} layers do not fit in the domain's {} cells on axis {a}",
                        w.thickness,
                        cells(a)
                    ),
                );
            }
            w.condition.validate(v, &format!("{path}.condition"));
            validate_contact_angle(v, &format!("{path}.contact_angle"), w.contact_angle);
        }
    }
}

/// Checks a wall's or an obstacle's static contact angle (degrees) at `path`.
pub(super) fn validate_contact_angle(v: &mut Validator, path: &str, angle: Option<f64>) {
    if let Some(angle) = angle
        && !(angle.is_finite() && angle > 0.0 && angle < 180.0)
    {
        v.err(path, "must lie strictly between 0 and 180 degrees");
    }
}

impl Contact {
    /// Checks a contact law at `path` (a wall's or an obstacle's `condition`).
    pub(super) fn validate(self, v: &mut Validator, path: &str) {
        if let Contact::Friction { coefficient } = self
            && !(coefficient.is_finite() && coefficient >= 0.0)
        {
            v.err(
                format!("{path}.friction.coefficient"),
                "must be a finite number >= 0",
            );
        }
        if let Contact::Navier { slip_length } = self
            && !(slip_length.is_finite() && slip_length > 0.0)
        {
            v.err(
                format!("{path}.navier.slip_length"),
                "must be a finite number > 0 (m)",
            );
        }
    }

    /// The slip length of a Navier surface (none for the other laws).
    pub fn slip_length(self) -> Option<f64> {
        match self {
            Contact::Navier { slip_length } => Some(slip_length),
            _ => None,
        }
    }
}
