//! The truncated hierarchical quadratic B-spline basis (THB; Giannelli, Jüttler & Speleers
//! 2012, "THB-splines: the truncated basis for hierarchical splines") on `Levels`.
//!
//! A level-ℓ B-spline B^ℓ_j (first knot j along each axis, support j … j+3) is active when
//! its support lies in Ω^ℓ and not in Ω^(ℓ+1). Each active function is truncated by every
//! finer level m: written in level-m B-splines through the two-scale relation
//! B^(m−1)_j = ¼B^m_(2j) + ¾B^m_(2j+1) + ¾B^m_(2j+2) + ¼B^m_(2j+3), it drops the terms whose
//! support lies in Ω^m. The truncated functions sum to one, are non-negative, and keep each
//! level's spline coefficients (a spline of the base level is Σ c_τ τ with c_τ its
//! coefficient on τ's own level), so linear and quadratic fields are reproduced exactly
//! across level boundaries.
//!
//! A point is evaluated on the element of the finest level ℓ* that holds it: every
//! function there is a combination of the 3^D level-ℓ* B-splines on that element, found by
//! refining and truncating the coarser functions level by level down to ℓ* (a multi-level
//! extraction, as D'Angella et al. 2018 do for THB), formed per call by `evaluate` and
//! kept per element by `evaluate_cached` (23× faster inside two levels in 3D).

use super::{Levels, RefinementError};
use crate::math::Vector;

/// Local B-splines on one element: 3^D, at most 27.
const LOCAL: usize = 27;

/// Two-scale coefficients of the quadratic B-spline: B^(m−1)_j = Σ_k W[k] B^m_(2j+k).
const TWO_SCALE: [f64; 4] = [0.25, 0.75, 0.75, 0.25];

/// One basis function's weight and gradient at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Weight<const D: usize> {
    /// The active function's index (`ThbBasis::function`).
    pub id: u32,
    /// Its value at the point.
    pub value: f64,
    /// Its gradient at the point, 1/m.
    pub gradient: Vector<D>,
}

/// The active functions of a grid with levels, numbered coarse level first.
#[derive(Clone, Debug)]
pub struct ThbBasis<const D: usize> {
    levels: Levels<D>,
    /// Per level: the id of the active function with each first knot in the level's
    /// function box (row-major, last axis fastest), `u32::MAX` where none is.
    ids: Vec<Vec<u32>>,
    /// Per active function: its level and first knot.
    functions: Vec<(usize, [i64; D])>,
}

impl<const D: usize> ThbBasis<D> {
    /// The active functions of `levels`.
    pub fn new(levels: Levels<D>) -> Self {
        let mut ids = Vec::with_capacity(levels.len());
        let mut functions = Vec::new();
        for level in 0..levels.len() {
            let shape = function_shape(&levels, level);
            let count: usize = shape.iter().product();
            let mut level_ids = vec![u32::MAX; count];
            for (flat, id) in level_ids.iter_mut().enumerate() {
                let j = unflatten(flat, &shape);
                if levels.support_in(level, &j, level) && !levels.support_in(level, &j, level + 1) {
                    *id = functions.len() as u32;
                    functions.push((level, j));
                }
            }
            ids.push(level_ids);
        }
        Self {
            levels,
            ids,
            functions,
        }
    }

    /// Number of active functions.
    pub fn len(&self) -> usize {
        self.functions.len()
    }

    /// Whether no function is active (a base box under three elements along an axis).
    pub fn is_empty(&self) -> bool {
        self.functions.is_empty()
    }

    /// The levels the basis lives on.
    pub fn levels(&self) -> &Levels<D> {
        &self.levels
    }

    /// Level and first knot of active function `id`.
    pub fn function(&self, id: u32) -> (usize, [i64; D]) {
        self.functions[id as usize]
    }

