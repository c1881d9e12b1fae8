//! Particles that cross a level boundary: one entering a finer level splits into 2^D
//! children, and 2^D leaving it merge into one, so the particle spacing follows the local
//! level (two particles per element and axis on every level).
//!
//! A split puts the children at the centres of the parent's 2^D sub-cells (offsets ±s/4
//! per axis, s its spacing), each with 1/2^D of its mass and volume, the parent's velocity
//! gradient C and the velocity of its affine field there, v + C·(x_c − x): mass, momentum
//! and the affine velocity field are kept exactly, and a merge of the children gives the
//! parent back. A merge keeps mass, the centre of mass and momentum, and fits C by least
//! squares to the children's velocities about their centre (exact when they sample one
//! affine field), plus their mass-weighted mean C. Intensive state (stress, temperature,
//! cure, damage) is copied to children and averaged over a merge with `merge_weights`.

use crate::math::{Matrix, Vector};

/// The state a split or merge changes: where a particle is, what it carries and its APIC
/// velocity gradient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kinematics<const D: usize> {
    /// Position, m.
    pub position: Vector<D>,
    /// Mass, kg.
    pub mass: f64,
    /// Volume, m^D.
    pub volume: f64,
    /// Velocity, m/s.
    pub velocity: Vector<D>,
    /// APIC velocity gradient C, 1/s.
    pub affine: Matrix<D>,
}

/// The 2^D children of `parent`, whose spacing (its extent along each axis) is `spacing`.
pub fn split<const D: usize>(parent: &Kinematics<D>, spacing: f64, out: &mut Vec<Kinematics<D>>) {
    out.clear();
    let share = 1.0 / f64::from(1u32 << D);
    for c in 0..1usize << D {
        let offset = Vector::<D>::from_fn(|d, _| {
            if (c >> d) & 1 == 1 {
                0.25 * spacing
            } else {
                -0.25 * spacing
            }
        });
        out.push(Kinematics {
            position: parent.position + offset,
            mass: parent.mass * share,
            volume: parent.volume * share,
            velocity: parent.velocity + parent.affine * offset,
            affine: parent.affine,
        });
    }
}

/// Each child's share of a merge's intensive fields: its mass fraction (equal shares
/// without a positive, finite total mass).
pub fn merge_weights<const D: usize>(children: &[Kinematics<D>], out: &mut Vec<f64>) {
    let total: f64 = children.iter().map(|c| c.mass).sum();
    let equal = 1.0 / children.len().max(1) as f64;
    out.clear();
    out.extend(children.iter().map(|c| {
        if total.is_finite() && total > 0.0 {
            c.mass / total
        } else {
            equal
        }
    }));
}

/// One particle from `children`; `None` without a positive, finite total mass.
pub fn merge<const D: usize>(children: &[Kinematics<D>]) -> Option<Kinematics<D>> {
    let mass: f64 = children.iter().map(|c| c.mass).sum();
    if !(mass.is_finite() && mass > 0.0) {
        return None;
    }
    let volume: f64 = children.iter().map(|c| c.volume).sum();
    let position = children
        .iter()
        .map(|c| c.position * c.mass)
        .sum::<Vector<D>>()
        / mass;
    let velocity = children
        .iter()
        .map(|c| c.velocity * c.mass)
        .sum::<Vector<D>>()
        / mass;
    let mean = children
        .iter()
        .map(|c| c.affine * c.mass)
        .sum::<Matrix<D>>()
        / mass;
    // Least squares of the velocities about the centre: C_fit = Σ m δv δxᵀ (Σ m δx δxᵀ)⁻¹;
    // what the mean C already explains is taken out first so both are not counted twice.
    let mut moment = Matrix::<D>::zeros();
    let mut spread = Matrix::<D>::zeros();
    for c in children {
        let dx = c.position - position;
        let dv = c.velocity - velocity - mean * dx;
        moment += dv * dx.transpose() * c.mass;
        spread += dx * dx.transpose() * c.mass;
    }
    let fit = spread
        .try_inverse()
        .map_or(Matrix::<D>::zeros(), |inverse| moment * inverse);
    Some(Kinematics {
        position,
        mass,
        volume,
        velocity,
        affine: mean + fit,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parent() -> Kinematics<3> {
        Kinematics {
            position: Vector::<3>::new(0.3, -0.2, 1.1),
            mass: 2.5,
            volume: 1e-3,
            velocity: Vector::<3>::new(1.0, -2.0, 0.5),
            affine: Matrix::<3>::new(0.4, -1.2, 0.3, 2.0, 0.1, -0.7, 0.5, 0.9, -0.5),
        }
    }

    #[test]
    fn a_split_keeps_mass_momentum_and_the_affine_field_and_merges_back() {
        let p = parent();
        let mut children = Vec::new();
        split(&p, 0.1, &mut children);
        assert_eq!(children.len(), 8);
        let mass: f64 = children.iter().map(|c| c.mass).sum();
        assert!((mass - p.mass).abs() < 1e-15);
        let momentum: Vector<3> = children.iter().map(|c| c.velocity * c.mass).sum();
        assert!((momentum - p.velocity * p.mass).norm() < 1e-14);
        for c in &children {
            let affine = p.velocity + p.affine * (c.position - p.position);
            assert!((c.velocity - affine).norm() < 1e-15);
            assert!(((c.position - p.position).abs() - Vector::<3>::repeat(0.025)).norm() < 1e-15);
        }
        let back = merge(&children).unwrap();
        assert!((back.position - p.position).norm() < 1e-15);
        assert!((back.mass - p.mass).abs() < 1e-15 && (back.volume - p.volume).abs() < 1e-18);
        assert!((back.velocity - p.velocity).norm() < 1e-14);
        assert!((back.affine - p.affine).norm() < 1e-12, "{:?}", back.affine);
    }

    #[test]
    fn a_merge_of_particles_in_one_affine_field_recovers_it() {
        // Children of unequal mass, not on a lattice, with their own C each zero: the fit
        // alone must find the field's gradient.
        let a = Vector::<2>::new(0.2, -0.4);
        let b = Matrix::<2>::new(1.5, -0.3, 0.8, -1.1);
        let points = [
            (0.01, 0.02, 1.0),
            (-0.03, 0.01, 2.0),
            (0.02, -0.025, 0.5),
            (-0.01, -0.015, 1.5),
        ];
        let children: Vec<Kinematics<2>> = points
            .iter()
            .map(|&(x, y, m)| {
                let position = Vector::<2>::new(x, y);
                Kinematics {
                    position,
                    mass: m,
                    volume: m * 1e-3,
                    velocity: a + b * position,
                    affine: Matrix::<2>::zeros(),
                }
            })
            .collect();
        let merged = merge(&children).unwrap();
        assert_eq!(merge::<2>(&[]), None);
        assert!((merged.velocity - (a + b * merged.position)).norm() < 1e-14);
        assert!((merged.affine - b).norm() < 1e-12, "{:?}", merged.affine);
        let mut weights = Vec::new();
        merge_weights(&children, &mut weights);
        assert!((weights.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!((weights[1] - 0.4).abs() < 1e-15);
    }
}
