//! The picture's geometry: the particle spacing (the size of the drawn squares), the domain
//! recorded in the store, and the drawn box.

use serde_json::Value;
use std::collections::HashMap;

/// The scene's domain box `[min, max, min, max]` along the picture's two `axes`, when the
/// store records it.
pub(super) fn domain(
    attributes: &serde_json::Map<String, Value>,
    axes: [usize; 2],
) -> Option<[f64; 4]> {
    let d = attributes.get("scene")?.get("domain")?;
    let corner = |key: &str| -> Option<(f64, f64)> {
        let c = d.get(key)?.as_array()?;
        Some((c.get(axes[0])?.as_f64()?, c.get(axes[1])?.as_f64()?))
    };
    let (min, max) = (corner("min")?, corner("max")?);
    let b = [min.0, max.0, min.1, max.1];
    (b.iter().all(|v| v.is_finite()) && b[1] > b[0] && b[3] > b[2]).then_some(b)
}

/// The drawn box: the domain (so that frames of a run share their framing) and every
/// particle's square, `[xmin, xmax, ymin, ymax]`, never of zero extent.
pub(super) fn picture_bounds(
    points: &[(f64, f64)],
    domain: Option<[f64; 4]>,
    spacing: f64,
) -> Option<[f64; 4]> {
    let half = 0.5 * spacing;
    let mut b = domain.unwrap_or([f64::MAX, f64::MIN, f64::MAX, f64::MIN]);
    for &(x, y) in points {
        b[0] = b[0].min(x - half);
        b[1] = b[1].max(x + half);
        b[2] = b[2].min(y - half);
        b[3] = b[3].max(y + half);
    }
    if b[0] > b[1] || b[2] > b[3] {
        return None;
    }
    // A single particle, or a line of them: give the flat direction some extent.
    let size = (b[1] - b[0]).max(b[3] - b[2]);
    let size = if size > 0.0 { size } else { 1e-3 };
    for axis in [0, 2] {
        if b[axis + 1] - b[axis] < 1e-3 * size {
            let mid = 0.5 * (b[axis] + b[axis + 1]);
            b[axis] = mid - 0.05 * size;
            b[axis + 1] = mid + 0.05 * size;
        }
    }
    Some(b)
}

/// The spacing of the particles `drawn` (indices into `positions`, `dim` numbers each) in
/// the run's own dimension: seen along an axis, a 3D run's particles lie on one another in
/// the picture, so their spacing there says nothing.
pub(super) fn spacing_of(positions: &[f64], dim: usize, drawn: &[usize]) -> Option<f64> {
    fn gather<const N: usize>(positions: &[f64], drawn: &[usize]) -> Vec<[f64; N]> {
        drawn
            .iter()
            .map(|&p| std::array::from_fn(|a| positions[N * p + a]))
            .collect()
    }
    match dim {
        3 => particle_spacing(&gather::<3>(positions, drawn)),
        _ => particle_spacing(&gather::<2>(positions, drawn)),
    }
}

