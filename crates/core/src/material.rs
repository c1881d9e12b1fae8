//! The constitutive-model interface: a material updates the stress of a whole batch of its
//! particles per call, so dynamic dispatch happens once per batch, never per particle.

use crate::math::Matrix;

/// Most per-particle state fields one material may declare.
pub const MAX_STATE_FIELDS: usize = 8;

/// Most shared fields (created by physics operators) one material may read.
pub const MAX_SHARED_READS: usize = 4;

/// A shared particle field a material reads (see [`crate::physics`]): `temperature` for
/// thermal softening, `solid_fraction` for a law that moves from fluid to solid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SharedRead {
    /// Field name.
    pub name: &'static str,
    /// Whether the scene must have a physics that creates it (else the slice is empty).
    pub required: bool,
}

/// A per-particle field a material keeps between steps (plastic strain, damage, ...).
/// The core allocates it only for the particles of that material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldSpec {
    /// Name, also used as the output field name.
    pub name: &'static str,
    /// Numbers per particle.
    pub components: usize,
    /// Value every particle starts with.
    pub initial: FieldInit,
}

impl FieldSpec {
    /// The field's start values for `count` particles of a `dimension`-D run, `components`
    /// numbers each (a run's start, and particles a stage converts into this material).
    pub fn initial_values(&self, count: usize, dimension: usize) -> Vec<f64> {
        let c = self.components;
        let mut field = vec![0.0; count * c];
        match self.initial {
            FieldInit::Zero => {}
            FieldInit::Identity => {
                for p in 0..count {
                    for d in 0..dimension {
                        field[p * c + d * dimension + d] = 1.0;
                    }
                }
            }
            FieldInit::Constant(value) => field.fill(value),
            FieldInit::Values(values) => {
                for chunk in field.chunks_exact_mut(c) {
                    for (x, v) in chunk.iter_mut().zip(values) {
                        *x = *v;
                    }
                }
            }
        }
        field
    }
}

/// A state field the core averages over a material length after every step: each
/// particle's `averaged` field becomes the volume-weighted mean of the `local` field over
/// the particles of its material within `radius` (never lower than it was, at most
/// `cap`). A damage law drives its damage this way so a crack's onset does not depend on
/// the cell (a nonlocal integral model); see `solver/state_averaging.rs`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AveragedState {
    /// Index (in [`ConstitutiveLaw::state_fields`]) of the one-component field averaged.
    pub local: usize,
    /// Index of the one-component field the average goes to.
    pub averaged: usize,
    /// Radius of the average, m (a material length).
    pub radius: f64,
    /// Largest value the averaged field takes.
    pub cap: f64,
}

/// Name of the one-component state field in which a law accumulates its inelastic work
/// density, J per m³ of reference volume; the stage figures average it per material and
/// turn its increment over a stage (a thermal cycle) into cycles to crack
/// ([`ConstitutiveLaw::cycles_to_crack`], `fatigue_measures.rs`).
pub const INELASTIC_WORK: &str = "inelastic_work";

/// Initial value of a state field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FieldInit {
    /// All zeros.
    Zero,
    /// The identity matrix (for a field of `D*D` components).
    Identity,
    /// The same number in every component (an initial temperature, say).
    Constant(f64),
    /// These numbers, one per component (a 3×3 identity in a 2D law that tracks the
    /// out-of-plane direction, say).
    Values(&'static [f64]),
}

/// The state fields of one batch, in the order the material declared them; each slice holds
/// `components` numbers per particle.
pub struct StateSlices<'a> {
    /// One slice per declared field; unused entries are empty.
    pub fields: [&'a mut [f64]; MAX_STATE_FIELDS],
}

/// The state fields of one batch, read-only: what the implicit tangent sees of the state
/// the step started from (see [`TangentBatch::state`]).
pub struct StateView<'a> {
    /// One slice per declared field, in declaration order; unused entries are empty.
    pub fields: [&'a [f64]; MAX_STATE_FIELDS],
}

