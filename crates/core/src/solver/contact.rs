//! The contact law between grid velocity fields (multi-velocity-field MPM, Bardenhagen et
//! al. 2000/2001; Huang et al. 2011), applied node by node after every field's own grid
//! update and before G2P.
//!
//! At a node where two or more fields have mass, field `f` is compared with the centre of
//! mass of all fields there:
//! - normal: `n_f = (g_f − g_others) / |…|` with `g = Σ_p m_p ∇w_ip` (the P2G weight
//!   gradient, taken with respect to the particle position, so `g` points out of its field's
//!   body): the difference of the two fields' mass gradients (Nairn's recommendation),
//!   pointing out of `f`; antisymmetric between two fields, so the corrections of a pair
//!   cancel and momentum is conserved;
//! - gap test: the fields touch only where the particle volumes they map to the node fill
//!   its support, `Σ_f Σ_p w_ip V_p ≥ (1 − GAP_TOLERANCE) dx^D` (for a flat interface
//!   between two bodies that tile space this is `φ_f + φ_others ≥ 1`, i.e. surfaces meet),
//!   so fields whose kernels overlap across a gap stay apart instead of touching a cell
//!   early;
//! - approach: `(v_f − v_cm)·n_f > 0`; separating fields are left free;
//! - the law of the pair (`f`, the other field with most mass at the node): frictionless
//!   removes the normal part of `v_f − v_cm`; Coulomb friction also reduces the tangential
//!   part by at most `μ` times the normal correction (stick when less is needed); no-slip
//!   sets `v_cm`. Pairs no scene pair names stay bonded: `v_cm` wherever both have mass,
//!   which is what a single shared field gives;
//! - a `cohesive` pair (a bonded interface that can delaminate, `cohesive.rs`) acts at its
//!   bonded nodes where only its two fields have mass, with its traction–separation law
//!   and no gap or approach test; elsewhere, and once debonded, it is Coulomb contact with
//!   the law's friction coefficient.

use super::cohesive::{CohesiveNode, NodeChange, Precrack, advance, bond_impulse};
use super::parallel::{SharedSlice, ordered_reduce};
use crate::boundary::Boundaries;
use crate::grid::{Grid, node_coords, node_position};
use crate::math::Vector;
use crate::scene::{CohesiveLaw, ContactLaw, MAX_CONTACT_FIELDS};

/// How far below a full support the particle volume at a node may be while the fields
/// there still count as touching (fraction of `dx^D`). Zero: the surfaces must meet. A
/// tolerance t accepts a gap of about t / 0.75 cells at a node on a flat interface (the
/// quadratic B-spline's slope there), but also lets nodes near the edge of a contact patch
/// touch, whose tilted normals add drag: the block on the incline (dx = 0.02) slid with
/// 0.9997, 0.963 and 0.817 of g(sin θ − μ cos θ) for t = 0, 0.02 and 0.1.
pub const GAP_TOLERANCE: f64 = 0.0;

/// The law between two fields as the solver applies it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum FieldLaw {
    /// One velocity wherever both have mass (fields no scene pair names).
    Bonded,
    /// A law from the scene's `contact` section.
    Contact(ContactLaw),
}

/// The law of every pair of fields, `count × count`, and the precracks of the cohesive
/// pairs.
pub(crate) struct FieldLaws {
    count: usize,
    laws: Vec<FieldLaw>,
    /// Where cohesive pairs start debonded.
    pub(crate) precracks: Vec<Precrack>,
}

impl FieldLaws {
    /// All pairs bonded.
    pub(crate) fn bonded(count: usize) -> Self {
        Self {
            count,
            laws: vec![FieldLaw::Bonded; count * count],
            precracks: Vec::new(),
        }
    }

    /// The cohesive law between fields `f` and `g`, if theirs is one.
    pub(crate) fn cohesive(&self, f: usize, g: usize) -> Option<CohesiveLaw> {
        match self.get(f, g) {
            FieldLaw::Contact(ContactLaw::Cohesive(law)) => Some(law),
            _ => None,
        }
    }

