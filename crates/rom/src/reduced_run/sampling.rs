//! Sample selection: the interior particles of the body and farthest-point sampling over
//! them, in the reference configuration.

use mpm_core::math::Vector;
use rayon::prelude::*;

/// Particles at least a cell inside the body: their 3^D neighbouring cells (of size `dx`,
/// in the reference configuration) hold at least 90% of the most any particle sees. Their
/// grid nodes are full, so the accelerations sampled there are not those of the sparsely
/// filled surface nodes; the outermost layer is left out. Every particle when none is.
pub fn interior_particles<const D: usize>(positions: &[Vector<D>], dx: f64) -> Vec<usize> {
    use std::collections::HashMap;
    let cell = |x: &Vector<D>| -> [i64; 3] {
        let mut c = [0i64; 3];
        for d in 0..D {
            c[d] = (x[d] / dx).floor() as i64;
        }
        c
    };
    let mut counts: HashMap<[i64; 3], usize> = HashMap::new();
    for x in positions {
        *counts.entry(cell(x)).or_default() += 1;
    }
    let reach = |c: [i64; 3]| -> usize {
        let mut total = 0;
        let z = if D == 3 { -1..=1 } else { 0..=0 };
        for i in -1..=1 {
            for j in -1..=1 {
                for k in z.clone() {
                    total += counts
                        .get(&[c[0] + i, c[1] + j, c[2] + k])
                        .copied()
                        .unwrap_or(0);
                }
            }
        }
        total
    };
    let seen: Vec<usize> = positions.iter().map(|x| reach(cell(x))).collect();
    let most = seen.iter().copied().max().unwrap_or(0);
    let inside: Vec<usize> = (0..positions.len())
        .filter(|&p| seen[p] * 10 >= most * 9)
        .collect();
    if inside.is_empty() {
        (0..positions.len()).collect()
    } else {
        inside
    }
}

/// `count` particles spread over `eligible` particles by farthest-point sampling in the
/// reference configuration, starting from the one nearest the centroid; sorted by index.
pub fn farthest_point_samples<const D: usize>(
    positions: &[Vector<D>],
    eligible: &[usize],
    count: usize,
) -> Vec<u32> {
    let n = eligible.len();
    if n == 0 || count == 0 {
        return Vec::new();
    }
    let centroid = eligible
        .iter()
        .fold(Vector::<D>::zeros(), |a, &p| a + positions[p])
        / n as f64;
    let first = (0..n)
        .min_by(|&a, &b| {
            (positions[eligible[a]] - centroid)
                .norm_squared()
                .total_cmp(&(positions[eligible[b]] - centroid).norm_squared())
        })
        .unwrap_or(0);
    let mut distance = vec![f64::INFINITY; n];
    let mut chosen = vec![eligible[first] as u32];
    let mut last = first;
    while chosen.len() < count.min(n) {
        let from = positions[eligible[last]];
        let next = distance
            .par_iter_mut()
            .zip(eligible.par_iter())
            .enumerate()
            .map(|(i, (d, &p))| {
                *d = d.min((positions[p] - from).norm_squared());
                (i, *d)
            })
            .reduce(
                || (usize::MAX, f64::NEG_INFINITY),
                |a, b| {
                    if b.1 > a.1 || (b.1 == a.1 && b.0 < a.0) {
                        b
                    } else {
                        a
                    }
                },
            );
        last = next.0;
        chosen.push(eligible[last] as u32);
    }
    chosen.sort_unstable();
    chosen.dedup();
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_spread_over_the_interior() {
        // A 10 x 10 lattice of spacing 0.5 in cells of 1: the outermost ring is not interior.
        let positions: Vec<Vector<2>> = (0..100)
            .map(|k| Vector::<2>::new(0.25 + 0.5 * (k / 10) as f64, 0.25 + 0.5 * (k % 10) as f64))
            .collect();
        let inside = interior_particles::<2>(&positions, 1.0);
        assert!(inside.len() < 100 && inside.len() >= 16, "{}", inside.len());
        let samples = farthest_point_samples::<2>(&positions, &inside, 4);
        assert_eq!(samples.len(), 4);
        // Four samples over a square spread to its four quadrants.
        let mut quadrants = [false; 4];
        for s in &samples {
            let x = positions[*s as usize];
            quadrants[(x[0] > 2.5) as usize * 2 + (x[1] > 2.5) as usize] = true;
        }
        assert!(quadrants.iter().all(|q| *q), "{samples:?}");
    }
}