/// Everything a material sees of one batch of its particles.
pub struct StressBatch<'a, const D: usize> {
    /// Time step of the update, seconds.
    pub dt: f64,
    /// Deformation gradient after this step's kinematic update.
    pub deformation_gradient: &'a [Matrix<D>],
    /// Velocity gradient of this step; empty unless the material asked for it
    /// ([`ConstitutiveLaw::needs_velocity_gradient`]).
    pub velocity_gradient: &'a [Matrix<D>],
    /// Reference (initial) volume of each particle, m³ (m² in 2D: per unit thickness).
    pub volume0: &'a [f64],
    /// Cauchy stress, written by the material.
    pub stress: &'a mut [Matrix<D>],
    /// In 2D (plane strain), each particle's mechanical stretch across the plane, F_zz:
    /// 1/(1 + e) where a free strain e acts across the plane too
    /// (`solver.free_strain_2d: "plane_strain"`). Empty means 1 (3D, or no free strain
    /// across the plane); read it with [`out_of_plane_stretch`].
    pub out_of_plane_stretch: &'a [f64],
    /// In 2D (plane strain), where a law that says [`ConstitutiveLaw::plane_strain_stress`]
    /// writes σzz, the stress the held third direction carries; empty in 3D.
    pub out_of_plane_stress: &'a mut [f64],
    /// The material's own per-particle state.
    pub state: StateSlices<'a>,
    /// The shared fields the material declared in [`ConstitutiveLaw::shared_reads`], in that
    /// order; a field no physics created is an empty slice.
    pub shared: [&'a [f64]; MAX_SHARED_READS],
    /// Where the law writes the plastic work it dissipated in this step, J per m³ of
    /// reference volume (heat for a thermal physics); empty when nothing consumes it.
    pub plastic_work: &'a mut [f64],
}

/// What a law sees to differentiate its stress: the implicit mode's tangent, for laws that
/// give it analytically ([`ConstitutiveLaw::has_stress_derivative`]).
pub struct TangentBatch<'a, const D: usize> {
    /// Time step of the update, seconds.
    pub dt: f64,
    /// Deformation gradient the derivative is taken at (the law's last update's).
    pub deformation_gradient: &'a [Matrix<D>],
    /// The change of the deformation gradient to differentiate along, per particle.
    pub direction: &'a [Matrix<D>],
    /// Cauchy stress at `deformation_gradient`.
    pub stress: &'a [Matrix<D>],
    /// The stretch across the plane the stress was computed with, as in
    /// [`StressBatch::out_of_plane_stretch`] (held fixed: δF has no zz part).
    pub out_of_plane_stretch: &'a [f64],
    /// The law's state at the start of the step, i.e. the state `update_stress` started
    /// from to reach `stress` (a path-dependent law differentiates its return map from it).
    pub state: StateView<'a>,
    /// The shared fields the law reads, as in [`StressBatch::shared`].
    pub shared: [&'a [f64]; MAX_SHARED_READS],
    /// Where the law writes dσ = ∂σ/∂F : direction, per particle.
    pub stress_change: &'a mut [Matrix<D>],
}

/// What a liquid sees to give its particles' dynamic viscosities: the incompressible
/// mode's implicit viscous solve (`viscosity: "implicit"`) evaluates them at the state
/// the step starts from (the last step's velocity gradient, temperature and cure) and
/// keeps them through the step (lagged one step, a Picard iteration over steps).
pub struct ViscosityBatch<'a, const D: usize> {
    /// Velocity gradient of the last step; empty unless the law asked for it
    /// ([`ConstitutiveLaw::needs_velocity_gradient`]).
    pub velocity_gradient: &'a [Matrix<D>],
    /// The shared fields the law reads, as in [`StressBatch::shared`].
    pub shared: [&'a [f64]; MAX_SHARED_READS],
    /// Where the law writes each particle's dynamic viscosity, Pa·s.
    pub viscosity: &'a mut [f64],
}

/// What a batch update reports back for diagnostics and the time step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BatchStats {
    /// Stored (strain) energy of the batch, J (J/m in 2D).
    pub strain_energy: f64,
    /// Largest wave speed in the batch, m/s; it bounds the stable time step.
    pub max_wave_speed: f64,
}

