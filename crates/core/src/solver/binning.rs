//! Per-step binning of particles into x-slabs for the coloured parallel P2G, and the
//! occasional reordering of particles by cell for memory locality.

use super::parallel::SharedSlice;
use crate::grid::Grid;
use crate::kernels::Kernel;
use crate::math::Vector;
use crate::particles::Particles;
use rayon::prelude::*;

/// The slab mark of a particle held in place: in no bin.
const HELD: u32 = u32::MAX;

/// Particle indices grouped by the x-slab of their first stencil node. Buffers are
/// allocated once and reused every step.
pub(crate) struct SlabBins {
    width: usize,
    slab_of: Vec<u32>,
    start: Vec<usize>,
    order: Vec<u32>,
    /// Per counting chunk of [`BIN_CHUNK`] particles and slab (`chunk · slabs + slab`):
    /// how many of the chunk's particles the slab holds, then where the chunk writes its
    /// next one.
    cursors: Vec<usize>,
}

/// Particles per task of the binning's parallel counting sort.
const BIN_CHUNK: usize = 16_384;

impl SlabBins {
    /// Bins for a grid, `width` node planes per slab.
    pub fn new(nodes_x: usize, width: usize, particles: usize) -> Self {
        let slabs = nodes_x.div_ceil(width);
        Self {
            width,
            slab_of: vec![0; particles],
            start: vec![0; slabs + 1],
            order: vec![0; particles],
            cursors: Vec::new(),
        }
    }

    /// Number of slabs.
    pub fn slab_count(&self) -> usize {
        self.start.len() - 1
    }

    /// Particles of one slab.
    pub fn slab(&self, s: usize) -> &[u32] {
        &self.order[self.start[s]..self.start[s + 1]]
    }

    /// Re-bins every particle (counting sort, stable).
    pub fn rebuild<const D: usize, K: Kernel>(&mut self, grid: &Grid<D>, particles: &Particles<D>) {
        let width = self.width;
        let slabs = self.slab_count();
        let (origin, inv_dx) = (grid.origin[0], grid.inv_dx);
        // Particles held in place (solids in incompressible mechanics) are in no bin, so
        // the transfers that scatter through the bins leave them out.
        let any_held = particles.any_held();
        self.slab_of
            .par_iter_mut()
            .zip(particles.position.par_iter())
            .enumerate()
            .for_each(|(p, (slab, x))| {
                if any_held && particles.is_held(p) {
                    *slab = HELD;
                    return;
                }
                let half = if K::USES_PARTICLE_SIZE {
                    particles.half_size[p]
                } else {
                    0.0
                };
                let base = K::weights((x[0] - origin) * inv_dx, half).base.max(0) as usize;
                *slab = (base / width).min(slabs - 1) as u32;
            });
        sort_into_slabs(
            &self.slab_of,
            &mut self.start,
            &mut self.order,
            &mut self.cursors,
        );
    }

    /// Splits these bins by contact field: `out[f]` gets, slab by slab and in the same
    /// order, the particles `p` with `field_of[p] == f` (the bins of field `f`'s own P2G).
    pub fn split_by_field(&self, field_of: &[u8], out: &mut [SlabBins]) {
        for bins in out.iter_mut() {
            bins.start.fill(0);
        }
        let mut filled = [0usize; crate::scene::MAX_CONTACT_FIELDS];
        for s in 0..self.slab_count() {
            for &p in self.slab(s) {
                let f = field_of[p as usize] as usize;
                out[f].order[filled[f]] = p;
                filled[f] += 1;
            }
            for (f, bins) in out.iter_mut().enumerate() {
                bins.start[s + 1] = filled[f];
            }
        }
    }
}

