//! A hash of particle indices by the cell of side `size` their position falls in, for the
//! neighbour searches of the stage figures (the stress average, the fatigue layer): the
//! particles within `size` of a point lie in its cell's 3^D block. Built once per query
//! set at a stage's end, not in the time loop.

use crate::math::Vector;
use std::collections::HashMap;

/// Particle indices by cell.
pub(crate) struct CellHash<const D: usize> {
    size: f64,
    cells: HashMap<[i64; D], Vec<usize>>,
    offsets: Vec<[i64; D]>,
}

impl<const D: usize> CellHash<D> {
    /// Hashes the particles `indices` at `positions[index]` into cells of side `size`.
    pub fn new(
        size: f64,
        positions: &[Vector<D>],
        indices: impl IntoIterator<Item = usize>,
    ) -> Self {
        let mut hash = Self {
            size,
            cells: HashMap::new(),
            offsets: (0..3usize.pow(D as u32))
                .map(|mut code| {
                    std::array::from_fn(|_| {
                        let o = (code % 3) as i64 - 1;
                        code /= 3;
                        o
                    })
                })
                .collect(),
        };
        for p in indices {
            let key = hash.cell(&positions[p]);
            hash.cells.entry(key).or_default().push(p);
        }
        hash
    }

    /// Whether no particle was hashed.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    fn cell(&self, x: &Vector<D>) -> [i64; D] {
        std::array::from_fn(|k| (x[k] / self.size).floor() as i64)
    }

    /// The hashed particles in the 3^D cells around `x`: every one within `size` of it,
    /// and some farther.
    pub fn near(&self, x: &Vector<D>) -> impl Iterator<Item = usize> + '_ {
        let home = self.cell(x);
        self.offsets.iter().flat_map(move |o| {
            let key: [i64; D] = std::array::from_fn(|a| home[a] + o[a]);
            self.cells.get(&key).into_iter().flatten().copied()
        })
    }
}