impl BatchStats {
    /// Combines the statistics of two batches.
    pub fn merge(self, other: Self) -> Self {
        Self {
            strain_energy: self.strain_energy + other.strain_energy,
            max_wave_speed: self.max_wave_speed.max(other.max_wave_speed),
        }
    }
}

/// What a plugin author implements for a material: one generic stress update that serves
/// both 2D (plane strain) and 3D.
pub trait ConstitutiveLaw: Send + Sync + 'static {
    /// Mass density in the reference configuration, kg/m³.
    fn density(&self) -> f64;
    /// Per-particle state this law keeps (none by default).
    fn state_fields(&self) -> &[FieldSpec] {
        &[]
    }
    /// A state field the core averages over a material length after every step (see
    /// [`AveragedState`]); none by default.
    fn averaged_state(&self) -> Option<AveragedState> {
        None
    }
    /// Whether the law needs the velocity gradient (rate-dependent laws do).
    fn needs_velocity_gradient(&self) -> bool {
        false
    }
    /// Shared fields (from physics operators) the law reads, at most [`MAX_SHARED_READS`].
    fn shared_reads(&self) -> &[SharedRead] {
        &[]
    }
    /// Whether the law writes the plastic work it dissipates ([`StressBatch::plastic_work`]);
    /// the core then always allocates that field, so the energy ledger counts it.
    fn reports_plastic_work(&self) -> bool {
        false
    }
    /// Cycles to crack initiation of a law with a fatigue law, from the volume-averaged
    /// inelastic work density of one cycle, J/m³ (see [`INELASTIC_WORK`]); `None`, the
    /// default, for a law without one or at no work.
    fn cycles_to_crack(&self, work_per_cycle: f64) -> Option<f64> {
        let _ = work_per_cycle;
        None
    }
    /// Cycles to failure of a law whose fatigue law also grows the crack (Darveaux:
    /// initiation, then a crack across the joint at a rate set by the same work per
    /// cycle); `None`, the default, without a growth law or at no work.
    fn cycles_to_failure(&self, work_per_cycle: f64) -> Option<f64> {
        let _ = work_per_cycle;
        None
    }
    /// Computes the Cauchy stress of every particle in the batch and reports the batch's
    /// strain energy and largest wave speed.
    fn update_stress<const D: usize>(&self, batch: StressBatch<'_, D>) -> BatchStats;
    /// Whether the law implements [`ConstitutiveLaw::stress_derivative`]. Without it (the
    /// default) the implicit mode differences `update_stress` instead, which every law
    /// supports; an analytic derivative is exact and skips the state restore and update.
    fn has_stress_derivative(&self) -> bool {
        false
    }
    /// The directional derivative of the stress, dσ = ∂σ/∂F : δF, of every particle in
    /// the batch at its deformation gradient: for a law with state, the derivative of the
    /// update from [`TangentBatch::state`] (the consistent tangent of its return map).
    /// Called only when [`ConstitutiveLaw::has_stress_derivative`] says so.
    fn stress_derivative<const D: usize>(&self, batch: TangentBatch<'_, D>) {
        let _ = batch;
    }
    /// `Some(μ)` marks a liquid: a law that gives only the deviatoric (viscous) stress,
    /// whose pressure the incompressible mode (`solver.mechanics.incompressible`) solves
    /// for; μ bounds its dynamic viscosity, Pa·s (say, the largest it has computed), for the
    /// explicit viscous step limit ρ·dx²/(2·D·μ). A liquid may keep a one-component state
    /// field named `pressure`: the mode writes each particle's pressure there. `None`, the
    /// default, is a solid, which the incompressible mode refuses.
    fn liquid_viscosity(&self) -> Option<f64> {
        None
    }
    /// Called before each step's stress update in the incompressible mode: a liquid starts
    /// its bound [`ConstitutiveLaw::liquid_viscosity`] afresh, so that the bound follows its
    /// viscosity down as well as up (a liquid that physics heats thins, and its step grows).
    fn forget_viscosity_bound(&self) {}
    /// A liquid's surface tension against the void, N/m: the incompressible mode sets the
    /// Laplace pressure σ·κ on its free surface. 0, the default, is no surface tension.
    fn surface_tension(&self) -> f64 {
        0.0
    }
    /// Each particle's dynamic viscosity, Pa·s, for the incompressible mode's implicit
    /// viscous solve; a liquid's `update_stress` must give the stress 2μ·dev(sym L) with
    /// the same μ at the same state. The default writes the bound
    /// [`ConstitutiveLaw::liquid_viscosity`] (0 for a solid) for every particle, right for
    /// a Newtonian liquid; a law whose viscosity depends on the state overrides it.
    fn liquid_viscosities<const D: usize>(&self, batch: ViscosityBatch<'_, D>) {
        let mu = self.liquid_viscosity().unwrap_or(0.0);
        batch.viscosity.fill(mu);
    }
    /// With `solver.free_strain_2d: "plane_strain"`, the factor by which a 2D scene's
    /// isotropic free strain (thermal expansion, cure shrinkage) acts in the plane, standing
    /// in for the out-of-plane part the held third direction turns into in-plane stress:
    /// 1 + ν for an isotropic elastic solid (the plane-strain expansion (1 + ν)α of the
    /// textbooks). The default 1 leaves the free strain in the plane only.
    fn plane_strain_expansion(&self) -> f64 {
        1.0
    }
    /// Whether the law, in 2D, is its 3D law at F = [[F, 0], [0, F_zz]]: it reads the stretch
    /// [`StressBatch::out_of_plane_stretch`] (and [`TangentBatch::out_of_plane_stretch`])
    /// and writes σzz to [`StressBatch::out_of_plane_stress`]. Then a free strain with
    /// `solver.free_strain_2d: "plane_strain"` reaches the law as that stretch (exact plane
    /// strain for any law) instead of scaled by [`ConstitutiveLaw::plane_strain_expansion`]
    /// in the plane. False, the default: σzz reads 0 and the scaling stands in.
    fn plane_strain_stress(&self) -> bool {
        false
    }
}

