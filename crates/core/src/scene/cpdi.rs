//! What a scene with CPDI's domain kernel (`solver.kernel: "cpdi2"`) may hold: the domains
//! live in the explicit dynamic step's own transfers (`solver::cpdi`), so the other
//! mechanics modes, contact between bodies, physics operators and the transfers and
//! schemes that step does not implement are refused (MLS is refused for every kernel but
//! the B-splines), each at its JSON path.

use super::validator::Validator;
use super::{AntiLocking, KernelName, Mechanics, Scene, Scheme, Transfer};

/// The reason every refusal starts with.
const DOMAINS: &str = "the `cpdi2` kernel's particle domains are built into the explicit \
                       dynamic step's own transfers";

impl Validator {
    /// Refuses what the CPDI step cannot do, each at its JSON path.
    pub(super) fn check_cpdi(&mut self, s: &Scene) {
        if s.solver.kernel != KernelName::Cpdi2 {
            return;
        }
        if s.solver.mechanics != Mechanics::Dynamic {
            self.err(
                "solver.mechanics",
                format!("{DOMAINS}: use `dynamic` mechanics, or another kernel"),
            );
        }
        if s.contact.is_some() {
            self.err(
                "contact",
                format!(
                    "{DOMAINS}, and contact's velocity fields are not: use another kernel \
                     (`gimp` is the nearest)"
                ),
            );
        }
        if let Some(name) = s.physics.keys().next() {
            self.err(
                format!("physics.{name}"),
                format!(
                    "{DOMAINS}; physics operators interpolate at particle centres: use \
                     another kernel (`gimp` is the nearest), or a stage of its own"
                ),
            );
        }
        if matches!(s.solver.transfer, Transfer::Xpic) {
            self.err(
                "solver.transfer",
                "the `cpdi2` kernel takes `pic`, `flip` or `apic`",
            );
        }
        if s.solver.scheme == Scheme::Usf {
            self.err("solver.scheme", "the `cpdi2` kernel takes `usl` or `musl`");
        }
        if s.solver.anti_locking == AntiLocking::Fbar {
            self.err(
                "solver.anti_locking",
                format!("{DOMAINS}, and F-bar's cell average is not: remove it"),
            );
        }
    }
}
