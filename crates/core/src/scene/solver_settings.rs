//! The `solver` section: kernel, transfer, update scheme, time step, gravity, damping,
//! mechanics mode and anti-locking; its types and its checks.

use super::validator::Validator;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Kernel (shape function) names as used in scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum KernelName {
    /// Linear tent functions.
    Linear,
    /// Uniform GIMP.
    Gimp,
    /// Quadratic B-spline.
    Bspline2,
    /// Cubic B-spline.
    Bspline3,
    /// Convected particle domains (CPDI; Sadeghirad et al. 2011, 2013): each particle's
    /// domain deforms with its F and its weights are the linear kernel averaged over it,
    /// so a body stretched to several times its length stays whole. Explicit dynamic
    /// mechanics, PIC/FLIP/APIC, USL/MUSL.
    #[serde(alias = "cpdi")]
    Cpdi2,
}

/// How particle velocities come back from the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Transfer {
    /// Particle-in-cell: dissipative, stable.
    Pic,
    /// FLIP blended with PIC by `solver.flip_blend`.
    Flip,
    /// Affine particle-in-cell: keeps angular momentum and an affine velocity per particle.
    Apic,
    /// Extended particle-in-cell of order `solver.xpic_order` (Hammerquist & Nairn 2017):
    /// PIC that keeps the part of the particles' velocity the grid can carry, so it loses
    /// little of PIC's stability and much less energy, without FLIP's noise. Explicit
    /// mechanics without contact between bodies.
    Xpic,
}

/// When the stress is updated within a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Update stress first, from the grid velocity before the momentum update.
    Usf,
    /// Update stress last, from the updated grid velocity.
    Usl,
    /// Modified USL: the updated particle velocities are mapped back to the grid first.
    Musl,
}

/// Time integration and discretisation choices.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Solver {
    /// Simulated end time, seconds.
    pub end_time: f64,
    /// End the run (in a staged scene, the stage) early, at the end of the first step
    /// after which its physics report holds this figure: `underfill.fill_time` ends a fill
    /// once its `fill_region` is filled, so the cure starts then. `end_time` stays the
    /// limit when the figure never comes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_when: Option<String>,
    /// Shape functions.
    #[serde(default = "default_kernel")]
    pub kernel: KernelName,
    /// Particle velocity update.
    #[serde(default = "default_transfer")]
    pub transfer: Transfer,
    /// FLIP fraction in the FLIP/PIC blend (1 = pure FLIP). Used with `transfer: flip`.
    #[serde(default = "default_flip_blend")]
    pub flip_blend: f64,
    /// Order m of XPIC(m), the grid's extrapolations per step (1 is PIC; each order adds one
    /// particle round trip). Used with `transfer: xpic`.
    #[serde(default = "default_xpic_order")]
    pub xpic_order: u32,
    /// Use the MLS-MPM force (needs `transfer: apic`).
    #[serde(default)]
    pub mls: bool,
    /// Stress update scheme.
    #[serde(default = "default_scheme")]
    pub scheme: Scheme,
    /// Courant number: dt = cfl · cell_size / max(|v| + c). Used when `dt` is not given.
    #[serde(default = "default_cfl")]
    pub cfl: f64,
    /// Fixed time step, seconds. Refused when it exceeds `max_cfl` times the stable step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt: Option<f64>,
    /// Largest Courant number a fixed `dt` may reach before the run refuses it.
    #[serde(default = "default_max_cfl")]
    pub max_cfl: f64,
    /// Gravity (one number per dimension), m/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<Vec<f64>>,
    /// Viscous damping rate of the grid velocity, 1/s (0 = none); for reaching equilibrium.
    #[serde(default)]
    pub damping: f64,
    /// Reorder particles by cell every this many steps, for memory locality (0 = never).
    #[serde(default = "default_sort_interval")]
    pub sort_interval: u32,
    /// Volumetric anti-locking for near-incompressible materials.
    #[serde(default, skip_serializing_if = "AntiLocking::is_none")]
    pub anti_locking: AntiLocking,
    /// How a 2D scene's free strain (thermal expansion, cure shrinkage) acts: in the plane
    /// only (the default), or as in plane strain, where the held third direction turns the
    /// out-of-plane part into in-plane stress.
    #[serde(default, skip_serializing_if = "FreeStrain2d::is_in_plane")]
    pub free_strain_2d: FreeStrain2d,
    /// How the grid is stored: `sparse` (the default) keeps, clears and updates only the
    /// blocks of nodes the particles' stencils reach, where the mode allows it (explicit
    /// dynamics, quasi-static relaxation or mechanics off, without contact); `dense` every
    /// node, always.
    #[serde(default, skip_serializing_if = "GridStorage::is_sparse")]
    pub grid: GridStorage,
    /// How mechanics advances: explicit dynamics (the default), not at all (physics only,
    /// particles stay put), or quasi-statically (relaxed to equilibrium every step).
    #[serde(default, skip_serializing_if = "Mechanics::is_dynamic")]
    pub mechanics: Mechanics,
    /// Finer grid levels over named boxes (hierarchical B-splines): the step runs on every
    /// level at once, and particles in a refined region are split at the start so each
    /// level's cells hold the body's particles per cell.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refinement: Option<super::refinement::Refinement>,
}

