//! Particle–grid transfers through the THB basis (APIC): P2G scatters mass and affine
//! momentum m_p (v_p + C_p (ξ_i − x_p)) to every function not zero at a particle, ξ_i the
//! function's centre; G2P gathers v_p = Σ w_ip v_i and C_p = Σ v_i ⊗ ∇w_ip. Partition of
//! unity and linear reproduction (thb.rs) make both exact for an affine velocity field on
//! every level and across level boundaries, and keep the total mass and momentum.

use super::{ExtractionCache, RefinementError, ThbBasis, Weight};
use crate::math::{Matrix, Vector};

/// Mass and momentum (then velocity) per active function of a `ThbBasis`.
#[derive(Clone, Debug, Default)]
pub struct LevelGrid<const D: usize> {
    /// Mass per function, kg.
    pub mass: Vec<f64>,
    /// Momentum per function after P2G, kg·m/s; velocity after `normalize`, m/s.
    pub momentum: Vec<Vector<D>>,
}

impl<const D: usize> LevelGrid<D> {
    /// Zeroes the grid, sized to `basis`.
    pub fn clear(&mut self, basis: &ThbBasis<D>) {
        self.mass.clear();
        self.mass.resize(basis.len(), 0.0);
        self.momentum.clear();
        self.momentum.resize(basis.len(), Vector::<D>::zeros());
    }

    /// Turns momentum into velocity where a function has mass (zero elsewhere).
    pub fn normalize(&mut self) {
        for (p, &m) in self.momentum.iter_mut().zip(&self.mass) {
            *p = if m > 0.0 {
                *p / m
            } else {
                Vector::<D>::zeros()
            };
        }
    }
}

/// What the transfers reuse from call to call: the weights of one particle and the
/// extraction of each element (valid for one basis; start a new one for another).
#[derive(Clone, Debug, Default)]
pub struct TransferScratch<const D: usize> {
    weights: Vec<Weight<D>>,
    cache: ExtractionCache<D>,
}

impl<const D: usize> TransferScratch<D> {
    /// The weights at particle `x` (`ThbBasis::evaluate_cached`).
    fn at(&mut self, basis: &ThbBasis<D>, x: &Vector<D>) -> Result<&[Weight<D>], RefinementError> {
        basis.evaluate_cached(&mut self.cache, x, &mut self.weights)?;
        Ok(&self.weights)
    }
}

/// P2G of particles at `position` with `mass`, `velocity` and velocity gradient `affine`
/// into `grid` (cleared first). A particle outside the basis's
/// interior stops it with `Outside` and its index.
pub fn particles_to_grid<const D: usize>(
    basis: &ThbBasis<D>,
    position: &[Vector<D>],
    mass: &[f64],
    velocity: &[Vector<D>],
    affine: &[Matrix<D>],
    grid: &mut LevelGrid<D>,
    scratch: &mut TransferScratch<D>,
) -> Result<(), (usize, RefinementError)> {
    grid.clear(basis);
    for (p, x) in position.iter().enumerate() {
        for w in scratch.at(basis, x).map_err(|e| (p, e))? {
            let i = w.id as usize;
            let offset = basis.center(w.id) - x;
            grid.mass[i] += w.value * mass[p];
            grid.momentum[i] += (velocity[p] + affine[p] * offset) * (w.value * mass[p]);
        }
    }
    Ok(())
}

/// G2P: each particle's velocity and velocity gradient from `grid` (velocities, after
/// `normalize`).
pub fn grid_to_particles<const D: usize>(
    basis: &ThbBasis<D>,
    position: &[Vector<D>],
    grid: &LevelGrid<D>,
    velocity: &mut [Vector<D>],
    affine: &mut [Matrix<D>],
    scratch: &mut TransferScratch<D>,
) -> Result<(), (usize, RefinementError)> {
    for (p, x) in position.iter().enumerate() {
        let mut v = Vector::<D>::zeros();
        let mut c = Matrix::<D>::zeros();
        for w in scratch.at(basis, x).map_err(|e| (p, e))? {
            let vi = grid.momentum[w.id as usize];
            v += vi * w.value;
            c += vi * w.gradient.transpose();
        }
        velocity[p] = v;
        affine[p] = c;
    }
    Ok(())
}