    /// Centre of active function `id` (its Greville point: the mean of its two inner
    /// knots), where a linear field's coefficient is the field's value, m.
    pub fn center(&self, id: u32) -> Vector<D> {
        let (level, j) = self.function(id);
        let h = self.levels.level_spacing(level);
        Vector::<D>::from_fn(|d, _| self.levels.origin()[d] + (j[d] as f64 + 1.5) * h)
    }

    /// The id of the active level-`level` function with first knot `j`, if it is active.
    pub fn id(&self, level: usize, j: &[i64; D]) -> Option<u32> {
        let shape = function_shape(&self.levels, level);
        if (0..D).any(|d| j[d] < 0 || j[d] as usize >= shape[d]) {
            return None;
        }
        let flat = (0..D).fold(0, |i, d| i * shape[d] + j[d] as usize);
        let id = self.ids[level][flat];
        (id != u32::MAX).then_some(id)
    }

    /// Writes into `out` (cleared first) every function that is not zero at `x`, with its
    /// value and gradient. `Outside` where `x` is not in the base box at least two elements
    /// from its edge (there the base level lacks functions and partition of unity).
    /// Forms the element's extraction anew; `evaluate_cached` keeps it.
    pub fn evaluate(&self, x: &Vector<D>, out: &mut Vec<Weight<D>>) -> Result<(), RefinementError> {
        out.clear();
        let (finest, element) = self.locate(x)?;
        let mut extraction = Vec::new();
        self.extract(finest, &element, &mut extraction);
        let (mut functions, mut terms) = (Vec::new(), Vec::new());
        compress(&extraction, &mut functions, &mut terms);
        self.combine(x, finest, &element, &functions, &terms, out);
        Ok(())
    }

    /// `evaluate` with the extraction of each element kept in `cache` (one per thread),
    /// formed the first time a point falls in the element.
    pub fn evaluate_cached(
        &self,
        cache: &mut ExtractionCache<D>,
        x: &Vector<D>,
        out: &mut Vec<Weight<D>>,
    ) -> Result<(), RefinementError> {
        out.clear();
        self.append_cached(cache, x, out)
    }

    /// `evaluate_cached` appending to `out` instead of clearing it: a pass that keeps
    /// every particle's weights in one buffer (the refined step's P2G, read again by G2P).
    pub fn append_cached(
        &self,
        cache: &mut ExtractionCache<D>,
        x: &Vector<D>,
        out: &mut Vec<Weight<D>>,
    ) -> Result<(), RefinementError> {
        let (finest, element) = self.locate(x)?;
        let (start, len) = match cache.index.get(&(finest, element)) {
            Some(&range) => range,
            None => {
                let mut extraction = std::mem::take(&mut cache.scratch);
                self.extract(finest, &element, &mut extraction);
                let start = cache.functions.len();
                compress(&extraction, &mut cache.functions, &mut cache.terms);
                let range = (start, extraction.len());
                cache.scratch = extraction;
                cache.index.insert((finest, element), range);
                range
            }
        };
        let functions = &cache.functions[start..start + len];
        self.combine(x, finest, &element, functions, &cache.terms, out);
        Ok(())
    }

    /// Whether `evaluate` takes `x` (it lies in the basis's interior).
    pub fn covers(&self, x: &Vector<D>) -> bool {
        self.locate(x).is_ok()
    }

    /// The finest level holding `x` and its element there, or `Outside`.
    fn locate(&self, x: &Vector<D>) -> Result<(usize, [i64; D]), RefinementError> {
        let base = self.levels.element_at(0, x);
        let shape = self.levels.shape(0);
        if (0..D).any(|d| base[d] < 2 || base[d] + 2 >= shape[d] as i64)
            || !x.iter().all(|v| v.is_finite())
        {
            return Err(RefinementError::Outside);
        }
        let finest = self
            .levels
            .finest_level(x)
            .ok_or(RefinementError::Outside)?;
        Ok((finest, self.levels.element_at(finest, x)))
    }