/// How the background grid is stored (`solver.grid`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum GridStorage {
    /// Only blocks of 512 nodes that particles' stencils reach are cleared, updated and
    /// held in memory; memory and grid work follow the particles, not the domain.
    #[default]
    Sparse,
    /// Every node every step (the reference the sparse grid is checked against).
    Dense,
}

impl GridStorage {
    fn is_sparse(&self) -> bool {
        *self == GridStorage::Sparse
    }
}

impl Solver {
    /// Whether a run keeps its grid sparse: `solver.grid` asks for it and every grid write
    /// of the mode comes from P2G, which marks the blocks it writes, as in explicit dynamics
    /// and quasi-static relaxation without contact fields (projection, Newton and contact
    /// operators write anywhere on the grid); with mechanics off nothing writes it.
    pub fn sparse_grid(&self, contact: bool) -> bool {
        self.grid.is_sparse()
            && !contact
            && matches!(
                self.mechanics,
                Mechanics::Dynamic
                    | Mechanics::QuasiStatic { .. }
                    | Mechanics::Off
                    | Mechanics::TotalLagrangian
            )
    }
}

/// How the mechanical part of a step is advanced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Mechanics {
    /// Explicit dynamics: the step is bounded by the wave speed (CFL).
    #[default]
    Dynamic,
    /// No mechanics: particles keep their place and carry no stress; the step is the
    /// physics' own stable step or `solver.dt`. For heat conduction and kinetics alone.
    Off,
    /// Quasi-static: after the physics of every step (of `solver.dt` or the physics' stable
    /// step), damped explicit iterations relax the body to equilibrium under the new free
    /// strains and loads. For slow processes (cure, cool-down) where inertia plays no part.
    QuasiStatic {
        /// Most relaxation iterations per step; a step that does not converge in them stops
        /// the run with a diagnostic.
        #[serde(default = "default_relax_iterations")]
        max_iterations: u32,
        /// Converged when the kinetic energy falls below this fraction of the strain energy
        /// (and of the largest kinetic energy of the step).
        #[serde(default = "default_relax_tolerance")]
        tolerance: f64,
        /// Velocity damping rate during relaxation, 1/s; default: critical damping of the
        /// lowest mode of the domain, 2π·c/(longest domain edge).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        damping: Option<f64>,
    },
    /// Implicit: Newton iterations on the grid displacement increment solve equilibrium
    /// (`static`) or Newmark dynamics (`dynamic`) every step, with steps far beyond the
    /// explicit stable step. For stiff, slow processes (cure, cool-down, thermal cycling).
    Implicit(ImplicitSettings),
    /// Incompressible liquid: a fractional-step (Chorin) projection every step. Body and
    /// viscous forces act explicitly (or the viscous ones implicitly, `viscosity:
    /// "implicit"`), then a pressure Poisson equation on the grid makes the nodal velocity
    /// (nearly) divergence-free; the step is bounded by the velocity CFL and, with explicit
    /// viscosity, the viscous limit, not by a sound speed. Every material of the
    /// scene must be a liquid (e.g. type `liquid`).
    Incompressible(IncompressibleSettings),
    /// Total Lagrangian MPM: explicit dynamics on a grid that stays the reference
    /// configuration, each particle's stencil fixed from the start, so nothing crosses a
    /// cell and a body stretched to several times its length stays whole. Walls hold the
    /// material that started at them; no obstacles, contact or physics sections.
    #[serde(alias = "tlmpm")]
    TotalLagrangian,
}

