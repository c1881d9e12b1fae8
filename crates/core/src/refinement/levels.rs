//! The nested regions of a grid with levels. Level ℓ has knots at origin + k·h/2^ℓ along
//! every axis and elements (knot spans) between them; level 0 covers its whole box of
//! elements, and each finer level ℓ covers a region Ω^ℓ ⊆ Ω^(ℓ−1) that is a union of
//! level-(ℓ−1) elements (each splits into 2^D of level ℓ), as THB-splines require.

use super::RefinementError;
use crate::kernels::fast_floor;
use crate::math::Vector;

/// Most refined levels above the base one.
pub const MAX_LEVELS: usize = 8;

/// Most elements a level may hold (its region mask is dense over the level's box).
pub const MAX_ELEMENTS: usize = 1 << 26;

/// The levels' geometry and regions: which elements of each level lie in Ω^ℓ.
#[derive(Clone, Debug)]
pub struct Levels<const D: usize> {
    origin: Vector<D>,
    spacing: f64,
    /// Level-0 elements per axis.
    elements: [usize; D],
    /// Per level: whether each element of the level's box (row-major, last axis fastest)
    /// lies in Ω^ℓ. Level 0's are all true.
    regions: Vec<Vec<bool>>,
}

impl<const D: usize> Levels<D> {
    /// Level 0 with its first knot at `origin`, knot spacing `spacing` and `elements` spans
    /// per axis; `refine[ℓ − 1]` lists the boxes (min, max corners) whose union is Ω^ℓ.
    /// Each box grows outward to the level-(ℓ−1) knots around it, is cut to the base box
    /// and to Ω^(ℓ−1), so the regions nest and are unions of coarser elements.
    pub fn new(
        origin: Vector<D>,
        spacing: f64,
        elements: [usize; D],
        refine: &[Vec<(Vector<D>, Vector<D>)>],
    ) -> Result<Self, RefinementError> {
        if !origin.iter().all(|x| x.is_finite()) {
            return Err(RefinementError::Base("origin"));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(RefinementError::Base("spacing"));
        }
        if refine.len() > MAX_LEVELS {
            return Err(RefinementError::TooManyLevels(refine.len()));
        }
        let mut levels = Self {
            origin,
            spacing,
            elements,
            regions: Vec::with_capacity(refine.len() + 1),
        };
        for level in 0..=refine.len() {
            let count = (0..D).fold(1u128, |n, d| n * ((elements[d] as u128) << level));
            if count == 0 || count > MAX_ELEMENTS as u128 {
                return Err(RefinementError::Elements {
                    level,
                    elements: count,
                    max: MAX_ELEMENTS,
                });
            }
        }
        levels
            .regions
            .push(vec![true; elements.iter().product::<usize>()]);
        for (k, boxes) in refine.iter().enumerate() {
            let level = k + 1;
            let mut region = vec![false; levels.element_count(level)];
            for (index, (min, max)) in boxes.iter().enumerate() {
                let bad =
                    (0..D).any(|d| !(min[d].is_finite() && max[d].is_finite()) || min[d] > max[d]);
                if bad {
                    return Err(RefinementError::Box { level, index });
                }
                levels.mark(level, min, max, &mut region);
            }
            levels.regions.push(region);
        }
        Ok(levels)
    }

    /// The levels over a solver grid with nodes at `min` + i·`dx`, i = 0 … `cells` per
    /// axis: origin `min` − 1.5·`dx` and `cells` + 3 elements, so level-0 function j is
    /// the quadratic B-spline of node j (the `bspline2` kernel's). The basis then covers
    /// points from half a cell inside the grid's faces (`ThbBasis::evaluate`).
    pub fn for_grid(
        min: Vector<D>,
        dx: f64,
        cells: [usize; D],
        refine: &[Vec<(Vector<D>, Vector<D>)>],
    ) -> Result<Self, RefinementError> {
        let elements = std::array::from_fn(|d| cells[d] + 3);
        Self::new(min - Vector::<D>::repeat(1.5 * dx), dx, elements, refine)
    }