/// Estimated particle spacing: the median distance to the nearest other particle, over up
/// to 2000 particles, found with a bucket grid, in the particles' own dimension `N` (a 3D
/// run seen along an axis stacks particles on one another in the picture). `None` for fewer
/// than two distinct points.
fn particle_spacing<const N: usize>(points: &[[f64; N]]) -> Option<f64> {
    let n = points.len();
    if n < 2 {
        return None;
    }
    let mut low = [f64::MAX; N];
    let mut high = [f64::MIN; N];
    for p in points {
        for a in 0..N {
            low[a] = low[a].min(p[a]);
            high[a] = high[a].max(p[a]);
        }
    }
    // Bucket side: the spacing the particles would have if they filled their box, over the
    // axes along which they spread.
    let spread: Vec<f64> = (0..N)
        .map(|a| high[a] - low[a])
        .filter(|e| *e > 0.0)
        .collect();
    let volume: f64 = spread.iter().product();
    let cell = match spread.len() {
        0 => return None,
        1 => spread[0] / (n - 1) as f64,
        k => (volume / n as f64).powf(1.0 / k as f64),
    };
    if cell.is_nan() || cell <= 0.0 {
        return None;
    }
    let key = |p: &[f64; N]| -> [i64; N] {
        std::array::from_fn(|a| ((p[a] - low[a]) / cell).floor() as i64)
    };
    let mut buckets: HashMap<[i64; N], Vec<usize>> = HashMap::new();
    for (i, p) in points.iter().enumerate() {
        buckets.entry(key(p)).or_default().push(i);
    }
    // Shells of buckets around a particle, nearest first; a point in shell r + 1 is at least
    // r cells away, so the search stops once the nearest found is closer than that.
    const MAX_RING: i64 = 64;
    let mut nearest = Vec::new();
    for i in (0..n).step_by((n / 2000).max(1)) {
        let p = &points[i];
        let centre = key(p);
        let mut best = f64::INFINITY;
        for r in 0..=MAX_RING {
            // The shell's buckets: the first axis at distance r is `lead`, the axes before it
            // lie strictly inside, those after it anywhere in [-r, r].
            for lead in 0..N {
                let width = (2 * r + 1) as usize;
                let inner = (2 * r - 1).max(0) as usize;
                let count = inner.pow(lead as u32) * width.pow((N - lead - 1) as u32);
                for sign in [-r, r] {
                    for flat in 0..count {
                        let mut rest = flat;
                        let offset: [i64; N] = std::array::from_fn(|a| {
                            if a == lead {
                                return sign;
                            }
                            let (span, low) = if a < lead {
                                (inner, 1 - r)
                            } else {
                                (width, -r)
                            };
                            let o = (rest % span) as i64 + low;
                            rest /= span;
                            o
                        });
                        let b: [i64; N] = std::array::from_fn(|a| centre[a] + offset[a]);
                        for &j in buckets.get(&b).into_iter().flatten() {
                            let d = (0..N)
                                .map(|a| (points[j][a] - p[a]).powi(2))
                                .sum::<f64>()
                                .sqrt();
                            if j != i && d > 0.0 && d < best {
                                best = d;
                            }
                        }
                    }
                    if r == 0 {
                        break; // one bucket: -0 and +0 are the same
                    }
                }
            }
            if best <= r as f64 * cell {
                break;
            }
        }
        if best.is_finite() {
            nearest.push(best);
        }
    }
    if nearest.is_empty() {
        return None;
    }
    nearest.sort_by(f64::total_cmp);
    Some(nearest[nearest.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spacing_is_the_lattice_spacing() {
        // A 40 x 8 lattice of spacing 0.25 mm with a few holes, shuffled order.
        let h = 2.5e-4;
        let mut points: Vec<[f64; 2]> = (0..320)
            .filter(|i| i % 17 != 3)
            .map(|i| [(i % 40) as f64 * h + 0.5 * h, (i / 40) as f64 * h + 0.5 * h])
            .collect();
        points.reverse();
        let s = particle_spacing(&points).unwrap();
        assert!((s - h).abs() < 1e-9 * h, "{s}");
        // A row of particles; two far apart clusters.
        let row: Vec<[f64; 2]> = (0..10).map(|i| [i as f64 * 0.1, 0.0]).collect();
        assert!((particle_spacing(&row).unwrap() - 0.1).abs() < 1e-12);
        let mut two: Vec<[f64; 2]> = (0..50).map(|i| [i as f64 * 1e-3, 0.0]).collect();
        two.extend((0..50).map(|i| [10.0 + i as f64 * 1e-3, 5.0]));
        assert!((particle_spacing(&two).unwrap() - 1e-3).abs() < 1e-9);
        assert_eq!(particle_spacing(&[[1.0, 1.0]]), None);
        assert_eq!(particle_spacing(&[[1.0, 1.0], [1.0, 1.0]]), None);
        // A 3D lattice 20 x 10 x 3, spacing 0.1 mm, jittered along z by a hundredth of it:
        // seen along z its points nearly coincide, in 3D the spacing is the lattice's.
        let h = 1e-4;
        let cube: Vec<[f64; 3]> = (0..600)
            .map(|i| {
                let (x, y, z) = (i % 20, (i / 20) % 10, i / 200);
                [
                    x as f64 * h,
                    y as f64 * h,
                    z as f64 * h + 1e-6 * (x % 3) as f64,
                ]
            })
            .collect();
        let s = particle_spacing(&cube).unwrap();
        assert!((s - h).abs() < 1e-3 * h, "{s}");
    }

    #[test]
    fn bounds_cover_the_domain_and_every_square() {
        let b = picture_bounds(&[(0.5, 0.5)], Some([0.0, 1.0, 0.0, 2.0]), 0.1).unwrap();
        assert_eq!(b, [0.0, 1.0, 0.0, 2.0]);
        let b = picture_bounds(&[(0.0, 0.0), (1.0, 0.5)], None, 0.2).unwrap();
        assert_eq!(b, [-0.1, 1.1, -0.1, 0.6]);
        // A line of particles gets some height.
        let b = picture_bounds(&[(0.0, 0.0), (1.0, 0.0)], None, 0.0).unwrap();
        assert!(b[3] - b[2] > 0.05, "{b:?}");
        assert_eq!(picture_bounds(&[], None, 0.0), None);
    }
}