/// Settings of `solver.mechanics.incompressible`; every field has a default.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct IncompressibleSettings {
    /// Relative residual the pressure solve (Jacobi-preconditioned CG) reaches.
    #[serde(default = "default_pressure_tolerance")]
    pub tolerance: f64,
    /// Most CG iterations per pressure solve; a solve that does not converge in them stops
    /// the run with a diagnostic.
    #[serde(default = "default_pressure_iterations")]
    pub max_iterations: u32,
    /// How the liquids' viscous stress acts: `explicit` (the default) as a force from the
    /// last step's velocity gradient, with the step bounded by ρ·dx²/(2·D·μ); `implicit` as
    /// a backward-Euler viscous solve on the grid before the pressure projection
    /// (Jacobi-preconditioned CG with `tolerance` and `max_iterations`) and an
    /// incremental projection (the Poisson equation solves for the pressure change), with
    /// no viscous bound on the step.
    #[serde(default)]
    pub viscosity: ViscousIntegration,
    /// Liquid that crosses a domain face without a wall leaves the run (its particles
    /// stop on the face without mass, `injected` = −1; the volume gone is the physics
    /// figure `incompressible.outflow_volume`) instead of stopping it as a particle that
    /// left the grid: the vents of a mould, the open end of a channel.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub outflow: bool,
    /// Air the liquid encloses (cut off from every domain face without a wall) resists
    /// being filled as an isothermal ideal gas; without it an enclosed pocket is free
    /// surface at zero pressure and costs nothing to fill.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub enclosed_air: Option<EnclosedAirSettings>,
    /// Correct the particles' volume per cell in every step of any liquid scene (the volume
    /// source: a cell inside the liquid whose particles hold more or less volume than the
    /// cell gives or takes a share of the difference through the pressure equation). Always
    /// on with inlets or enclosed air. Without it the projection keeps the grid velocity
    /// divergence-free but lets the particles drift apart where the liquid is pulled: a
    /// capillary fill's liquid thinned by up to a quarter and filled at 0.4–0.66 of
    /// Washburn's rate. Off by default: the dam break and the capillary rise read worse
    /// with it (README, "Capillary filling with liquid particles").
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub volume_correction: bool,
}

/// Settings of `solver.mechanics.incompressible.enclosed_air`: the gas in the pockets the
/// liquid closes (solver/incompressible/enclosed_air.rs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EnclosedAirSettings {
    /// Absolute pressure of the open air, Pa: a pocket closes at it, and its gauge pressure
    /// is p·V₀/V − this after its volume goes from V₀ to V (Boyle).
    #[serde(default = "default_ambient_pressure")]
    pub ambient_pressure: f64,
    /// Smallest pocket, in cells, whose gas resists; a smaller one (a gap between moving
    /// particles) is closed by the liquid around it, as is an enclosed region without gas.
    #[serde(default = "default_min_pocket_cells")]
    pub min_cells: f64,
}

fn default_ambient_pressure() -> f64 {
    101_325.0
}
fn default_min_pocket_cells() -> f64 {
    4.0
}