/// The stress's force on each function, f_i = −Σ_p V_p σ_p ∇w_ip, into `force` (sized to
/// the basis and zeroed first).
pub fn internal_forces<const D: usize>(
    basis: &ThbBasis<D>,
    position: &[Vector<D>],
    volume: &[f64],
    stress: &[Matrix<D>],
    force: &mut Vec<Vector<D>>,
    scratch: &mut TransferScratch<D>,
) -> Result<(), (usize, RefinementError)> {
    force.clear();
    force.resize(basis.len(), Vector::<D>::zeros());
    for (p, x) in position.iter().enumerate() {
        for w in scratch.at(basis, x).map_err(|e| (p, e))? {
            force[w.id as usize] -= stress[p] * w.gradient * volume[p];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refinement::Levels;

    /// Particles scattered over a 2D base of 16 × 16 elements of 0.1 with two refined
    /// levels, carrying v = a + B x: P2G keeps mass and momentum, every function with mass
    /// gets a + B ξ_i, and G2P gives back v_p and C_p = B, across the level boundaries.
    #[test]
    fn an_affine_velocity_field_crosses_level_boundaries_exactly() {
        let refine = vec![
            vec![(Vector::<2>::new(0.5, 0.4), Vector::<2>::new(1.1, 1.0))],
            vec![(Vector::<2>::new(0.65, 0.55), Vector::<2>::new(0.9, 1.3))],
        ];
        let basis =
            ThbBasis::new(Levels::new(Vector::<2>::zeros(), 0.1, [16, 16], &refine).unwrap());
        let n = 3000;
        let r = crate::refinement::numbers(12345, 3 * n);
        let position: Vec<Vector<2>> = (0..n)
            .map(|p| Vector::<2>::new(0.2 + 1.2 * r[3 * p], 0.2 + 1.2 * r[3 * p + 1]))
            .collect();
        let mass: Vec<f64> = (0..n).map(|p| 0.5 + r[3 * p + 2]).collect();
        let a = Vector::<2>::new(0.3, -1.2);
        let b = Matrix::<2>::new(0.7, -0.4, 1.1, 0.2);
        let velocity: Vec<Vector<2>> = position.iter().map(|x| a + b * x).collect();
        let affine = vec![b; n];
        let mut grid = LevelGrid::default();
        let mut scratch = TransferScratch::default();
        particles_to_grid(
            &basis,
            &position,
            &mass,
            &velocity,
            &affine,
            &mut grid,
            &mut scratch,
        )
        .unwrap();
        let total: f64 = mass.iter().sum();
        let grid_total: f64 = grid.mass.iter().sum();
        assert!(
            (grid_total / total - 1.0).abs() < 1e-13,
            "mass {grid_total} vs {total}"
        );
        let momentum: Vector<2> = mass.iter().zip(&velocity).map(|(m, v)| v * *m).sum();
        let grid_momentum: Vector<2> = grid.momentum.iter().sum();
        assert!((grid_momentum - momentum).norm() < 1e-10 * momentum.norm());
        grid.normalize();
        let mut levels_with_mass = [false; 3];
        for id in 0..basis.len() as u32 {
            if grid.mass[id as usize] > 0.0 {
                levels_with_mass[basis.function(id).0] = true;
                let exact = a + b * basis.center(id);
                let error = (grid.momentum[id as usize] - exact).norm();
                assert!(error < 1e-12, "function {id}: {error}");
            }
        }
        assert_eq!(levels_with_mass, [true; 3]);
        let mut back = vec![Vector::<2>::zeros(); n];
        let mut gradient = vec![Matrix::<2>::zeros(); n];
        grid_to_particles(
            &basis,
            &position,
            &grid,
            &mut back,
            &mut gradient,
            &mut scratch,
        )
        .unwrap();
        for p in 0..n {
            assert!((back[p] - velocity[p]).norm() < 1e-12, "particle {p}");
            assert!(
                (gradient[p] - b).norm() < 1e-10,
                "particle {p}: {:?}",
                gradient[p]
            );
        }
    }

    /// A uniform stress puts no force on any function whose support the particles cover:
    /// with 2^D particles per element of the finest level at its two-point Gauss points
    /// (exact for the cubic integrands ∂w/∂x_d on an element), across two level boundaries.
    #[test]
    fn a_uniform_stress_puts_no_force_inside_the_particles() {
        let refine = vec![
            vec![(Vector::<2>::new(0.5, 0.4), Vector::<2>::new(1.1, 1.0))],
            vec![(Vector::<2>::new(0.65, 0.55), Vector::<2>::new(0.9, 1.3))],
        ];
        let basis =
            ThbBasis::new(Levels::new(Vector::<2>::zeros(), 0.1, [16, 16], &refine).unwrap());
        let levels = basis.levels();
        let gauss = [0.5 - 0.5 / 3f64.sqrt(), 0.5 + 0.5 / 3f64.sqrt()];
        let (mut position, mut volume) = (Vec::new(), Vec::new());
        // Each base element over [0.2, 1.4)², split into its finest elements.
        for i in 2..14 {
            for j in 2..14 {
                let corner = Vector::<2>::new(i as f64 * 0.1, j as f64 * 0.1);
                let centre = corner + Vector::<2>::repeat(0.05);
                let level = levels.finest_level(&centre).unwrap();
                let h = levels.level_spacing(level);
                let n = 1 << level;
                for a in 0..n * n {
                    let sub = corner + Vector::<2>::new((a / n) as f64, (a % n) as f64) * h;
                    for g in 0..4 {
                        position.push(sub + Vector::<2>::new(gauss[g / 2], gauss[g % 2]) * h);
                        volume.push(0.25 * h * h);
                    }
                }
            }
        }
        let stress = vec![Matrix::<2>::new(3.0, -1.5, -1.5, 2.0); position.len()];
        let mut force = Vec::new();
        internal_forces(
            &basis,
            &position,
            &volume,
            &stress,
            &mut force,
            &mut TransferScratch::default(),
        )
        .unwrap();
        let mut inside = [0usize; 3];
        for id in 0..basis.len() as u32 {
            let (level, j) = basis.function(id);
            let h = levels.level_spacing(level);
            // Support [j h, (j + 3) h] per axis within the particles' [0.2, 1.4].
            let covered = (0..2)
                .all(|d| j[d] as f64 * h >= 0.2 - 1e-12 && (j[d] + 3) as f64 * h <= 1.4 + 1e-12);
            if covered {
                inside[level] += 1;
                let f = force[id as usize].norm();
                assert!(f < 1e-12, "function {id} on level {level}: force {f}");
            }
        }
        assert!(
            inside.iter().all(|&n| n > 0),
            "functions checked per level {inside:?}"
        );
    }

    #[test]
    fn a_particle_off_the_interior_is_named() {
        let none: Vec<Vec<(Vector<1>, Vector<1>)>> = Vec::new();
        let basis = ThbBasis::new(Levels::new(Vector::<1>::zeros(), 0.1, [10], &none).unwrap());
        let position = [Vector::<1>::new(0.5), Vector::<1>::new(0.05)];
        let mut grid = LevelGrid::default();
        let result = particles_to_grid(
            &basis,
            &position,
            &[1.0, 1.0],
            &[Vector::<1>::zeros(); 2],
            &[Matrix::<1>::zeros(); 2],
            &mut grid,
            &mut TransferScratch::default(),
        );
        assert_eq!(result, Err((1, RefinementError::Outside)));
    }
}