/// Fills `order` with the particle indices slab by slab, each slab's in index order, and
/// `start` (one longer than the slab count) with where each slab's run begins; particles
/// marked [`HELD`] in `slab_of` are left out. A counting sort in parallel over chunks of
/// particles: each chunk counts its particles per slab, the counts become each chunk's
/// first place in each slab (slab by slab, chunk by chunk: the order a serial pass gives),
/// and each chunk then writes its own places. `cursors` is scratch, kept between calls.
fn sort_into_slabs(
    slab_of: &[u32],
    start: &mut [usize],
    order: &mut [u32],
    cursors: &mut Vec<usize>,
) {
    let slabs = start.len() - 1;
    let chunks = slab_of.len().div_ceil(BIN_CHUNK);
    cursors.clear();
    cursors.resize(chunks * slabs, 0);
    cursors
        .par_chunks_mut(slabs)
        .zip(slab_of.par_chunks(BIN_CHUNK))
        .for_each(|(count, slab_of)| {
            for &s in slab_of.iter().filter(|&&s| s != HELD) {
                count[s as usize] += 1;
            }
        });
    let mut next = 0;
    for s in 0..slabs {
        start[s] = next;
        for c in 0..chunks {
            let cursor = &mut cursors[c * slabs + s];
            (*cursor, next) = (next, next + *cursor);
        }
    }
    start[slabs] = next;
    assert!(next <= order.len(), "more particles binned than places");
    let order = SharedSlice::new(order);
    cursors
        .par_chunks_mut(slabs)
        .zip(slab_of.par_chunks(BIN_CHUNK))
        .enumerate()
        .for_each(|(c, (cursor, slab_of))| {
            for (k, &s) in slab_of.iter().enumerate().filter(|(_, s)| **s != HELD) {
                let at = &mut cursor[s as usize];
                // SAFETY: the cursors of different chunks and slabs run over disjoint
                // ranges of `order` (their counts' prefix sums), all below `next`, which
                // is at most its length.
                unsafe { *order.get(*at) = (c * BIN_CHUNK + k) as u32 };
                *at += 1;
            }
        });
}

/// Reorders particles within each material group by grid cell. Buffers are reused.
pub(crate) struct Reorder {
    keys: Vec<u64>,
    perm: Vec<u32>,
    visited: Vec<bool>,
}

impl Reorder {
    /// Buffers for `n` particles.
    pub fn new(n: usize) -> Self {
        Self {
            keys: vec![0; n],
            perm: vec![0; n],
            visited: vec![false; n],
        }
    }

    /// Sorts every group's particles by the index of the cell they lie in; `per_particle`
    /// (one number per particle, or empty) is solver state kept outside the particles that
    /// must follow them (the free strain the stress last applied).
    pub fn apply<const D: usize>(
        &mut self,
        grid: &Grid<D>,
        p: &mut Particles<D>,
        per_particle: &mut [f64],
    ) {
        let (origin, inv_dx) = (grid.origin, grid.inv_dx);
        let cell_key = |x: &Vector<D>| -> u64 {
            let mut key = 0u64;
            for d in 0..D {
                let c = ((x[d] - origin[d]) * inv_dx).max(0.0) as u64;
                key = key * (grid.cells[d] as u64 + 1) + c;
            }
            key
        };
        for (k, x) in self.keys.iter_mut().zip(&p.position) {
            *k = cell_key(x);
        }
        for g in 0..p.groups.len() {
            let range = p.groups[g].range.clone();
            let perm = &mut self.perm[range.clone()];
            for (j, v) in perm.iter_mut().enumerate() {
                *v = j as u32;
            }
            let keys = &self.keys[range.clone()];
            perm.sort_unstable_by_key(|&j| keys[j as usize]);
            let visited = &mut self.visited[range.clone()];
            let r = range.clone();
            gather(&mut p.position[r.clone()], perm, visited);
            gather(&mut p.velocity[r.clone()], perm, visited);
            gather(&mut p.mass[r.clone()], perm, visited);
            gather(&mut p.volume0[r.clone()], perm, visited);
            gather(&mut p.deformation_gradient[r.clone()], perm, visited);
            gather(&mut p.stress[r.clone()], perm, visited);
            gather(&mut p.id[r.clone()], perm, visited);
            if !p.affine.is_empty() {
                gather(&mut p.affine[r.clone()], perm, visited);
            }
            if !p.velocity_gradient.is_empty() {
                gather(&mut p.velocity_gradient[r.clone()], perm, visited);
            }
            if !p.half_size.is_empty() {
                gather(&mut p.half_size[r.clone()], perm, visited);
            }
            if !p.stress_zz.is_empty() {
                gather(&mut p.stress_zz[r.clone()], perm, visited);
            }
            if !p.initial_position.is_empty() {
                gather(&mut p.initial_position[r.clone()], perm, visited);
            }
            if !p.external_force.is_empty() {
                gather(&mut p.external_force[r.clone()], perm, visited);
            }
            if !p.contact_field.is_empty() {
                gather(&mut p.contact_field[r.clone()], perm, visited);
            }
            for field in p.shared.all_mut() {
                gather(&mut field[r.clone()], perm, visited);
            }
            if per_particle.len() == p.position.len() {
                gather(&mut per_particle[r.clone()], perm, visited);
            }
            let group = &mut p.groups[g];
            let n = range.len();
            for field in &mut group.state {
                let comps = field.len() / n.max(1);
                gather_strided(field, comps, perm, visited);
            }
        }
    }
}

