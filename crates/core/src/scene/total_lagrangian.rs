//! What a scene in total Lagrangian mechanics (`solver.mechanics: "total_lagrangian"`)
//! may hold: the grid is the bodies' reference configuration, so whatever acts where a
//! body is now (obstacles, contact between bodies, physics operators on the current
//! grid, inflow) has no place in it, and neither do the transfers and schemes the mode
//! does not implement.

use super::validator::Validator;
use super::{AntiLocking, Mechanics, Scene, Scheme, Shape, Transfer};

/// The reason every refusal gives.
const REFERENCE_GRID: &str = "total Lagrangian MPM keeps the grid as the bodies' reference \
                              configuration";

impl Validator {
    /// Refuses what total Lagrangian mechanics cannot do, each at its JSON path.
    pub(super) fn check_total_lagrangian(&mut self, s: &Scene) {
        if s.solver.mechanics != Mechanics::TotalLagrangian {
            return;
        }
        if !s.obstacles.is_empty() {
            self.err(
                "obstacles",
                format!(
                    "{REFERENCE_GRID}, and an obstacle acts where a body is now: remove the \
                     obstacles (walls on the domain faces hold the material that starts at \
                     them) or use `dynamic` mechanics"
                ),
            );
        }
        if s.contact.is_some() {
            self.err(
                "contact",
                format!(
                    "{REFERENCE_GRID}, and contact between bodies happens where they are now: \
                     use `dynamic` mechanics"
                ),
            );
        }
        if let Some(name) = s.physics.keys().next() {
            self.err(
                format!("physics.{name}"),
                format!(
                    "{REFERENCE_GRID}; physics operators work on the grid where the bodies \
                     are now: use `dynamic` mechanics (or a stage of its own)"
                ),
            );
        }
        for (k, body) in s.bodies.iter().enumerate() {
            if matches!(body.shape, Shape::Inflow(_)) {
                self.err(
                    format!("bodies[{k}].shape"),
                    format!("{REFERENCE_GRID}: particles cannot enter it during the run"),
                );
            }
        }
        if matches!(s.solver.transfer, Transfer::Xpic) {
            self.err(
                "solver.transfer",
                "total Lagrangian MPM takes `pic`, `flip` or `apic`",
            );
        }
        if s.solver.mls {
            self.err(
                "solver.mls",
                "the MLS-MPM force is for the updated Lagrangian step: remove it",
            );
        }
        if s.solver.scheme == Scheme::Usf {
            self.err(
                "solver.scheme",
                "total Lagrangian MPM takes `usl` or `musl` (the paper's, the velocities \
                 mapped back before F grows)",
            );
        }
        if s.solver.anti_locking == AntiLocking::Fbar {
            self.err(
                "solver.anti_locking",
                "F-bar averages J over the current cells, which total Lagrangian MPM does \
                 not have: remove it",
            );
        }
    }
}