impl Default for IncompressibleSettings {
    fn default() -> Self {
        Self {
            tolerance: default_pressure_tolerance(),
            max_iterations: default_pressure_iterations(),
            viscosity: ViscousIntegration::default(),
            outflow: false,
            enclosed_air: None,
            volume_correction: false,
        }
    }
}

/// How the incompressible mode integrates the liquids' viscous stress in time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ViscousIntegration {
    /// The particles' viscous stress of the last step enters P2G as a force; the step is
    /// bounded by ρ·dx²/(2·D·μ).
    #[default]
    Explicit,
    /// Backward Euler on the grid: the nodal velocity solves
    /// (M/dt) v + Σ_p V_p 2μ_p dev(sym ∇v_p)·∇w_p = (M/dt) v̂ before the pressure
    /// projection, with μ_p lagged one step for non-Newtonian laws; no viscous step bound.
    Implicit,
}

fn default_pressure_tolerance() -> f64 {
    1e-8
}
fn default_pressure_iterations() -> u32 {
    2000
}

/// What the implicit mode solves each step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ImplicitForm {
    /// Equilibrium per load step, no inertia; velocities are zero after each step.
    #[default]
    Static,
    /// Newmark time integration with inertia (average acceleration by default).
    Dynamic,
}

/// The Krylov method of each Newton iteration's linear solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum KrylovMethod {
    /// GMRES: the tangent away from equilibrium need not be symmetric or positive definite.
    #[default]
    Auto,
    /// Jacobi-preconditioned conjugate gradients (symmetric tangents).
    Cg,
    /// Restarted GMRES, right-preconditioned by Jacobi (any tangent).
    Gmres,
}

/// How the implicit mode's tangent differentiates the stress.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum TangentMethod {
    /// The laws' analytic stress derivative where every material of the scene has one
    /// (the elastic laws), else finite differences.
    #[default]
    Auto,
    /// Directional finite differences of each law's own stress update (any law).
    FiniteDifference,
}

/// The arithmetic of the implicit solver's factored preconditioner.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum FactorPrecision {
    /// f64.
    #[default]
    Double,
    /// f32: half the bytes of the factor; the residual, the Krylov vectors and the answer
    /// stay f64, so only the Krylov iterations can change. f64 takes over for the rest of
    /// the run once an f32 factorisation fails or a fresh f32 factor needs more than 20
    /// Krylov iterations.
    Single,
}

impl FactorPrecision {
    fn is_double(&self) -> bool {
        *self == FactorPrecision::Double
    }
}

/// Settings of `solver.mechanics.implicit`; every field has a default.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ImplicitSettings {
    /// `static` (equilibrium) or `dynamic` (Newmark).
    #[serde(default)]
    pub form: ImplicitForm,
    /// Newmark β (dynamic form); 1/4 with γ = 1/2 is the energy-conserving average
    /// acceleration rule. Unconditionally stable when β ≥ (γ + 1/2)²/4.
    #[serde(default = "default_newmark_beta")]
    pub beta: f64,
    /// Newmark γ (dynamic form); γ > 1/2 damps the highest frequencies (dissipative variant).
    #[serde(default = "default_newmark_gamma")]
    pub gamma: f64,
    /// Most Newton iterations per step before the step is cut.
    #[serde(default = "default_newton_iterations")]
    pub max_newton_iterations: u32,
    /// Converged when the out-of-balance force norm falls below this fraction of the
    /// step's force scale (external forces, first residual, internal force contributions).
    #[serde(default = "default_force_tolerance")]
    pub force_tolerance: f64,
    /// Or when the energy norm |δu·R| falls below this fraction of the first iteration's.
    #[serde(default = "default_energy_tolerance")]
    pub energy_tolerance: f64,
    /// Linear solver of each Newton iteration.
    #[serde(default)]
    pub krylov: KrylovMethod,
    /// The stress derivative of the tangent: analytic where the laws have it, or finite
    /// differences.
    #[serde(default)]
    pub tangent: TangentMethod,
    /// Relative residual the linear solve reaches (inexact Newton).
    #[serde(default = "default_krylov_tolerance")]
    pub krylov_tolerance: f64,
    /// Most Krylov iterations per linear solve.
    #[serde(default = "default_krylov_iterations")]
    pub max_krylov_iterations: u32,
    /// Halvings of a step that does not converge before the run stops with a diagnostic.
    #[serde(default = "default_max_cuts")]
    pub max_cuts: u32,
    /// Gravity is ramped linearly from 0 over this time, s (static loading in increments);
    /// absent: full gravity from the first step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity_ramp: Option<f64>,
    /// Keep a step's factored preconditioner for the next step (same unknowns and step)
    /// and factor afresh only once a Krylov solve needs more than 20 iterations, instead of
    /// at every step's start: for large 3D static stages, where the factorisation is most of
    /// a step. Off by default (a run's iterates then depend on the steps before it).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub reuse_preconditioner: bool,
    /// `single` factors the preconditioner in f32: for large 3D stages, where the
    /// factorisation is most of a step (about 1.6× faster there, the same iterations).
    #[serde(default, skip_serializing_if = "FactorPrecision::is_double")]
    pub factor_precision: FactorPrecision,
}