    /// Marks in `region` (level `level`) the children of the level-(ℓ−1) elements in Ω^(ℓ−1)
    /// that the box touches.
    fn mark(&self, level: usize, min: &Vector<D>, max: &Vector<D>, region: &mut [bool]) {
        let coarse = level - 1;
        let h = self.level_spacing(coarse);
        let shape = self.shape(coarse);
        let mut lo = [0i64; D];
        let mut hi = [0i64; D];
        for d in 0..D {
            // A face within 1e-9 of an element of a knot is on it (0.3/0.1 is 2.9999…).
            let a = ((min[d] - self.origin[d]) / h + 1e-9).floor();
            let b = ((max[d] - self.origin[d]) / h - 1e-9).ceil();
            let n = shape[d] as f64;
            lo[d] = a.clamp(0.0, n) as i64;
            hi[d] = b.clamp(0.0, n) as i64;
            if hi[d] == lo[d] {
                return;
            }
        }
        let mut e = lo;
        loop {
            if self.in_region(coarse, &e) {
                for c in 0..1usize << D {
                    let child: [usize; D] =
                        std::array::from_fn(|d| 2 * e[d] as usize + ((c >> d) & 1));
                    region[self.flat(level, &child)] = true;
                }
            }
            if !next(&mut e, &lo, &hi) {
                break;
            }
        }
    }

    /// Number of levels, the base one included.
    pub fn len(&self) -> usize {
        self.regions.len()
    }

    /// Whether there is no level (never: level 0 always exists).
    pub fn is_empty(&self) -> bool {
        self.regions.is_empty()
    }

    /// The first knot of every level, m.
    pub fn origin(&self) -> &Vector<D> {
        &self.origin
    }

    /// Knot spacing of level `level`, h/2^ℓ, m.
    pub fn level_spacing(&self, level: usize) -> f64 {
        self.spacing / f64::from(1u32 << level)
    }

    /// Elements per axis of level `level`'s box.
    pub fn shape(&self, level: usize) -> [usize; D] {
        std::array::from_fn(|d| self.elements[d] << level)
    }

    /// Elements in level `level`'s box.
    pub fn element_count(&self, level: usize) -> usize {
        self.shape(level).iter().product()
    }

    /// Elements of level `level` in its region Ω^ℓ (0 for a level that is not there).
    pub fn region_len(&self, level: usize) -> usize {
        self.regions
            .get(level)
            .map_or(0, |r| r.iter().filter(|&&inside| inside).count())
    }

    /// Row-major index (last axis fastest) of element `e` in level `level`'s box.
    fn flat(&self, level: usize, e: &[usize; D]) -> usize {
        let shape = self.shape(level);
        (0..D).fold(0, |i, d| i * shape[d] + e[d])
    }

    /// Whether element `e` (signed, so callers can ask beyond the box) of level `level`
    /// lies in Ω^ℓ; false outside the box and for levels that are not there.
    pub fn in_region(&self, level: usize, e: &[i64; D]) -> bool {
        if level >= self.regions.len() {
            return false;
        }
        let shape = self.shape(level);
        if (0..D).any(|d| e[d] < 0 || e[d] as usize >= shape[d]) {
            return false;
        }
        let e: [usize; D] = std::array::from_fn(|d| e[d] as usize);
        self.regions[level][self.flat(level, &e)]
    }

    /// The level-`level` element holding `x` (it may lie beyond the box).
    pub fn element_at(&self, level: usize, x: &Vector<D>) -> [i64; D] {
        let h = self.level_spacing(level);
        std::array::from_fn(|d| fast_floor((x[d] - self.origin[d]) / h) as i64)
    }

    /// The finest level whose region holds `x`, or `None` outside the base box.
    pub fn finest_level(&self, x: &Vector<D>) -> Option<usize> {
        (0..self.regions.len())
            .rev()
            .find(|&level| self.in_region(level, &self.element_at(level, x)))
    }