    /// Every function not zero on `element` of level `finest`, as its id and coefficients
    /// on the element's 3^D local B-splines (local index Σ_d a_d·3^(D−1−d), a_d = j_d −
    /// (e_d − 2)), into `carried` (cleared first).
    fn extract(&self, finest: usize, element: &[i64; D], carried: &mut Vec<(u32, [f64; LOCAL])>) {
        carried.clear();
        let local = 3usize.pow(D as u32);
        let mut parent = [0i64; D];
        for level in 0..=finest {
            // The ancestor on this level (elements inside the base box are ≥ 0).
            let here: [i64; D] = std::array::from_fn(|d| element[d] >> (finest - level));
            if level > 0 {
                let child: [i64; D] = std::array::from_fn(|d| here[d] - 2 * parent[d]);
                for (_, coefficients) in carried.iter_mut() {
                    *coefficients = refine::<D>(coefficients, &child);
                }
            }
            parent = here;
            // Truncation: drop the level's B-splines whose support lies in Ω^level (active
            // here, or finer still), then add the active ones.
            for b in 0..local {
                let j = local_knot(&here, b);
                if level > 0 && self.levels.support_in(level, &j, level) {
                    for (_, coefficients) in carried.iter_mut() {
                        coefficients[b] = 0.0;
                    }
                }
            }
            carried.retain(|(_, c)| c[..local].iter().any(|&v| v != 0.0));
            for b in 0..local {
                if let Some(id) = self.id(level, &local_knot(&here, b)) {
                    let mut unit = [0.0; LOCAL];
                    unit[b] = 1.0;
                    carried.push((id, unit));
                }
            }
        }
    }

    /// Values and gradients at `x` of the functions of an element's compressed extraction
    /// (`functions` index into `terms`).
    fn combine(
        &self,
        x: &Vector<D>,
        finest: usize,
        element: &[i64; D],
        functions: &[ExtractedFunction],
        terms: &[(u8, f64)],
        out: &mut Vec<Weight<D>>,
    ) {
        let local = 3usize.pow(D as u32);
        let h = self.levels.level_spacing(finest);
        let mut values = [[0.0; 3]; D];
        let mut slopes = [[0.0; 3]; D];
        for d in 0..D {
            let u = (x[d] - self.levels.origin()[d]) / h - element[d] as f64;
            values[d] = [0.5 * (1.0 - u) * (1.0 - u), 0.5 + u - u * u, 0.5 * u * u];
            slopes[d] = [-(1.0 - u) / h, (1.0 - 2.0 * u) / h, u / h];
        }
        // The element's 3^D local B-splines and their gradients at x, once; each function
        // is then a combination of them.
        let mut local_value = [0.0; LOCAL];
        let mut local_gradient = [Vector::<D>::zeros(); LOCAL];
        for b in 0..local {
            let a = local_digits::<D>(b);
            let mut product = 1.0;
            for d in 0..D {
                product *= values[d][a[d]];
            }
            local_value[b] = product;
            local_gradient[b] = Vector::<D>::from_fn(|g, _| {
                (0..D)
                    .map(|d| {
                        if d == g {
                            slopes[d][a[d]]
                        } else {
                            values[d][a[d]]
                        }
                    })
                    .product()
            });
        }
        for f in functions {
            let own = &terms[f.start as usize..f.start as usize + f.count as usize];
            let (value, gradient) = match own {
                // A function of the element's own level, not truncated there: one local
                // B-spline (most functions, everywhere but near a level boundary).
                &[(b, 1.0)] => (local_value[b as usize], local_gradient[b as usize]),
                _ => own
                    .iter()
                    .fold((0.0, Vector::<D>::zeros()), |(value, gradient), &(b, c)| {
                        (
                            value + c * local_value[b as usize],
                            gradient + local_gradient[b as usize] * c,
                        )
                    }),
            };
            out.push(Weight {
                id: f.id,
                value,
                gradient,
            });
        }
    }
}