/// Particle `k`'s stretch across the plane from [`StressBatch::out_of_plane_stretch`]:
/// 1 where the slice is empty.
#[inline]
pub fn out_of_plane_stretch(stretch: &[f64], k: usize) -> f64 {
    stretch.get(k).copied().unwrap_or(1.0)
}

/// Object-safe form of [`ConstitutiveLaw`]; implemented for every law, used by the solver.
pub trait Material: Send + Sync {
    /// See [`ConstitutiveLaw::density`].
    fn density(&self) -> f64;
    /// See [`ConstitutiveLaw::state_fields`].
    fn state_fields(&self) -> &[FieldSpec];
    /// See [`ConstitutiveLaw::averaged_state`].
    fn averaged_state(&self) -> Option<AveragedState>;
    /// See [`ConstitutiveLaw::needs_velocity_gradient`].
    fn needs_velocity_gradient(&self) -> bool;
    /// See [`ConstitutiveLaw::shared_reads`].
    fn shared_reads(&self) -> &[SharedRead];
    /// See [`ConstitutiveLaw::reports_plastic_work`].
    fn reports_plastic_work(&self) -> bool;
    /// See [`ConstitutiveLaw::cycles_to_crack`].
    fn cycles_to_crack(&self, work_per_cycle: f64) -> Option<f64>;
    /// See [`ConstitutiveLaw::cycles_to_failure`].
    fn cycles_to_failure(&self, work_per_cycle: f64) -> Option<f64>;
    /// 2D (plane strain) batch update.
    fn update_stress_2d(&self, batch: StressBatch<'_, 2>) -> BatchStats;
    /// 3D batch update.
    fn update_stress_3d(&self, batch: StressBatch<'_, 3>) -> BatchStats;
    /// See [`ConstitutiveLaw::has_stress_derivative`].
    fn has_stress_derivative(&self) -> bool;
    /// 2D [`ConstitutiveLaw::stress_derivative`].
    fn stress_derivative_2d(&self, batch: TangentBatch<'_, 2>);
    /// 3D [`ConstitutiveLaw::stress_derivative`].
    fn stress_derivative_3d(&self, batch: TangentBatch<'_, 3>);
    /// See [`ConstitutiveLaw::liquid_viscosity`].
    fn liquid_viscosity(&self) -> Option<f64>;
    /// See [`ConstitutiveLaw::forget_viscosity_bound`].
    fn forget_viscosity_bound(&self);
    /// See [`ConstitutiveLaw::surface_tension`].
    fn surface_tension(&self) -> f64;
    /// 2D [`ConstitutiveLaw::liquid_viscosities`].
    fn liquid_viscosities_2d(&self, batch: ViscosityBatch<'_, 2>);
    /// 3D [`ConstitutiveLaw::liquid_viscosities`].
    fn liquid_viscosities_3d(&self, batch: ViscosityBatch<'_, 3>);
    /// See [`ConstitutiveLaw::plane_strain_expansion`].
    fn plane_strain_expansion(&self) -> f64;
    /// See [`ConstitutiveLaw::plane_strain_stress`].
    fn plane_strain_stress(&self) -> bool;
}

impl<T: ConstitutiveLaw> Material for T {
    fn density(&self) -> f64 {
        ConstitutiveLaw::density(self)
    }
    fn state_fields(&self) -> &[FieldSpec] {
        ConstitutiveLaw::state_fields(self)
    }
    fn averaged_state(&self) -> Option<AveragedState> {
        ConstitutiveLaw::averaged_state(self)
    }
    fn needs_velocity_gradient(&self) -> bool {
        ConstitutiveLaw::needs_velocity_gradient(self)
    }
    fn shared_reads(&self) -> &[SharedRead] {
        ConstitutiveLaw::shared_reads(self)
    }
    fn reports_plastic_work(&self) -> bool {
        ConstitutiveLaw::reports_plastic_work(self)
    }
    fn cycles_to_crack(&self, work_per_cycle: f64) -> Option<f64> {
        ConstitutiveLaw::cycles_to_crack(self, work_per_cycle)
    }
    fn cycles_to_failure(&self, work_per_cycle: f64) -> Option<f64> {
        ConstitutiveLaw::cycles_to_failure(self, work_per_cycle)
    }
    fn update_stress_2d(&self, batch: StressBatch<'_, 2>) -> BatchStats {
        self.update_stress::<2>(batch)
    }
    fn update_stress_3d(&self, batch: StressBatch<'_, 3>) -> BatchStats {
        self.update_stress::<3>(batch)
    }
    fn has_stress_derivative(&self) -> bool {
        ConstitutiveLaw::has_stress_derivative(self)
    }
    fn stress_derivative_2d(&self, batch: TangentBatch<'_, 2>) {
        self.stress_derivative::<2>(batch)
    }
    fn stress_derivative_3d(&self, batch: TangentBatch<'_, 3>) {
        self.stress_derivative::<3>(batch)
    }
    fn liquid_viscosity(&self) -> Option<f64> {
        ConstitutiveLaw::liquid_viscosity(self)
    }
    fn forget_viscosity_bound(&self) {
        ConstitutiveLaw::forget_viscosity_bound(self)
    }
    fn surface_tension(&self) -> f64 {
        ConstitutiveLaw::surface_tension(self)
    }
    fn liquid_viscosities_2d(&self, batch: ViscosityBatch<'_, 2>) {
        self.liquid_viscosities::<2>(batch)
    }
    fn liquid_viscosities_3d(&self, batch: ViscosityBatch<'_, 3>) {
        self.liquid_viscosities::<3>(batch)
    }
    fn plane_strain_expansion(&self) -> f64 {
        ConstitutiveLaw::plane_strain_expansion(self)
    }
    fn plane_strain_stress(&self) -> bool {
        ConstitutiveLaw::plane_strain_stress(self)
    }
}

/// Lamé parameters (λ, μ) from Young's modulus and Poisson's ratio.
pub fn lame_parameters(youngs_modulus: f64, poisson_ratio: f64) -> (f64, f64) {
    let e = youngs_modulus;
    let nu = poisson_ratio;
    let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = e / (2.0 * (1.0 + nu));
    (lambda, mu)
}
