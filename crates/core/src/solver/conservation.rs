//! Conservation checks of a run: total mass, linear momentum and angular momentum (with
//! APIC's affine part: APIC keeps it, PIC loses it, FLIP does not keep it), measured at
//! every frame against the start.
//! A run's metrics say which of them the scene should keep (nothing acts from outside:
//! no gravity, walls, obstacles or damping) and by how much they changed.

use crate::math::{Matrix, Vector};
use crate::output::Conservation;
use crate::particles::Particles;

/// Totals of one instant.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Totals {
    mass: f64,
    /// Linear momentum (x, y, z; z is 0 in 2D).
    momentum: [f64; 3],
    /// Σ m |v|: the scale a change of momentum is judged against.
    momentum_scale: f64,
    /// Angular momentum about the origin (2D: only z), with the APIC affine part.
    angular: [f64; 3],
    /// Σ m |x − x̄| |v| + |affine part|: the scale of angular momentum.
    angular_scale: f64,
}

impl Totals {
    /// The angular momentum's magnitude about the origin (2D: its z component).
    pub fn angular_momentum(&self) -> f64 {
        self.angular.iter().map(|a| a * a).sum::<f64>().sqrt()
    }
}

/// Measures the particles' totals; `affine_inertia` is the APIC inertia D = coef·dx² of a
/// B-spline kernel (None: no affine part is counted).
pub(super) fn totals<const D: usize>(
    particles: &Particles<D>,
    affine_inertia: Option<f64>,
) -> Totals {
    let n = particles.len();
    let mut t = Totals::default();
    let mut centre = Vector::<D>::zeros();
    for p in 0..n {
        t.mass += particles.mass[p];
        centre += particles.position[p] * particles.mass[p];
    }
    if t.mass > 0.0 {
        centre /= t.mass;
    }
    let with_affine = affine_inertia.filter(|_| particles.affine.len() == n);
    for p in 0..n {
        let (m, x, v) = (
            particles.mass[p],
            particles.position[p],
            particles.velocity[p],
        );
        let (x3, v3) = (embed(&x), embed(&v));
        let spin = match with_affine {
            Some(inertia) => affine_spin(&particles.affine[p], inertia),
            None => [0.0; 3],
        };
        let cross = x3.cross(&v3);
        for a in 0..3 {
            t.momentum[a] += m * v3[a];
            t.angular[a] += m * (cross[a] + spin[a]);
        }
        t.momentum_scale += m * v.norm();
        let arm = (x - centre).norm();
        t.angular_scale += m * (arm * v.norm() + spin.iter().map(|s| s * s).sum::<f64>().sqrt());
    }
    t
}

fn embed<const D: usize>(v: &Vector<D>) -> nalgebra::Vector3<f64> {
    let mut out = nalgebra::Vector3::zeros();
    for d in 0..D {
        out[d] = v[d];
    }
    out
}

/// The angular momentum per unit mass the affine velocity C carries on the grid:
/// Σᵢ wᵢ dᵢ × C dᵢ = D·(C_zy − C_yz, C_xz − C_zx, C_yx − C_xy) with Σ w d dᵀ = D·I.
fn affine_spin<const D: usize>(c: &Matrix<D>, inertia: f64) -> [f64; 3] {
    let at = |r: usize, col: usize| if r < D && col < D { c[(r, col)] } else { 0.0 };
    [
        inertia * (at(2, 1) - at(1, 2)),
        inertia * (at(0, 2) - at(2, 0)),
        inertia * (at(1, 0) - at(0, 1)),
    ]
}

/// Largest changes from the start over the frames seen so far.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Tracker {
    start: Totals,
    mass: f64,
    momentum: f64,
    angular: f64,
    momentum_scale: f64,
    angular_scale: f64,
}

impl Tracker {
    /// Starts from the totals at time 0.
    pub fn new(start: Totals) -> Self {
        Self {
            start,
            momentum_scale: start.momentum_scale,
            angular_scale: start.angular_scale,
            ..Self::default()
        }
    }

    /// Takes in the totals of a frame.
    pub fn observe(&mut self, now: Totals) {
        let s = &self.start;
        let change =
            |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
        self.momentum_scale = self.momentum_scale.max(now.momentum_scale);
        self.angular_scale = self.angular_scale.max(now.angular_scale);
        self.mass = self.mass.max((now.mass - s.mass).abs());
        self.momentum = self.momentum.max(change(now.momentum, s.momentum));
        self.angular = self.angular.max(change(now.angular, s.angular));
    }

    /// The run's figures: `external` says whether anything acts from outside (then
    /// momentum need not be kept); `angular` whether angular momentum can be measured (not
    /// for APIC with GIMP or linear shape functions, whose affine inertia is not stored).
    pub fn report(&self, external: bool, angular: bool) -> Conservation {
        let relative = |change: f64, scale: f64| if scale > 0.0 { change / scale } else { 0.0 };
        Conservation {
            external_forces: external,
            mass_change: relative(self.mass, self.start.mass),
            momentum_change: relative(self.momentum, self.momentum_scale),
            angular_momentum_change: angular.then(|| relative(self.angular, self.angular_scale)),
        }
    }
}

impl Tracker {
    /// Appends the tracker's numbers to a checkpoint's scalars.
    pub fn save(&self, out: &mut crate::checkpoint::Scalars) {
        let s = &self.start;
        out.push(&[s.mass]);
        out.push(&s.momentum);
        out.push(&[s.momentum_scale]);
        out.push(&s.angular);
        out.push(&[
            s.angular_scale,
            self.mass,
            self.momentum,
            self.angular,
            self.momentum_scale,
            self.angular_scale,
        ]);
    }

    /// Reads what [`Tracker::save`] wrote.
    pub fn load(
        input: &mut crate::checkpoint::Scalars,
    ) -> Result<Self, crate::checkpoint::CheckpointError> {
        let start = Totals {
            mass: input.take()?,
            momentum: input.take_n()?,
            momentum_scale: input.take()?,
            angular: input.take_n()?,
            angular_scale: input.take()?,
        };
        let [mass, momentum, angular, momentum_scale, angular_scale] = input.take_n()?;
        Ok(Self {
            start,
            mass,
            momentum,
            angular,
            momentum_scale,
            angular_scale,
        })
    }
}
