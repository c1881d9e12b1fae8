//! The picture's geometry: the particle spacing (the size of the drawn squares), the domain
//! recorded in the store, and the drawn box.

use serde_json::Value;
use std::collections::HashMap;

/// The scene's domain box `[xmin, xmax, ymin, ymax]`, when the store records it.
pub(super) fn domain(attributes: &serde_json::Map<String, Value>) -> Option<[f64; 4]> {
    let d = attributes.get("scene")?.get("domain")?;
    let corner = |key: &str| -> Option<(f64, f64)> {
        let c = d.get(key)?.as_array()?;
        Some((c.first()?.as_f64()?, c.get(1)?.as_f64()?))
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

/// Estimated particle spacing: the median distance to the nearest other particle, over up
/// to 2000 particles, found with a bucket grid. `None` for fewer than two distinct points.
pub(crate) fn particle_spacing(points: &[(f64, f64)]) -> Option<f64> {
    let n = points.len();
    if n < 2 {
        return None;
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in points {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let (w, h) = (x1 - x0, y1 - y0);
    let cell = if w * h > 0.0 {
        (w * h / n as f64).sqrt()
    } else {
        w.max(h) / (n - 1) as f64
    };
    if cell.is_nan() || cell <= 0.0 {
        return None;
    }
    let key = |(x, y): (f64, f64)| {
        (
            ((x - x0) / cell).floor() as i64,
            ((y - y0) / cell).floor() as i64,
        )
    };
    let mut buckets: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, &p) in points.iter().enumerate() {
        buckets.entry(key(p)).or_default().push(i);
    }
    // Rings of buckets around a particle, nearest first; a point in ring r + 1 is at least
    // r cells away, so the search stops once the nearest found is closer than that.
    const MAX_RING: i64 = 64;
    let mut nearest = Vec::new();
    for i in (0..n).step_by((n / 2000).max(1)) {
        let p = points[i];
        let (cx, cy) = key(p);
        let mut best = f64::INFINITY;
        for r in 0..=MAX_RING {
            for dx in -r..=r {
                let edge = dx.abs() == r;
                let dys: Vec<i64> = if edge {
                    (-r..=r).collect()
                } else {
                    vec![-r, r]
                };
                for dy in dys {
                    for &j in buckets.get(&(cx + dx, cy + dy)).into_iter().flatten() {
                        let d = (points[j].0 - p.0).hypot(points[j].1 - p.1);
                        if j != i && d > 0.0 && d < best {
                            best = d;
                        }
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
        let mut points: Vec<(f64, f64)> = (0..320)
            .filter(|i| i % 17 != 3)
            .map(|i| ((i % 40) as f64 * h + 0.5 * h, (i / 40) as f64 * h + 0.5 * h))
            .collect();
        points.reverse();
        let s = particle_spacing(&points).unwrap();
        assert!((s - h).abs() < 1e-9 * h, "{s}");
        // A row of particles; two far apart clusters.
        let row: Vec<(f64, f64)> = (0..10).map(|i| (i as f64 * 0.1, 0.0)).collect();
        assert!((particle_spacing(&row).unwrap() - 0.1).abs() < 1e-12);
        let mut two: Vec<(f64, f64)> = (0..50).map(|i| (i as f64 * 1e-3, 0.0)).collect();
        two.extend((0..50).map(|i| (10.0 + i as f64 * 1e-3, 5.0)));
        assert!((particle_spacing(&two).unwrap() - 1e-3).abs() < 1e-9);
        assert_eq!(particle_spacing(&[(1.0, 1.0)]), None);
        assert_eq!(particle_spacing(&[(1.0, 1.0), (1.0, 1.0)]), None);
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
