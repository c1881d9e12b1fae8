//! Averages a law's state field over a material length after every step
//! ([`AveragedState`]): each particle's averaged field becomes the volume-weighted mean of
//! the local field over the particles of its material within the radius, kept from falling
//! and capped. A damage law that fails its particles on the averaged damage (a nonlocal
//! integral model, Pijaudier-Cabot & Bažant 1987) starts its cracks where a region of that
//! size has used up its ductility, not where one particle at a singular corner has, so the
//! onset converges as the cell shrinks.
//!
//! Neighbours are found through particles sorted by cells one radius wide (a sort, then a
//! binary search among the occupied cells per neighbour cell), in buffers kept between
//! steps: no allocation per step once they have grown. A particle with no nonzero local
//! value in the cells around it averages to 0 without a pair visited. The averaged field lags the local one by a step: the law sees this
//! step's average in the next step.

use crate::material::AveragedState;
use crate::math::{Vector, determinant};
use crate::particles::Particles;
use rayon::prelude::*;

/// The groups whose law averages a field, and the buffers the averaging reuses.
pub(super) struct StateAveraging {
    /// (group index, what its law averages).
    groups: Vec<(usize, AveragedState)>,
    /// (cell, index within the group), sorted by cell.
    order: Vec<([i64; 3], u32)>,
    /// Each occupied cell's run of `order` (cell, first, end) and whether any of its
    /// particles has a nonzero local value.
    runs: Vec<([i64; 3], u32, u32, bool)>,
    /// Current volume of the group's particles.
    volume: Vec<f64>,
    /// The new averages, before they are written.
    averaged: Vec<f64>,
}

impl StateAveraging {
    /// The averaging the particles' laws ask for; `None` when none does.
    pub(super) fn for_particles<const D: usize>(particles: &Particles<D>) -> Option<Self> {
        let groups: Vec<(usize, AveragedState)> = particles
            .groups
            .iter()
            .enumerate()
            .filter_map(|(g, group)| Some((g, group.material.averaged_state()?)))
            .collect();
        (!groups.is_empty()).then(|| Self {
            groups,
            order: Vec::new(),
            runs: Vec::new(),
            volume: Vec::new(),
            averaged: Vec::new(),
        })
    }

    /// Averages every group's field once (after a step).
    pub(super) fn apply<const D: usize>(&mut self, particles: &mut Particles<D>) {
        for &(g, spec) in &self.groups {
            let range = particles.groups[g].range.clone();
            let radius = spec.radius;
            let cell = |x: &Vector<D>| -> [i64; 3] {
                let mut c = [0i64; 3];
                for (a, v) in x.iter().enumerate() {
                    c[a] = (v / radius).floor() as i64;
                }
                c
            };
            let positions = &particles.position[range.clone()];
            self.order.clear();
            self.order.extend(
                positions
                    .iter()
                    .enumerate()
                    .map(|(k, x)| (cell(x), k as u32)),
            );
            self.order.sort_unstable();
            self.volume.clear();
            self.volume.extend(
                range.clone().map(|p| {
                    determinant(&particles.deformation_gradient[p]) * particles.volume0[p]
                }),
            );
            let local = &particles.groups[g].state[spec.local];
            // Each cell's run of `order`, and whether any of its particles has a local
            // value: a particle with no such cell around it averages to exactly 0, and is
            // skipped (most of a body, where nothing has yielded).
            self.runs.clear();
            let mut start = 0;
            while start < self.order.len() {
                let key = self.order[start].0;
                let mut end = start;
                let mut active = false;
                while end < self.order.len() && self.order[end].0 == key {
                    active |= local[self.order[end].1 as usize] != 0.0;
                    end += 1;
                }
                self.runs.push((key, start as u32, end as u32, active));
                start = end;
            }
            let (order, runs, volume) = (&self.order, &self.runs, &self.volume);
            let reach: i64 = if D == 3 { 1 } else { 0 };
            let run_of = |key: [i64; 3]| runs.binary_search_by(|r| r.0.cmp(&key)).ok();
            self.averaged.clear();
            self.averaged.resize(range.len(), 0.0);
            self.averaged
                .par_iter_mut()
                .enumerate()
                .for_each(|(k, out)| {
                    let x = positions[k];
                    let home = cell(&x);
                    let mut around = [None; 27];
                    let mut n = 0;
                    let mut active = false;
                    for dx in -1..=1 {
                        for dy in -1..=1 {
                            for dz in -reach..=reach {
                                let r = run_of([home[0] + dx, home[1] + dy, home[2] + dz]);
                                active |= r.is_some_and(|r| runs[r].3);
                                around[n] = r;
                                n += 1;
                            }
                        }
                    }
                    if !active {
                        *out = 0.0;
                        return;
                    }
                    let (mut weighted, mut total) = (0.0, 0.0);
                    for r in around[..n].iter().flatten() {
                        let (_, first, last, _) = runs[*r];
                        for &(_, j) in &order[first as usize..last as usize] {
                            let j = j as usize;
                            if (positions[j] - x).norm() <= radius {
                                weighted += volume[j] * local[j];
                                total += volume[j];
                            }
                        }
                    }
                    *out = if total > 0.0 {
                        weighted / total
                    } else {
                        local[k]
                    };
                });
            let target = &mut particles.groups[g].state[spec.averaged];
            for (value, &new) in target.iter_mut().zip(&self.averaged) {
                *value = value.max(new).min(spec.cap);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn cells_sort_so_a_cell_is_one_run() {
        // The search relies on the order keeping each cell's particles together.
        let mut order = [
            ([1, 0, 0], 0u32),
            ([0, 1, 0], 1),
            ([1, 0, 0], 2),
            ([0, 0, 0], 3),
        ];
        order.sort_unstable();
        let key = [1, 0, 0];
        let first = order.partition_point(|(c, _)| *c < key);
        let members: Vec<u32> = order[first..]
            .iter()
            .take_while(|(c, _)| *c == key)
            .map(|(_, j)| *j)
            .collect();
        assert_eq!(members, vec![0, 2]);
    }
}
