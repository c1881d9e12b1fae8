//! The energy ledger of a run: the work done on the bodies from outside and the energy
//! dissipated by each physical cause, kept separately so that what remains of the energy
//! balance is the method's own error, not damping or plasticity.

use serde::Serialize;

/// Work and dissipation since the start of a run, by cause, J (J/m in 2D). Each entry is
/// the energy that entered (work) or left (dissipated) the bodies' mechanical energy
/// (kinetic + strain + gravity potential).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct EnergyLedger {
    /// Work done by moving obstacles (and walls) on the bodies, m Δv · v_surface at their
    /// nodes; fixed surfaces do none.
    pub boundaries: f64,
    /// Work of changing free strains (thermal expansion, cure shrinkage) against the stress.
    pub free_strain: f64,
    /// Kinetic energy removed by the grid velocity damping of `solver.damping`.
    pub damping: f64,
    /// Plastic work the materials reported (dissipated into heat).
    pub plastic: f64,
    /// Energy Coulomb friction dissipated: between bodies in contact, and at walls and
    /// obstacles with a friction condition (the motion along them it took away).
    pub friction: f64,
    /// Energy the cohesive interfaces dissipated as they softened.
    pub cohesive: f64,
    /// Mechanical energy (kinetic + gravity potential) liquid brought in through inlets
    /// less what it carried out through open faces, at the crossing.
    pub openings: f64,
    /// Energy the liquids' viscosity dissipated (incompressible mode): the viscous stress
    /// power Σ_p V_p σ_p : L_p of the liquid particles at the end of each step, times the
    /// step (and the drag of Navier-slip surfaces).
    pub viscous: f64,
    /// Work the liquid's pressure did through the volume source (scenes with inlets or
    /// enclosed air), the correction that moves misplaced particle volume back: the volume
    /// it let each cell gain or lose, times the pressure there, Σ_i p_i ΔV_i. Reported, not
    /// counted in the balance ([`EnergyLedger::net_input`]): the method takes most of it
    /// back within the step, and it grows as the step shrinks (the inflow tank: 1.7e-2 J/m
    /// at `cfl` 0.5, 7.8e-2 at 0.1, where the balance leaves 7.1e-4 J/m unexplained).
    pub volume_source: f64,
}

impl EnergyLedger {
    /// The entries in declaration order but `openings`, `viscous` and `volume_source` (for
    /// checkpoints, which keep those apart so that checkpoints written before they existed
    /// still restore).
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.boundaries,
            self.free_strain,
            self.damping,
            self.plastic,
            self.friction,
            self.cohesive,
        ]
    }

    /// The ledger whose [`EnergyLedger::to_array`] is `a` (`openings`, `viscous` and
    /// `volume_source` 0).
    pub fn from_array(a: [f64; 6]) -> Self {
        let [
            boundaries,
            free_strain,
            damping,
            plastic,
            friction,
            cohesive,
        ] = a;
        Self {
            boundaries,
            free_strain,
            damping,
            plastic,
            friction,
            cohesive,
            openings: 0.0,
            viscous: 0.0,
            volume_source: 0.0,
        }
    }

    /// Net energy the ledger explains: work done on the bodies and energy carried in by
    /// liquid, less all dissipation (not the volume source's work: see its field).
    pub fn net_input(&self) -> f64 {
        self.boundaries + self.free_strain + self.openings - self.dissipated()
    }

    /// Everything dissipated by a physical cause.
    pub fn dissipated(&self) -> f64 {
        self.damping + self.plastic + self.friction + self.cohesive + self.viscous
    }
}
