//! Particle lattices that fill the bodies' shapes. Only the lattice points inside a region
//! (the shape's bounding box within the domain) are visited, so the work and memory of a
//! body are what [`super::budget`] estimated before anything was allocated.

use super::BodyParticles;
use super::Shape;

/// Per-axis bounds where particles may lie (unused axes of a 2D scene are ignored).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Region {
    /// Lower bound on each axis.
    pub lo: [f64; 3],
    /// Upper bound on each axis.
    pub hi: [f64; 3],
}

impl Region {
    /// The intersection of two regions.
    pub fn intersect(&self, other: &Region) -> Region {
        let mut r = *self;
        for a in 0..3 {
            r.lo[a] = r.lo[a].max(other.lo[a]);
            r.hi[a] = r.hi[a].min(other.hi[a]);
        }
        r
    }
}

/// Most lattice spacings a shape may span on one axis: beyond this, lattice indices lose
/// their precision in f64 (and no grid could hold the particles anyway).
pub(crate) const MAX_SPACINGS: f64 = 1e12;

/// The axis-aligned bounding box of a box, sphere or cylinder (`None` for a file or an
/// inflow, which check their own extent).
pub(crate) fn bounding_box(dim: usize, shape: &Shape) -> Option<Region> {
    let mut r = Region {
        lo: [0.0; 3],
        hi: [0.0; 3],
    };
    match shape {
        Shape::Box { min, max } => {
            r.lo[..dim].copy_from_slice(&min[..dim]);
            r.hi[..dim].copy_from_slice(&max[..dim]);
        }
        Shape::Sphere { center, radius } => {
            for (a, c) in center.iter().take(dim).enumerate() {
                r.lo[a] = c - radius;
                r.hi[a] = c + radius;
            }
        }
        Shape::Cylinder {
            center,
            radius,
            axis,
            length,
        } => {
            let norm = axis.iter().map(|x| x * x).sum::<f64>().sqrt();
            for a in 0..dim {
                let c = axis[a] / norm;
                let reach = c.abs() * length / 2.0 + radius * (1.0 - c * c).max(0.0).sqrt();
                r.lo[a] = center[a] - reach;
                r.hi[a] = center[a] + reach;
            }
        }
        Shape::File { .. } | Shape::Inflow(_) => return None,
    }
    Some(r)
}

/// Indices `i` in `[first, end)` whose point `base + (i + offset)·step` may lie in
/// `[lo, hi]`, widened by one on each side (the caller tests each point exactly).
fn span(base: f64, offset: f64, step: f64, lo: f64, hi: f64, first: i64, end: i64) -> (i64, i64) {
    let a = (((lo - base) / step - offset).floor() - 1.0).max(first as f64);
    let b = (((hi - base) / step - offset).ceil() + 2.0).min(end as f64);
    if a < b {
        (a as i64, b as i64)
    } else {
        (first, first)
    }
}

/// A box's lattice, fitted exactly to the box: `counts` points per axis at
/// `min + (i + 0.5)·step`, of which `ranges` fall in the region.
pub(crate) struct BoxLattice {
    step: [f64; 3],
    ranges: [(i64, i64); 3],
    volume: f64,
}

impl BoxLattice {
    /// The lattice of spacing about `h` fitted to the box `[min, max]`, restricted to
    /// `region`; `None` when the box is thinner than half a spacing on some axis.
    pub fn new(dim: usize, min: &[f64], max: &[f64], h: f64, region: &Region) -> Option<Self> {
        let mut step = [0.0; 3];
        let mut ranges = [(0i64, 1i64); 3];
        let mut volume = 1.0;
        for a in 0..dim {
            let len = max[a] - min[a];
            let count = (len / h).round().min(MAX_SPACINGS);
            // NaN (a malformed box) counts as empty, like a box thinner than half a spacing.
            if count.is_nan() || count < 1.0 {
                return None;
            }
            step[a] = len / count;
            volume *= step[a];
            ranges[a] = span(
                min[a],
                0.5,
                step[a],
                region.lo[a],
                region.hi[a],
                0,
                count as i64,
            );
        }
        Some(Self {
            step,
            ranges,
            volume,
        })
    }

    /// Lattice points visited (in the region).
    pub fn points(&self) -> f64 {
        self.ranges.iter().map(|(a, b)| (b - a) as f64).product()
    }
}

/// A lattice of spacing `h` centred on `center` (offset by `offset` spacings), visited over
/// `bounds`: the shape's bounding box within the region.
pub(crate) struct CentredLattice {
    ranges: [(i64, i64); 3],
}

impl CentredLattice {
    /// The lattice points within `reach` of `center` that may lie in `bounds`.
    pub fn new(
        dim: usize,
        center: &[f64],
        reach: f64,
        h: f64,
        offset: [f64; 3],
        bounds: &Region,
    ) -> Self {
        let n = ((reach / h).ceil() + 1.0).min(MAX_SPACINGS) as i64;
        let mut ranges = [(0i64, 1i64); 3];
        for a in 0..dim {
            ranges[a] = span(center[a], offset[a], h, bounds.lo[a], bounds.hi[a], -n, n);
        }
        Self { ranges }
    }

    /// Lattice points visited.
    pub fn points(&self) -> f64 {
        self.ranges.iter().map(|(a, b)| (b - a) as f64).product()
    }
}