    /// Whether any pair of fields has a cohesive law.
    pub(crate) fn has_cohesive(&self) -> bool {
        self.laws
            .iter()
            .any(|l| matches!(l, FieldLaw::Contact(ContactLaw::Cohesive(_))))
    }

    /// Sets the law between fields `f` and `g` (both ways).
    pub(crate) fn set(&mut self, f: usize, g: usize, law: ContactLaw) {
        self.laws[f * self.count + g] = FieldLaw::Contact(law);
        self.laws[g * self.count + f] = FieldLaw::Contact(law);
    }

    #[inline]
    fn get(&self, f: usize, g: usize) -> FieldLaw {
        self.laws[f * self.count + g]
    }
}

/// What the contact pass did in one step.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ContactStats {
    /// Nodes where a contact law changed a field's velocity.
    pub nodes: usize,
    /// Kinetic energy the corrections added at the nodes (≤ 0: impact and friction loss).
    /// It is not a dissipation: most of it is the momentum exchange that the bodies turn
    /// into strain energy, and the next P2G rebuilds part of the relative velocity it
    /// removes (0.83 of the two disks' initial kinetic energy in total, while they lose
    /// 0.14 of their energy), so only `friction_work` enters the energy balance.
    pub work: f64,
    /// Magnitude of the momentum the corrections moved between fields (an impulse, N·s).
    pub impulse: f64,
    /// Work of Coulomb friction against the slip where fields slide, J (≤ 0):
    /// `Σ m_f Δv_t · (v̄_f − v_cm)_t` with the tangential parts of the change and of the
    /// mean of the old and new velocity relative to the centre of mass.
    pub friction_work: f64,
    /// What the cohesive laws did (energy dissipated, nodes damaged and debonded).
    pub cohesive: NodeChange,
}

impl ContactStats {
    fn merge(a: Self, b: Self) -> Self {
        Self {
            nodes: a.nodes + b.nodes,
            work: a.work + b.work,
            impulse: a.impulse + b.impulse,
            friction_work: a.friction_work + b.friction_work,
            cohesive: NodeChange::merge(a.cohesive, b.cohesive),
        }
    }
}

/// The fields' grid data the law reads: velocities (in `grids[f].momentum` after the grid
/// update), masses, mass gradients and nodal particle volumes; the bonded interfaces'
/// node states (when the scene has a cohesive pair) and the step.
pub(crate) struct FieldData<'a, const D: usize> {
    pub grids: &'a mut [Grid<D>],
    pub gradient: &'a [Vec<Vector<D>>],
    pub volume: &'a [Vec<f64>],
    pub laws: &'a FieldLaws,
    pub cohesive: Option<SharedSlice<CohesiveNode<D>>>,
    pub dt: f64,
}