impl Default for ImplicitSettings {
    fn default() -> Self {
        Self {
            form: ImplicitForm::Static,
            beta: default_newmark_beta(),
            gamma: default_newmark_gamma(),
            max_newton_iterations: default_newton_iterations(),
            force_tolerance: default_force_tolerance(),
            energy_tolerance: default_energy_tolerance(),
            krylov: KrylovMethod::Auto,
            tangent: TangentMethod::Auto,
            krylov_tolerance: default_krylov_tolerance(),
            max_krylov_iterations: default_krylov_iterations(),
            max_cuts: default_max_cuts(),
            gravity_ramp: None,
            reuse_preconditioner: false,
            factor_precision: FactorPrecision::Double,
        }
    }
}

fn default_newmark_beta() -> f64 {
    0.25
}
fn default_newmark_gamma() -> f64 {
    0.5
}
fn default_newton_iterations() -> u32 {
    25
}
fn default_force_tolerance() -> f64 {
    1e-6
}
fn default_energy_tolerance() -> f64 {
    1e-12
}
fn default_krylov_tolerance() -> f64 {
    1e-6
}
fn default_krylov_iterations() -> u32 {
    500
}
fn default_max_cuts() -> u32 {
    6
}

impl ImplicitSettings {
    /// Checks the tolerances, iteration counts and Newmark parameters.
    fn validate(&self, v: &mut Validator) {
        let p = "solver.mechanics.implicit";
        for (name, value) in [
            ("force_tolerance", self.force_tolerance),
            ("energy_tolerance", self.energy_tolerance),
            ("krylov_tolerance", self.krylov_tolerance),
        ] {
            if !(value > 0.0 && value < 1.0) {
                v.err(
                    format!("{p}.{name}"),
                    format!("must lie in (0, 1) (got {value})"),
                );
            }
        }
        for (name, value) in [
            ("max_newton_iterations", self.max_newton_iterations),
            ("max_krylov_iterations", self.max_krylov_iterations),
        ] {
            if value == 0 {
                v.err(format!("{p}.{name}"), "must be at least 1");
            }
        }
        if self.max_cuts > 30 {
            v.err(format!("{p}.max_cuts"), "must be at most 30");
        }
        if let Some(ramp) = self.gravity_ramp {
            v.positive(&format!("{p}.gravity_ramp"), ramp);
        }
        if !(self.gamma.is_finite() && self.gamma >= 0.5 && self.gamma <= 1.0) {
            v.err(
                format!("{p}.gamma"),
                format!("must lie in [0.5, 1] (got {})", self.gamma),
            );
        } else {
            let least = (self.gamma + 0.5).powi(2) / 4.0;
            if !(self.beta.is_finite() && self.beta >= least - 1e-12 && self.beta <= 1.0) {
                v.err(
                    format!("{p}.beta"),
                    format!(
                        "must lie in [(gamma + 1/2)^2/4, 1] = [{least}, 1] for unconditional stability (got {})",
                        self.beta
                    ),
                );
            }
        }
    }
}