    /// Whether the support of the level-`level` quadratic B-spline with first knot `j` (the
    /// elements j … j+2 along each axis) lies in Ω^`target` (`target` ≥ `level`; the
    /// elements split into those of `target`).
    pub fn support_in(&self, level: usize, j: &[i64; D], target: usize) -> bool {
        if target >= self.regions.len() {
            return false;
        }
        let scale = 1i64 << (target - level);
        let lo: [i64; D] = std::array::from_fn(|d| j[d] * scale);
        let hi: [i64; D] = std::array::from_fn(|d| (j[d] + 3) * scale);
        let mut e = lo;
        loop {
            if !self.in_region(target, &e) {
                return false;
            }
            if !next(&mut e, &lo, &hi) {
                return true;
            }
        }
    }
}

/// Steps `e` through the box [lo, hi) (last axis fastest); false once past its end.
fn next<const D: usize>(e: &mut [i64; D], lo: &[i64; D], hi: &[i64; D]) -> bool {
    for d in (0..D).rev() {
        e[d] += 1;
        if e[d] < hi[d] {
            return true;
        }
        e[d] = lo[d];
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_nest_and_snap_to_coarser_elements() {
        // Spacing 0.1: level 1 over x in [0.3, 0.6] is level-0 elements 3..6, so level-1
        // elements 6..12; level 2 asked over the whole box is cut to level 1's region.
        let refine = vec![
            vec![(Vector::<1>::new(0.3), Vector::<1>::new(0.6))],
            vec![(Vector::<1>::new(0.0), Vector::<1>::new(1.0))],
        ];
        let levels = Levels::new(Vector::<1>::new(0.0), 0.1, [10], &refine).unwrap();
        assert_eq!(levels.len(), 3);
        let l1: Vec<i64> = (0..20).filter(|&e| levels.in_region(1, &[e])).collect();
        assert_eq!(l1, (6..12).collect::<Vec<_>>());
        let l2: Vec<i64> = (0..40).filter(|&e| levels.in_region(2, &[e])).collect();
        assert_eq!(l2, (12..24).collect::<Vec<_>>());
        assert_eq!(levels.finest_level(&Vector::<1>::new(0.45)), Some(2));
        assert_eq!(levels.finest_level(&Vector::<1>::new(0.05)), Some(0));
        assert_eq!(levels.finest_level(&Vector::<1>::new(-0.05)), None);
    }

    #[test]
    fn bad_geometry_is_refused() {
        let none: Vec<Vec<(Vector<2>, Vector<2>)>> = Vec::new();
        assert_eq!(
            Levels::new(Vector::<2>::zeros(), 0.0, [4, 4], &none).unwrap_err(),
            RefinementError::Base("spacing")
        );
        assert!(matches!(
            Levels::new(Vector::<2>::zeros(), 1.0, [0, 4], &none),
            Err(RefinementError::Elements { level: 0, .. })
        ));
        let inverted = vec![vec![(
            Vector::<2>::new(1.0, 1.0),
            Vector::<2>::new(0.0, 2.0),
        )]];
        assert_eq!(
            Levels::new(Vector::<2>::zeros(), 1.0, [4, 4], &inverted).unwrap_err(),
            RefinementError::Box { level: 1, index: 0 }
        );
        let deep = vec![vec![]; MAX_LEVELS + 1];
        assert_eq!(
            Levels::new(Vector::<2>::zeros(), 1.0, [4, 4], &deep).unwrap_err(),
            RefinementError::TooManyLevels(MAX_LEVELS + 1)
        );
        let huge = vec![vec![]; 8];
        assert!(matches!(
            Levels::new(Vector::<2>::zeros(), 1.0, [1 << 12, 1 << 12], &huge),
            Err(RefinementError::Elements { .. })
        ));
    }
}