/// Applies the contact laws at every node shared by two or more fields, then the walls and
/// obstacles again to the velocities it changed (at `time`, the end of the step).
pub(crate) fn apply_contact<const D: usize>(
    data: FieldData<'_, D>,
    boundaries: &Boundaries<D>,
    time: f64,
) -> ContactStats {
    const CHUNK: usize = 4096;
    let count = data.grids.len();
    let Some(first) = data.grids.first() else {
        return ContactStats::default();
    };
    let (origin, dx, stride, len) = (first.origin, first.dx, first.stride, first.len());
    let full = dx.powi(D as i32) * (1.0 - GAP_TOLERANCE);
    let mut velocity: [Option<SharedSlice<Vector<D>>>; MAX_CONTACT_FIELDS] =
        [None; MAX_CONTACT_FIELDS];
    for (f, grid) in data.grids.iter_mut().enumerate() {
        velocity[f] = Some(SharedSlice::new(&mut grid.momentum));
    }
    let grids = &*data.grids;
    let (gradient, volume, laws) = (data.gradient, data.volume, data.laws);
    let (cohesive, dt) = (data.cohesive, data.dt);
    ordered_reduce(
        len.div_ceil(CHUNK),
        ContactStats::default,
        |chunk| {
            let mut stats = ContactStats::default();
            let mut m = [0.0; MAX_CONTACT_FIELDS];
            let mut v = [Vector::<D>::zeros(); MAX_CONTACT_FIELDS];
            for i in chunk * CHUNK..((chunk + 1) * CHUNK).min(len) {
                let mut present = 0;
                for f in 0..count {
                    m[f] = grids[f].mass[i];
                    if m[f] > 0.0 {
                        present += 1;
                    }
                }
                if present < 2 {
                    continue;
                }
                let mut total = 0.0;
                let mut momentum = Vector::<D>::zeros();
                let mut grad_sum = Vector::<D>::zeros();
                let mut filled = 0.0;
                for f in (0..count).filter(|&f| m[f] > 0.0) {
                    // SAFETY: chunks are disjoint node ranges; only this task reads node i.
                    v[f] = unsafe { *velocity[f].unwrap_unchecked().get(i) };
                    total += m[f];
                    momentum += v[f] * m[f];
                    grad_sum += gradient[f][i];
                    filled += volume[f][i];
                }
                if present == 2
                    && let Some(nodes) = cohesive
                {
                    let mut fields = (0..count).filter(|&f| m[f] > 0.0);
                    let (a, b) = (fields.next().unwrap_or(0), fields.next().unwrap_or(0));
                    // SAFETY: chunks are disjoint node ranges; only this task touches node i.
                    let node = unsafe { nodes.get(i) };
                    let normal = gradient[a][i] - gradient[b][i];
                    let length = normal.norm();
                    if let Some(law) = laws.cohesive(a, b)
                        && node.pair == [a as u8, b as u8]
                        && length > 0.0
                    {
                        let n = normal / length;
                        if let Some(bond) =
                            bond_impulse(node, &law, [m[a], m[b]], [v[a], v[b]], &n, dt)
                        {
                            let j = bond.impulse;
                            let mut new = if bond.holds {
                                [momentum / total; 2]
                            } else {
                                [v[a] + j / m[a], v[b] - j / m[b]]
                            };
                            for (k, f) in [a, b].into_iter().enumerate() {
                                if !boundaries.is_empty() {
                                    let ijk = node_coords(&stride, i);
                                    let x = node_position(&origin, dx, ijk);
                                    boundaries.apply(ijk, &x, time, m[f], &mut new[k]);
                                }
                                stats.work +=
                                    0.5 * m[f] * (new[k].norm_squared() - v[f].norm_squared());
                                stats.impulse += m[f] * (new[k] - v[f]).norm();
                                // SAFETY: as above.
                                unsafe { *velocity[f].unwrap_unchecked().get(i) = new[k] };
                            }
                            let change = advance(node, &law, new, &bond, &n, dt);
                            stats.cohesive = NodeChange::merge(stats.cohesive, change);
                            stats.nodes += 1;
                            continue;
                        }
                    }
                }
                let v_cm = momentum / total;
                let touching = filled >= full;
                let mut changed = false;
                for f in (0..count).filter(|&f| m[f] > 0.0) {
                    let partner = (0..count)
                        .filter(|&g| g != f)
                        .max_by(|&a, &b| m[a].total_cmp(&m[b]))
                        .unwrap_or(f);
                    let new = match laws.get(f, partner) {
                        FieldLaw::Bonded => v_cm,
                        FieldLaw::Contact(law) => {
                            if !touching {
                                continue;
                            }
                            let normal = gradient[f][i] * 2.0 - grad_sum;
                            let length = normal.norm();
                            if length == 0.0 {
                                continue;
                            }
                            let n = normal / length;
                            let Some(new) = correct(v[f], v_cm, &n, law) else {
                                continue;
                            };
                            if sliding(v[f], v_cm, &n, law) {
                                let change = new - v[f];
                                let slip = (v[f] + new) * 0.5 - v_cm;
                                let tangential = |x: Vector<D>| x - n * x.dot(&n);
                                stats.friction_work +=
                                    m[f] * tangential(change).dot(&tangential(slip));
                            }
                            new
                        }
                    };
                    let mut new = new;
                    if !boundaries.is_empty() {
                        let ijk = node_coords(&stride, i);
                        let x = node_position(&origin, dx, ijk);
                        boundaries.apply(ijk, &x, time, m[f], &mut new);
                    }
                    stats.work += 0.5 * m[f] * (new.norm_squared() - v[f].norm_squared());
                    stats.impulse += m[f] * (new - v[f]).norm();
                    // SAFETY: as above.
                    unsafe { *velocity[f].unwrap_unchecked().get(i) = new };
                    changed = true;
                }
                if changed {
                    stats.nodes += 1;
                }
            }
            stats
        },
        ContactStats::merge,
    )
}