impl Mechanics {
    /// Whether mechanics is explicit dynamics (the default).
    pub fn is_dynamic(&self) -> bool {
        *self == Mechanics::Dynamic
    }

    /// Whether the mode integrates the equations of motion explicitly with nothing but
    /// the bodies' own forces (explicit or total Lagrangian dynamics): energy and momentum
    /// are conserved where nothing acts from outside.
    pub fn is_explicit_dynamics(&self) -> bool {
        matches!(self, Mechanics::Dynamic | Mechanics::TotalLagrangian)
    }
}

fn default_relax_iterations() -> u32 {
    5000
}
fn default_relax_tolerance() -> f64 {
    1e-6
}

/// How a 2D scene's isotropic free strain acts on the stress.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum FreeStrain2d {
    /// In the plane only: the laws see F / (1 + e) in the plane and no out-of-plane strain
    /// (in-plane thermal stresses about 1/(1 + ν) of physical plane strain).
    #[default]
    InPlane,
    /// Physical plane strain (εzz = 0): a law that says `plane_strain_stress` sees the free
    /// strain across the plane too, as its stretch there, and gives σzz; another's in-plane
    /// free strain is scaled by its `plane_strain_expansion` (1 + ν for isotropic elastic
    /// solids) instead.
    PlaneStrain,
    /// Generalized plane strain: as `plane_strain`, but the strain across the plane is one
    /// constant ε₀ for the whole section, with no net force along it (a long body free to
    /// contract along its length, such as a package's cross-section: the die, underfill and
    /// substrate contract together instead of against a rigid wall).
    GeneralizedPlaneStrain,
}

impl FreeStrain2d {
    /// Whether it is the default.
    pub fn is_in_plane(&self) -> bool {
        *self == Self::InPlane
    }
}

/// Volumetric anti-locking options.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum AntiLocking {
    /// Each particle keeps its own volume change.
    #[default]
    None,
    /// F-bar: the volume change is averaged over the neighbouring grid nodes (explicit and
    /// quasi-static modes) or over the particles sharing a stencil (implicit mode).
    Fbar,
}

impl AntiLocking {
    /// Whether no anti-locking is asked for.
    pub fn is_none(&self) -> bool {
        *self == AntiLocking::None
    }
}

fn default_kernel() -> KernelName {
    KernelName::Bspline2
}
fn default_transfer() -> Transfer {
    Transfer::Apic
}
fn default_flip_blend() -> f64 {
    0.99
}
fn default_xpic_order() -> u32 {
    2
}
fn default_scheme() -> Scheme {
    Scheme::Usl
}
fn default_cfl() -> f64 {
    0.3
}
fn default_max_cfl() -> f64 {
    1.0
}
fn default_sort_interval() -> u32 {
    16
}

/// Highest XPIC order a scene may ask for: each order is one more particle round trip per
/// step, and Hammerquist & Nairn report no gain past a few.
pub const MAX_XPIC_ORDER: u32 = 8;