/// The extraction of each element a point has fallen in (`ThbBasis::evaluate_cached`):
/// the functions not zero there with their coefficients on its local B-splines.
#[derive(Clone, Debug, Default)]
pub struct ExtractionCache<const D: usize> {
    /// (level, element) → the range of its functions in `functions`.
    index: std::collections::HashMap<(usize, [i64; D]), (usize, usize), KeyHash>,
    functions: Vec<ExtractedFunction>,
    terms: Vec<(u8, f64)>,
    scratch: Vec<(u32, [f64; LOCAL])>,
}

/// One function of an element's extraction: its id and its nonzero coefficients on the
/// element's local B-splines, `terms[start..start + count]` as (local index, coefficient).
#[derive(Clone, Copy, Debug)]
struct ExtractedFunction {
    id: u32,
    start: u32,
    count: u8,
}

/// Appends an element's extraction to `functions` and `terms`, keeping only the nonzero
/// coefficients: a function of the element's own level is then a single term.
fn compress(
    extraction: &[(u32, [f64; LOCAL])],
    functions: &mut Vec<ExtractedFunction>,
    terms: &mut Vec<(u8, f64)>,
) {
    for (id, coefficients) in extraction {
        let start = terms.len() as u32;
        terms.extend(
            (0..LOCAL)
                .filter(|&b| coefficients[b] != 0.0)
                .map(|b| (b as u8, coefficients[b])),
        );
        functions.push(ExtractedFunction {
            id: *id,
            start,
            count: (terms.len() as u32 - start) as u8,
        });
    }
}

impl<const D: usize> ExtractionCache<D> {
    /// Number of elements kept.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Whether no element is kept yet.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }
}

/// A multiplicative hash of the cache's integer keys (the standard SipHash is built to
/// resist crafted keys, which element indices are not, and costs several times more).
#[derive(Clone, Copy, Debug, Default)]
struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, n: u64) {
        self.0 = (self.0.rotate_left(5) ^ n).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }

    fn write_usize(&mut self, n: usize) {
        self.write_u64(n as u64);
    }

    fn write_i64(&mut self, n: i64) {
        self.write_u64(n as u64);
    }
}

/// Builds [`KeyHasher`]s for the cache's map.
type KeyHash = std::hash::BuildHasherDefault<KeyHasher>;

/// First knots per axis of the level's functions: those whose support (three elements)
/// lies in the level's box.
fn function_shape<const D: usize>(levels: &Levels<D>, level: usize) -> [usize; D] {
    let shape = levels.shape(level);
    std::array::from_fn(|d| shape[d].saturating_sub(2))
}

fn unflatten<const D: usize>(mut flat: usize, shape: &[usize; D]) -> [i64; D] {
    let mut j = [0i64; D];
    for d in (0..D).rev() {
        j[d] = (flat % shape[d]) as i64;
        flat /= shape[d];
    }
    j
}

/// Per-axis digits (0, 1, 2) of local index `b`, first axis most significant.
fn local_digits<const D: usize>(mut b: usize) -> [usize; D] {
    let mut a = [0usize; D];
    for d in (0..D).rev() {
        a[d] = b % 3;
        b /= 3;
    }
    a
}

/// First knot of local B-spline `b` on element `e`: e − 2 + digit, per axis.
fn local_knot<const D: usize>(e: &[i64; D], b: usize) -> [i64; D] {
    let a = local_digits::<D>(b);
    std::array::from_fn(|d| e[d] - 2 + a[d] as i64)
}

