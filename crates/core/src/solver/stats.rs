//! Per-step statistics gathered inside the particle passes (no extra sweep).

use crate::math::Vector;

/// A problem found at one particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ParticleFault {
    pub particle: usize,
    pub field: &'static str,
    pub value: f64,
}

impl ParticleFault {
    /// Keeps the fault of the lower particle index, so results do not depend on threads.
    pub fn first(a: Option<Self>, b: Option<Self>) -> Option<Self> {
        match (a, b) {
            (Some(x), Some(y)) => Some(if x.particle <= y.particle { x } else { y }),
            (x, None) => x,
            (None, y) => y,
        }
    }
}

/// Kinematic figures of the particles after a velocity/position/F update.
#[derive(Clone, Copy, Debug)]
pub(crate) struct KinematicStats<const D: usize> {
    pub kinetic_energy: f64,
    pub momentum: Vector<D>,
    /// Potential energy of gravity, -Σ m g·x.
    pub gravity_energy: f64,
    pub max_speed: f64,
    pub min_det_f: f64,
    pub min_det_particle: usize,
    /// NaN/inf in a particle field.
    pub non_finite: Option<ParticleFault>,
    /// A particle whose stencil left the grid.
    pub escaped: Option<ParticleFault>,
}

impl<const D: usize> Default for KinematicStats<D> {
    fn default() -> Self {
        Self {
            kinetic_energy: 0.0,
            momentum: Vector::<D>::zeros(),
            gravity_energy: 0.0,
            max_speed: 0.0,
            min_det_f: f64::INFINITY,
            min_det_particle: 0,
            non_finite: None,
            escaped: None,
        }
    }
}

impl<const D: usize> KinematicStats<D> {
    /// Combines two partial results.
    pub fn merge(self, o: Self) -> Self {
        let (min_det_f, min_det_particle) = if o.min_det_f < self.min_det_f {
            (o.min_det_f, o.min_det_particle)
        } else {
            (self.min_det_f, self.min_det_particle)
        };
        Self {
            kinetic_energy: self.kinetic_energy + o.kinetic_energy,
            momentum: self.momentum + o.momentum,
            gravity_energy: self.gravity_energy + o.gravity_energy,
            max_speed: self.max_speed.max(o.max_speed),
            min_det_f,
            min_det_particle,
            non_finite: ParticleFault::first(self.non_finite, o.non_finite),
            escaped: ParticleFault::first(self.escaped, o.escaped),
        }
    }
}

impl<const D: usize> KinematicStats<D> {
    /// Adds particle `p` (mass `m`, velocity `v`, position `x`, deformation gradient `f`)
    /// to the sums and checks under `pull` (gravity, and the particle's dead-load share if
    /// the scene has loads): kinetic energy, momentum, the potential of gravity and loads,
    /// the largest speed squared (G2P takes the root once per chunk), the smallest det F
    /// and the first non-finite field.
    #[inline(always)]
    pub fn record(
        &mut self,
        p: usize,
        m: f64,
        v: &crate::math::Vector<D>,
        x: &crate::math::Vector<D>,
        f: &crate::math::Matrix<D>,
        pull: (&crate::math::Vector<D>, Option<&crate::math::Vector<D>>),
    ) {
        let (gravity, load) = pull;
        let speed2 = v.norm_squared();
        self.kinetic_energy += 0.5 * m * speed2;
        self.momentum += *v * m;
        self.gravity_energy -= m * gravity.dot(x);
        // A dead load's potential, −f·x, counts with gravity's.
        if let Some(load) = load {
            self.gravity_energy -= load.dot(x);
        }
        self.max_speed = self.max_speed.max(speed2);
        let det = crate::math::determinant(f);
        if det < self.min_det_f {
            self.min_det_f = det;
            self.min_det_particle = p;
        }
        if self.non_finite.is_none() {
            let bad = if !speed2.is_finite() {
                Some(("v", speed2))
            } else if !x.iter().all(|c| c.is_finite()) {
                Some(("x", x.norm()))
            } else if !det.is_finite() {
                Some(("F", det))
            } else {
                None
            };
            self.non_finite = bad.map(|(field, value)| ParticleFault {
                particle: p,
                field,
                value,
            });
        }
    }
}