/// Whether Coulomb friction slides (rather than sticks) for a field moving at `v`: only
/// then does friction work against the slip. At stick nodes the tangential velocity the
/// law removes is mostly what the next P2G rebuilds from the particles, not slip (a block
/// at rest on an incline would show work that nothing did).
#[inline]
fn sliding<const D: usize>(v: Vector<D>, v_cm: Vector<D>, n: &Vector<D>, law: ContactLaw) -> bool {
    let ContactLaw::Friction { coefficient } = debonded(law) else {
        return false;
    };
    let relative = v - v_cm;
    let approach = relative.dot(n);
    (relative - n * approach).norm() > coefficient * approach
}

/// The contact law a pair obeys where it is not bonded: a cohesive law's debonded faces
/// are Coulomb contact with its friction coefficient; other laws are themselves.
#[inline]
fn debonded(law: ContactLaw) -> ContactLaw {
    match law {
        ContactLaw::Cohesive(c) => ContactLaw::Friction {
            coefficient: c.friction,
        },
        law => law,
    }
}

/// The corrected velocity of a field moving at `v` against the centre of mass `v_cm`
/// across outward normal `n`, or `None` when the field separates (left free).
#[inline]
fn correct<const D: usize>(
    v: Vector<D>,
    v_cm: Vector<D>,
    n: &Vector<D>,
    law: ContactLaw,
) -> Option<Vector<D>> {
    let relative = v - v_cm;
    let approach = relative.dot(n);
    if approach <= 0.0 {
        return None;
    }
    Some(match debonded(law) {
        ContactLaw::NoSlip | ContactLaw::Cohesive(_) => v_cm,
        ContactLaw::Frictionless => v - n * approach,
        ContactLaw::Friction { coefficient } => {
            let tangential = relative - n * approach;
            let slip = tangential.norm();
            if slip <= coefficient * approach {
                v_cm
            } else {
                v - n * approach - tangential * (coefficient * approach / slip)
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vector;

    fn vec2(x: f64, y: f64) -> Vector<2> {
        Vector::<2>::new(x, y)
    }

    #[test]
    fn separating_fields_are_left_free() {
        let n = vec2(0.0, 1.0);
        assert!(correct(vec2(0.0, -1.0), vec2(0.0, 0.0), &n, ContactLaw::NoSlip).is_none());
    }

    #[test]
    fn frictionless_removes_only_the_normal_approach() {
        let n = vec2(0.0, 1.0);
        let v = correct(vec2(2.0, 1.0), vec2(0.0, 0.0), &n, ContactLaw::Frictionless).unwrap();
        assert_eq!(v, vec2(2.0, 0.0));
    }

    #[test]
    fn coulomb_friction_limits_the_tangential_correction() {
        let n = vec2(0.0, 1.0);
        let law = ContactLaw::Friction { coefficient: 0.5 };
        // Normal correction 1, tangential slip 2: reduced by 0.5 to 1.5.
        let v = correct(vec2(2.0, 1.0), vec2(0.0, 0.0), &n, law).unwrap();
        assert!((v - vec2(1.5, 0.0)).norm() < 1e-15);
        // Slip 0.2 below mu·1: stick at the centre-of-mass velocity.
        let v = correct(vec2(0.2, 1.0), vec2(0.0, 0.0), &n, law).unwrap();
        assert_eq!(v, vec2(0.0, 0.0));
    }
}
