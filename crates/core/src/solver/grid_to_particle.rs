//! G2P: gather grid velocities back to particles (PIC, FLIP/PIC blend or APIC), move them,
//! and update the deformation gradient from the velocity gradient.

use super::parallel::{SharedSlice, chunk_count, chunk_range, ordered_reduce};
use super::separable::gather;
use super::stats::{KinematicStats, ParticleFault};
use super::stencil::{Stencil, stencil_fits};
use crate::grid::Grid;
use crate::kernels::Kernel;
use crate::math::{Matrix, Vector, determinant, inverse};
use crate::particles::Particles;
use crate::scene::Transfer;

/// What one G2P pass updates.
#[derive(Clone, Copy, Debug)]
pub(crate) struct G2pParams<const D: usize> {
    pub dt: f64,
    pub transfer: Transfer,
    pub flip_blend: f64,
    /// Update particle velocities (and APIC affine matrices).
    pub velocity: bool,
    /// Move particles with the grid velocity.
    pub position: bool,
    /// Update F from the velocity gradient.
    pub deformation: bool,
    /// Use the APIC matrix C as the velocity gradient (MLS-MPM).
    pub gradient_from_affine: bool,
    pub gravity: Vector<D>,
}

/// Gathers from the grid and updates particles; returns the kinematic statistics. With
/// contact `fields` (empty otherwise), each particle gathers from its own field's grid.
pub(crate) fn grid_to_particle<const D: usize, K: Kernel>(
    grid: &Grid<D>,
    fields: &[Grid<D>],
    particles: &mut Particles<D>,
    params: G2pParams<D>,
) -> KinematicStats<D> {
    let n = particles.len();
    let dt = params.dt;
    let inv_dx = grid.inv_dx;
    let apic = params.transfer == Transfer::Apic;
    let flip = params.transfer == Transfer::Flip;
    // XPIC adds the gathered correction v* − vⁿ (`grid.xpic_velocity`) to the PIC velocity.
    let xpic = params.transfer == Transfer::Xpic && params.velocity;
    let store_gradient = !particles.velocity_gradient.is_empty();
    // Particles held in place (solids in incompressible mechanics) keep their state; they
    // count in the statistics as they are.
    let held = particles.any_held().then_some(&particles.groups[..]);
    let Particles {
        position,
        velocity,
        mass,
        deformation_gradient,
        affine,
        velocity_gradient,
        half_size,
        contact_field,
        external_force,
        ..
    } = particles;
    let (mass, half_size, contact_field) = (&*mass, &*half_size, &*contact_field);
    let loads = (!external_force.is_empty()).then_some(&*external_force);
    let position = SharedSlice::new(position);
    let velocity = SharedSlice::new(velocity);
    let deformation = SharedSlice::new(deformation_gradient);
    let affine = SharedSlice::new(affine);
    let gradient_out = SharedSlice::new(velocity_gradient);
    let identity = Matrix::<D>::identity();

    ordered_reduce(
        chunk_count(n),
        KinematicStats::default,
        |chunk| {
            let range = chunk_range(chunk, n);
            let mut stats = KinematicStats::<D>::default();
            for p in range {
                // SAFETY: chunks are disjoint particle ranges; each particle is touched by
                // exactly one task.
                let (x, v, f) = unsafe { (position.get(p), velocity.get(p), deformation.get(p)) };
                // A particle without mass (one waiting at an inlet, or gone through an
                // outlet: incompressible/inflow.rs) carries nothing: it neither moves nor
                // counts. Gathered, it read the velocity of nodes that only a far particle's
                // stencil reaches, and a spurious speed there stopped the run.
                if mass[p] == 0.0 {
                    continue;
                }
                if held.is_some_and(|groups| crate::particles::held_in(groups, p)) {
                    stats.record(p, mass[p], v, x, f, (&params.gravity, loads.map(|l| &l[p])));
                    continue;
                }
                let half = if K::USES_PARTICLE_SIZE {
                    half_size[p]
                } else {
                    0.0
                };
                let stencil = Stencil::<D>::new::<K>(grid, x, half);
                let source = if fields.is_empty() {
                    grid
                } else {
                    &fields[contact_field[p] as usize]
                };
                let need_b = apic && (params.velocity || params.gradient_from_affine);
                let need_grad = params.deformation && !params.gradient_from_affine;
                let mut v_pic = Vector::<D>::zeros();
                let mut v_flip_change = Vector::<D>::zeros();
                let mut b = Matrix::<D>::zeros();
                let mut inertia = Matrix::<D>::zeros();
                let mut grad = Matrix::<D>::zeros();
                if !flip && !xpic && (K::APIC_INERTIA.is_some() || !need_b) {
                    // The tensor-product gather (constant APIC inertia, no FLIP change).
                    let g =
                        gather::<D, K>(&stencil, &grid.stride, &source.momentum, need_b, need_grad);
                    (v_pic, b, grad) = (g.velocity, g.affine, g.gradient);
                } else {
                    stencil.for_each::<K>(&grid.stride, |i, w, dw, dpos| {
                        let vi = source.momentum[i];
                        v_pic += vi * w;
                        if need_b {
                            b += (vi * w) * dpos.transpose();
                            if K::APIC_INERTIA.is_none() {
                                inertia += (dpos * w) * dpos.transpose();
                            }
                        }
                        if need_grad {
                            grad += vi * dw.transpose();
                        }
                        if flip && params.velocity {
                            v_flip_change += (vi - source.velocity_old[i]) * w;
                        }
                        if xpic {
                            v_flip_change += source.xpic_velocity[i] * w;
                        }
                    });
                }
                // Affine matrix C = B·D⁻¹ (offsets in cells, so divide by dx once).
                let c = if need_b {
                    match K::APIC_INERTIA {
                        Some(coef) => b * (inv_dx / coef),
                        None => {
                            inverse(&inertia).map_or(Matrix::<D>::zeros(), |di| b * di * inv_dx)
                        }
                    }
                } else {
                    Matrix::<D>::zeros()
                };
                if params.velocity {
                    match params.transfer {
                        Transfer::Pic => *v = v_pic,
                        Transfer::Apic => {
                            *v = v_pic;
                            // SAFETY: as above.
                            unsafe { *affine.get(p) = c };
                        }
                        Transfer::Flip => {
                            let a = params.flip_blend;
                            *v = (*v + v_flip_change) * a + v_pic * (1.0 - a);
                        }
                        Transfer::Xpic => *v = v_pic + v_flip_change,
                    }
                }
                if params.position {
                    *x += v_pic * dt;
                }
                if params.deformation {
                    let l = if params.gradient_from_affine {
                        c
                    } else {
                        grad * inv_dx
                    };
                    *f = (identity + l * dt) * *f;
                    if store_gradient {
                        // SAFETY: as above.
                        unsafe { *gradient_out.get(p) = l };
                    }
                }
                // Statistics and checks.
                stats.record(p, mass[p], v, x, f, (&params.gravity, loads.map(|l| &l[p])));
                if params.position
                    && stats.escaped.is_none()
                    && !stencil_fits::<D, K>(grid, x, half)
                {
                    stats.escaped = Some(ParticleFault {
                        particle: p,
                        field: "x",
                        value: x.norm(),
                    });
                }
            }
            stats.max_speed = stats.max_speed.sqrt();
            stats
        },
        KinematicStats::merge,
    )
}

/// Kinematic statistics of the current particle state without changing it.
pub(crate) fn measure<const D: usize>(
    particles: &Particles<D>,
    gravity: Vector<D>,
) -> KinematicStats<D> {
    let mut stats = KinematicStats::<D>::default();
    for p in 0..particles.len() {
        let (m, v, x) = (
            particles.mass[p],
            particles.velocity[p],
            particles.position[p],
        );
        stats.kinetic_energy += 0.5 * m * v.norm_squared();
        stats.momentum += v * m;
        stats.gravity_energy -= m * gravity.dot(&x);
        if let Some(load) = particles.external_force.get(p) {
            stats.gravity_energy -= load.dot(&x);
        }
        stats.max_speed = stats.max_speed.max(v.norm());
        let det = determinant(&particles.deformation_gradient[p]);
        if det < stats.min_det_f {
            stats.min_det_f = det;
            stats.min_det_particle = p;
        }
    }
    stats
}