/// Reserves room for `points` more particles, or says why it cannot.
fn reserve(body: &mut BodyParticles, dim: usize, points: f64) -> Result<(), String> {
    let n = points as usize;
    body.positions
        .try_reserve(n.saturating_mul(dim))
        .and_then(|()| body.volumes.try_reserve(n))
        .map_err(|e| format!("cannot hold {points:.3e} particles: {e}"))
}

/// Fills an axis-aligned box with its lattice (within the region only).
pub(crate) fn fill_box(
    dim: usize,
    min: &[f64],
    max: &[f64],
    h: f64,
    region: &Region,
    body: &mut BodyParticles,
) -> Result<(), String> {
    let Some(lattice) = BoxLattice::new(dim, min, max, h, region) else {
        return Ok(());
    };
    reserve(body, dim, lattice.points())?;
    let [ri, rj, rk] = lattice.ranges;
    for i in ri.0..ri.1 {
        for j in rj.0..rj.1 {
            for k in rk.0..rk.1 {
                let idx = [i, j, k];
                for a in 0..dim {
                    body.positions
                        .push(min[a] + (idx[a] as f64 + 0.5) * lattice.step[a]);
                }
                body.volumes.push(lattice.volume);
            }
        }
    }
    Ok(())
}

/// Fills the points of a lattice centred on `center` within `reach` and `bounds` that
/// satisfy `inside` (called with the offset from the centre).
#[allow(clippy::too_many_arguments)]
pub(crate) fn fill_lattice(
    dim: usize,
    center: &[f64],
    reach: f64,
    h: f64,
    offset: [f64; 3],
    bounds: &Region,
    body: &mut BodyParticles,
    inside: impl Fn(&[f64]) -> bool,
) -> Result<(), String> {
    let lattice = CentredLattice::new(dim, center, reach, h, offset, bounds);
    let volume = h.powi(dim as i32);
    let [ri, rj, rk] = lattice.ranges;
    let mut r = [0.0; 3];
    for i in ri.0..ri.1 {
        for j in rj.0..rj.1 {
            for k in rk.0..rk.1 {
                let idx = [i, j, k];
                for a in 0..dim {
                    r[a] = (idx[a] as f64 + offset[a]) * h;
                }
                if inside(&r[..dim]) {
                    if body.volumes.len() == body.volumes.capacity() {
                        reserve(body, dim, (body.volumes.len() as f64).max(1024.0))?;
                    }
                    for a in 0..dim {
                        body.positions.push(center[a] + r[a]);
                    }
                    body.volumes.push(volume);
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn everywhere() -> Region {
        Region {
            lo: [f64::NEG_INFINITY; 3],
            hi: [f64::INFINITY; 3],
        }
    }

    #[test]
    fn a_region_keeps_exactly_the_points_of_the_full_lattice_inside_it() {
        let (min, max, h) = ([0.0, 0.0], [1.0, 0.5], 0.1);
        let mut full = BodyParticles::default();
        fill_box(2, &min, &max, h, &everywhere(), &mut full).unwrap();
        assert_eq!(full.volumes.len(), 50);
        let region = Region {
            lo: [0.3, -1.0, 0.0],
            hi: [0.62, 0.2, 0.0],
        };
        let mut part = BodyParticles::default();
        fill_box(2, &min, &max, h, &region, &mut part).unwrap();
        let inside: Vec<f64> = full
            .positions
            .chunks_exact(2)
            .filter(|x| x[0] >= 0.3 && x[0] <= 0.62 && x[1] <= 0.2)
            .flatten()
            .copied()
            .collect();
        let kept: Vec<f64> = part
            .positions
            .chunks_exact(2)
            .filter(|x| x[0] >= 0.3 && x[0] <= 0.62 && x[1] <= 0.2)
            .flatten()
            .copied()
            .collect();
        assert_eq!(inside, kept);
        assert!(part.volumes.len() <= 30, "{}", part.volumes.len());
    }

    #[test]
    fn a_huge_sphere_visits_only_the_points_in_its_bounds() {
        let bounds = Region {
            lo: [0.0, 0.0, 0.0],
            hi: [1.0, 1.0, 0.0],
        };
        let lattice = CentredLattice::new(2, &[0.5, 0.5], 1e9, 0.01, [0.5; 3], &bounds);
        assert!(lattice.points() < 110.0 * 110.0, "{}", lattice.points());
        let mut body = BodyParticles::default();
        fill_lattice(
            2,
            &[0.5, 0.5],
            1e9,
            0.01,
            [0.5; 3],
            &bounds,
            &mut body,
            |_| true,
        )
        .unwrap();
        assert_eq!(body.volumes.len() as f64, lattice.points());
    }

    #[test]
    fn a_tilted_cylinder_has_a_tight_bounding_box() {
        let shape = Shape::Cylinder {
            center: vec![0.0, 0.0, 0.0],
            radius: 0.1,
            axis: vec![1.0, 0.0, 0.0],
            length: 2.0,
        };
        let b = bounding_box(3, &shape).unwrap();
        assert_eq!((b.lo[0], b.hi[0]), (-1.0, 1.0));
        assert!((b.hi[1] - 0.1).abs() < 1e-15 && (b.hi[2] - 0.1).abs() < 1e-15);
    }
}
