//! Thermal conditions on the domain faces: fixed temperature, heat flux, convection.

use mpm_core::grid::Grid;
use mpm_core::physics::Property;
use mpm_core::scene::{Issue, Side};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A condition on one or more faces of the domain. Exactly one of `temperature`,
/// `heat_flux` and `convection` is given; each value is a number or a `[[time, value], ...]`
/// schedule (linear between rows, held past the ends).
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ThermalBoundary {
    /// Faces it covers.
    pub sides: Vec<Side>,
    /// Fixed temperature, K: the grid nodes on and behind the face are held at it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature: Option<Property>,
    /// Heat flux into the body, W/m² (negative: out of it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heat_flux: Option<Property>,
    /// Convection to an ambient fluid (an oven, air).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub convection: Option<Convection>,
}

/// Newton cooling `q = h (T_ambient − T)` into the body.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Convection {
    /// Heat transfer coefficient h, W/(m² K).
    pub coefficient: f64,
    /// Ambient temperature, K: a number or a `[[time, T], ...]` schedule (an oven profile).
    pub ambient: Property,
}

impl ThermalBoundary {
    /// Problems with the condition at `path`.
    pub fn check(&self, path: &str, dim: usize) -> Vec<Issue> {
        let mut issues = Vec::new();
        if self.sides.is_empty() {
            issues.push(Issue::new(
                format!("{path}.sides"),
                "name at least one face",
            ));
        }
        for (i, side) in self.sides.iter().enumerate() {
            if side.axis_and_upper().0 >= dim {
                issues.push(Issue::new(
                    format!("{path}.sides[{i}]"),
                    format!("a {dim}D domain has no such face"),
                ));
            }
        }
        let given = [
            self.temperature.is_some(),
            self.heat_flux.is_some(),
            self.convection.is_some(),
        ]
        .iter()
        .filter(|g| **g)
        .count();
        if given != 1 {
            issues.push(Issue::new(
                path,
                "give exactly one of `temperature`, `heat_flux` and `convection`",
            ));
        }
        let finite = |v: f64| v.is_finite();
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if let Some(t) = &self.temperature {
            issues.extend(t.check(
                &format!("{path}.temperature"),
                "a finite number > 0 K",
                positive,
            ));
        }
        if let Some(q) = &self.heat_flux {
            issues.extend(q.check(&format!("{path}.heat_flux"), "finite", finite));
        }
        if let Some(c) = &self.convection {
            if !(c.coefficient.is_finite() && c.coefficient >= 0.0) {
                issues.push(Issue::new(
                    format!("{path}.convection.coefficient"),
                    format!("must be a finite number >= 0 (got {})", c.coefficient),
                ));
            }
            issues.extend(c.ambient.check(
                &format!("{path}.convection.ambient"),
                "a finite number > 0 K",
                positive,
            ));
        }
        issues
    }
}

/// A face of the domain in grid terms: the axis, the node index of the face plane, and
/// which way is outside.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Face {
    pub axis: usize,
    pub plane: usize,
    pub upper: bool,
}

impl Face {
    /// The face `side` of the domain `[min, max]` on `grid` (the grid pads the domain).
    pub fn new<const D: usize>(side: Side, grid: &Grid<D>, min: &[f64], max: &[f64]) -> Self {
        let (axis, upper) = side.axis_and_upper();
        // The domain spans a whole number of cells from its lower corner (as in the core).
        let cells = ((max[axis] - min[axis]) / grid.dx - 1e-9).ceil();
        let lower = ((min[axis] - grid.origin[axis]) / grid.dx).round();
        let plane = if upper { lower + cells } else { lower };
        Self {
            axis,
            plane: plane.max(0.0) as usize,
            upper,
        }
    }

    /// Whether node coordinate `c` (along the axis) lies on the face plane.
    pub fn on(&self, c: usize) -> bool {
        c == self.plane
    }

    /// Whether node coordinate `c` lies on the face plane or outside the domain.
    pub fn on_or_behind(&self, c: usize) -> bool {
        if self.upper {
            c >= self.plane
        } else {
            c <= self.plane
        }
    }
}