/// Coefficients on a child element's local B-splines from those on its parent's; `child`
/// is the child's offset (0 or 1) per axis. Fine b (knot k = 2e + s − 2 + b) takes
/// W[k − 2j] of coarse a (knot j = e − 2 + a), where 0 ≤ k − 2j ≤ 3.
fn refine<const D: usize>(coarse: &[f64; LOCAL], child: &[i64; D]) -> [f64; LOCAL] {
    let local = 3usize.pow(D as u32);
    // Per axis: factor[d][b][a].
    let mut factor = [[[0.0; 3]; 3]; D];
    for d in 0..D {
        for (b, row) in factor[d].iter_mut().enumerate() {
            for (a, f) in row.iter_mut().enumerate() {
                let k = child[d] + 2 + b as i64 - 2 * a as i64;
                if (0..4).contains(&k) {
                    *f = TWO_SCALE[k as usize];
                }
            }
        }
    }
    let mut fine = [0.0; LOCAL];
    for (b, out) in fine.iter_mut().enumerate().take(local) {
        let fb = local_digits::<D>(b);
        let mut sum = 0.0;
        for (a, &c) in coarse.iter().enumerate().take(local) {
            if c == 0.0 {
                continue;
            }
            let ca = local_digits::<D>(a);
            let mut w = c;
            for d in 0..D {
                w *= factor[d][fb[d]][ca[d]];
            }
            sum += w;
        }
        *out = sum;
    }
    fine
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two levels above a base of 16 elements of 0.1 per axis: level 1 over a box off the
    /// middle, level 2 over a smaller one that crosses level 1's edge (so it is cut).
    fn basis<const D: usize>() -> ThbBasis<D> {
        let refine = vec![
            vec![(Vector::<D>::repeat(0.52), Vector::<D>::repeat(1.07))],
            vec![(Vector::<D>::repeat(0.61), Vector::<D>::repeat(1.3))],
        ];
        ThbBasis::new(Levels::new(Vector::<D>::zeros(), 0.1, [16; D], &refine).unwrap())
    }

    /// Points inside the base box, two elements from its edge, with some on level
    /// boundaries and knots.
    fn points<const D: usize>(n: usize) -> Vec<Vector<D>> {
        let r = crate::refinement::numbers(D as u64, n * D);
        let mut p: Vec<Vector<D>> = (0..n)
            .map(|i| Vector::<D>::from_fn(|d, _| 0.2 + 1.2 * r[i * D + d]))
            .collect();
        p.push(Vector::<D>::repeat(0.5));
        p.push(Vector::<D>::repeat(0.6));
        p.push(Vector::<D>::repeat(1.1));
        p.push(Vector::<D>::repeat(0.8));
        p
    }

    fn check<const D: usize>() {
        let basis = basis::<D>();
        let levels: Vec<usize> = (0..basis.len() as u32)
            .map(|i| basis.function(i).0)
            .collect();
        for level in 0..3 {
            assert!(
                levels.contains(&level),
                "no active function on level {level}"
            );
        }
        let mut out = Vec::new();
        let mut seen = [false; 3];
        let mut cache = ExtractionCache::default();
        let mut cached = Vec::new();
        for x in points::<D>(400) {
            basis.evaluate(&x, &mut out).unwrap();
            basis.evaluate_cached(&mut cache, &x, &mut cached).unwrap();
            assert_eq!(out, cached, "cached extraction at {x:?}");
            seen[basis.levels().finest_level(&x).unwrap()] = true;
            let sum: f64 = out.iter().map(|w| w.value).sum();
            assert!(
                (sum - 1.0).abs() < 1e-12,
                "partition of unity at {x:?}: {sum}"
            );
            let mut linear = Vector::<D>::zeros();
            let mut gradient = crate::math::Matrix::<D>::zeros();
            let mut slope = Vector::<D>::zeros();
            let mut square = 0.0;
            for w in &out {
                assert!(w.value >= -1e-15, "negative weight {} at {x:?}", w.value);
                let c = basis.center(w.id);
                let h = basis.levels().level_spacing(basis.function(w.id).0);
                linear += c * w.value;
                gradient += c * w.gradient.transpose();
                slope += w.gradient;
                // x_0² has coefficient ξ² − h²/4 on each level (the blossom at the inner
                // knots ξ ± h/2), so it checks the truncation keeps each level's
                // coefficients.
                square += (c[0] * c[0] - 0.25 * h * h) * w.value;
            }
            assert!(
                (linear - x).norm() < 1e-12,
                "linear field at {x:?}: {linear:?}"
            );
            let identity = crate::math::Matrix::<D>::identity();
            assert!(
                (gradient - identity).norm() < 1e-9,
                "gradient of x at {x:?}: {gradient:?}"
            );
            assert!(slope.norm() < 1e-9, "gradients sum to {slope:?} at {x:?}");
            assert!(
                (square - x[0] * x[0]).abs() < 1e-12,
                "x² at {x:?}: {square}"
            );
        }
        assert_eq!(seen, [true; 3], "points on every level");
        assert!(!cache.is_empty());
    }

    #[test]
    fn partition_of_unity_and_reproduction_across_levels_1d() {
        check::<1>();
    }

    #[test]
    fn partition_of_unity_and_reproduction_across_levels_2d() {
        check::<2>();
    }

    #[test]
    fn partition_of_unity_and_reproduction_across_levels_3d() {
        check::<3>();
    }

    #[test]
    fn without_refinement_the_basis_is_the_quadratic_b_spline() {
        let none: Vec<Vec<(Vector<2>, Vector<2>)>> = Vec::new();
        let basis = ThbBasis::new(Levels::new(Vector::<2>::zeros(), 0.5, [8, 8], &none).unwrap());
        assert_eq!(basis.len(), 36);
        let mut out = Vec::new();
        let x = Vector::<2>::new(1.7, 2.2);
        basis.evaluate(&x, &mut out).unwrap();
        assert_eq!(out.len(), 9);
        let b = |r: f64| {
            let r = r.abs();
            if r < 0.5 {
                0.75 - r * r
            } else if r < 1.5 {
                0.5 * (1.5 - r) * (1.5 - r)
            } else {
                0.0
            }
        };
        for w in &out {
            let c = basis.center(w.id);
            let expected = b((x[0] - c[0]) / 0.5) * b((x[1] - c[1]) / 0.5);
            assert!(
                (w.value - expected).abs() < 1e-14,
                "{} vs {expected}",
                w.value
            );
        }
    }

    #[test]
    fn on_a_solver_grid_level_0_is_the_bspline2_kernel_of_its_nodes() {
        use crate::kernels::{Kernel, QuadraticBSpline};
        let (min, dx) = (Vector::<2>::new(-0.3, 0.1), 0.05);
        let none: Vec<Vec<(Vector<2>, Vector<2>)>> = Vec::new();
        let basis = ThbBasis::new(Levels::for_grid(min, dx, [10, 12], &none).unwrap());
        assert_eq!(basis.len(), 11 * 13);
        let mut out = Vec::new();
        for x in [
            Vector::<2>::new(-0.27, 0.13),
            Vector::<2>::new(-0.01, 0.3),
            Vector::<2>::new(0.17, 0.67),
        ] {
            basis.evaluate(&x, &mut out).unwrap();
            let axes: Vec<_> = (0..2)
                .map(|d| QuadraticBSpline::weights((x[d] - min[d]) / dx, 0.0))
                .collect();
            assert_eq!(out.len(), 9);
            for w in &out {
                let (level, j) = basis.function(w.id);
                assert_eq!(level, 0);
                let mut expected = 1.0;
                for d in 0..2 {
                    let k = (j[d] - axes[d].base as i64) as usize;
                    assert!(k < 3, "node {j:?} outside the kernel's stencil at {x:?}");
                    expected *= axes[d].w[k];
                }
                assert!(
                    (w.value - expected).abs() < 1e-14,
                    "{} vs {expected}",
                    w.value
                );
            }
        }
        // Closer than half a cell to a face, the kernel would reach node −1.
        assert_eq!(
            basis.evaluate(&Vector::<2>::new(-0.28, 0.3), &mut out),
            Err(RefinementError::Outside)
        );
    }

    #[test]
    fn points_off_the_interior_are_refused() {
        let basis = basis::<2>();
        let mut out = Vec::new();
        for x in [
            Vector::<2>::new(0.1, 0.8),
            Vector::<2>::new(0.8, 1.55),
            Vector::<2>::new(f64::NAN, 0.8),
        ] {
            assert_eq!(basis.evaluate(&x, &mut out), Err(RefinementError::Outside));
        }
    }
}