impl Solver {
    /// Checks the time step, CFL, transfer and scheme combinations, gravity and mechanics.
    pub(super) fn validate(&self, v: &mut Validator) {
        v.positive("solver.end_time", self.end_time);
        if !(self.cfl > 0.0 && self.cfl <= 1.0) {
            v.err(
                "solver.cfl",
                format!("must be in (0, 1] (got {})", self.cfl),
            );
        }
        if !(0.0..=1.0).contains(&self.flip_blend) {
            v.err("solver.flip_blend", "must be in [0, 1]");
        }
        if !(1..=MAX_XPIC_ORDER).contains(&self.xpic_order) {
            v.err(
                "solver.xpic_order",
                format!(
                    "must be an order from 1 to {MAX_XPIC_ORDER} (got {})",
                    self.xpic_order
                ),
            );
        }
        if self.transfer == Transfer::Xpic
            && matches!(
                self.mechanics,
                Mechanics::Implicit(_) | Mechanics::Incompressible(_)
            )
        {
            v.err(
                "solver.transfer",
                "`xpic` works with explicit mechanics (`dynamic`, `quasi_static`): the \
                 implicit and incompressible modes solve their velocities on the grid; use \
                 `pic`, `flip` or `apic`",
            );
        }
        if self.mls && self.transfer != Transfer::Apic {
            v.err("solver.mls", "the MLS-MPM force needs `transfer: apic`");
        }
        if self.mls && !matches!(self.kernel, KernelName::Bspline2 | KernelName::Bspline3) {
            v.err(
                "solver.mls",
                "the MLS-MPM force needs a B-spline kernel (constant APIC inertia)",
            );
        }
        if self.mls && self.scheme != Scheme::Usl {
            v.err(
                "solver.mls",
                "the MLS-MPM force is a USL scheme: use `scheme: usl`",
            );
        }
        if let Some(dt) = self.dt {
            v.positive("solver.dt", dt);
        }
        if !self.free_strain_2d.is_in_plane() && v.dim != 2 {
            v.err(
                "solver.free_strain_2d",
                "is for 2D scenes (a 3D scene's free strain acts in every direction): remove it",
            );
        }
        v.positive("solver.max_cfl", self.max_cfl);
        if self
            .end_when
            .as_ref()
            .is_some_and(|name| name.trim().is_empty())
        {
            v.err(
                "solver.end_when",
                "names a figure of the physics report, say \"underfill.fill_time\"",
            );
        }
        if let Some(g) = &self.gravity {
            v.vector("solver.gravity", g);
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            v.err("solver.damping", "must be a finite number >= 0");
        }
        if let Mechanics::QuasiStatic {
            max_iterations,
            tolerance,
            damping,
        } = self.mechanics
        {
            let p = "solver.mechanics.quasi_static";
            if max_iterations == 0 {
                v.err(format!("{p}.max_iterations"), "must be at least 1");
            }
            if !(tolerance > 0.0 && tolerance < 1.0) {
                v.err(
                    format!("{p}.tolerance"),
                    format!("must lie in (0, 1) (got {tolerance})"),
                );
            }
            if let Some(d) = damping {
                v.positive(&format!("{p}.damping"), d);
            }
        }
        if let Mechanics::Incompressible(settings) = &self.mechanics {
            let p = "solver.mechanics.incompressible";
            if !(settings.tolerance > 0.0 && settings.tolerance < 1.0) {
                v.err(
                    format!("{p}.tolerance"),
                    format!("must lie in (0, 1) (got {})", settings.tolerance),
                );
            }
            if settings.max_iterations == 0 {
                v.err(format!("{p}.max_iterations"), "must be at least 1");
            }
            if let Some(air) = &settings.enclosed_air {
                if !(air.ambient_pressure.is_finite() && air.ambient_pressure > 0.0) {
                    v.err(
                        format!("{p}.enclosed_air.ambient_pressure"),
                        format!(
                            "must be a finite absolute pressure > 0 Pa (got {})",
                            air.ambient_pressure
                        ),
                    );
                }
                if !(air.min_cells.is_finite() && air.min_cells >= 1.0) {
                    v.err(
                        format!("{p}.enclosed_air.min_cells"),
                        format!(
                            "must be a finite number of cells ≥ 1 (got {})",
                            air.min_cells
                        ),
                    );
                }
            }
            if self.anti_locking == AntiLocking::Fbar {
                v.err(
                    "solver.anti_locking",
                    "F-bar has no part in incompressible mechanics (the pressure solve keeps the volume): remove it",
                );
            }
        }
        if let Mechanics::Implicit(settings) = &self.mechanics {
            settings.validate(v);
        }
    }
}