/// In place: `a[j] = old a[perm[j]]`, following cycles.
fn gather<T: Copy>(a: &mut [T], perm: &[u32], visited: &mut [bool]) {
    visited.fill(false);
    for start in 0..a.len() {
        if visited[start] {
            continue;
        }
        let tmp = a[start];
        let mut j = start;
        loop {
            visited[j] = true;
            let k = perm[j] as usize;
            if k == start {
                a[j] = tmp;
                break;
            }
            a[j] = a[k];
            j = k;
        }
    }
}

/// [`gather`] for arrays holding `comps` numbers per particle.
fn gather_strided(a: &mut [f64], comps: usize, perm: &[u32], visited: &mut [bool]) {
    const MAX: usize = 32;
    assert!(
        comps <= MAX,
        "state fields hold at most {MAX} numbers per particle"
    );
    visited.fill(false);
    let mut tmp = [0.0; MAX];
    for start in 0..perm.len() {
        if visited[start] {
            continue;
        }
        tmp[..comps].copy_from_slice(&a[start * comps..(start + 1) * comps]);
        let mut j = start;
        loop {
            visited[j] = true;
            let k = perm[j] as usize;
            if k == start {
                a[j * comps..(j + 1) * comps].copy_from_slice(&tmp[..comps]);
                break;
            }
            a.copy_within(k * comps..(k + 1) * comps, j * comps);
            j = k;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_parallel_counting_sort_is_the_serial_one() {
        // Several chunks, a few slabs, some particles held (in no slab).
        let (n, slabs) = (3 * BIN_CHUNK + 1234, 7);
        let mut k = 12345u64;
        let slab_of: Vec<u32> = (0..n)
            .map(|_| {
                k = k
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                match (k >> 33) % 9 {
                    8 => HELD,
                    s => (s % slabs as u64) as u32,
                }
            })
            .collect();
        let (mut start, mut order, mut cursors) = (vec![0; slabs + 1], vec![0; n], Vec::new());
        sort_into_slabs(&slab_of, &mut start, &mut order, &mut cursors);
        let mut expected = Vec::new();
        for s in 0..slabs as u32 {
            assert_eq!(start[s as usize], expected.len());
            expected.extend((0..n as u32).filter(|&p| slab_of[p as usize] == s));
        }
        assert_eq!(start[slabs], expected.len());
        assert!(expected.len() < n, "some particles are held");
        assert_eq!(&order[..expected.len()], &expected[..]);
        // Again with the scratch kept, as every step does.
        order.fill(0);
        sort_into_slabs(&slab_of, &mut start, &mut order, &mut cursors);
        assert_eq!(&order[..expected.len()], &expected[..]);
    }

    #[test]
    fn gather_applies_the_permutation() {
        let mut a = [10, 11, 12, 13, 14];
        let perm = [3u32, 0, 4, 1, 2];
        let mut visited = [false; 5];
        gather(&mut a, &perm, &mut visited);
        assert_eq!(a, [13, 10, 14, 11, 12]);
        let mut b = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5];
        gather_strided(&mut b, 2, &perm, &mut visited);
        assert_eq!(b, [3.0, 3.5, 0.0, 0.5, 4.0, 4.5, 1.0, 1.5, 2.0, 2.5]);
    }
}
