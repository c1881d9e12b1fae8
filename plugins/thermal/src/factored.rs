//! The factored preconditioner of the implicit heat step: the step's matrix
//! A = C + dt (K + H) on the free nodes, assembled from the particles (K_ij =
//! Σ_p V_p k_p ∇w_ip·∇w_jp, the lumped capacity C and the convection H on the diagonal) and
//! factored by the core's sparse Cholesky. A is the matrix-free operator itself, so
//! conjugate gradients converge in one or two iterations instead of a number growing with
//! the grid (Jacobi needed up to 157 per step on the underfill-cure section, where the
//! diffusion length of a 30 s step is centimetres against a millimetre body). The sparsity
//! pattern and its symbolic factorisation are kept while the particles stay in their cells.
//! With contact conductance the unknowns are rows (node + group × nodes) and the
//! interface couplings add their entries.

use crate::interface::Coupling;
use faer::sparse::Pair;
use mpm_core::linear_solvers::sparse_cholesky::{PatternCache, SparseCholesky};
use mpm_core::physics::Interpolation;
use std::sync::Mutex;

/// Most matrix entries (before summing duplicates) the assembly may make (about 48 bytes
/// each); a larger system keeps Jacobi.
const MAX_ENTRIES: usize = 20_000_000;

/// What one solve needs, kept between steps (behind a lock: the physics is shared).
#[derive(Default)]
pub(crate) struct FactoredState {
    pattern: PatternCache,
    pairs: Vec<Pair<usize, usize>>,
    values: Vec<f64>,
    /// Index among the free nodes of each grid node (`u32::MAX` when not free).
    index: Vec<u32>,
    /// Grid node of each free index.
    nodes: Vec<u32>,
    /// The right-hand side and solution on the free nodes (reused).
    compact: Vec<f64>,
}

/// The lockable state, owned by the thermal physics.
#[derive(Default)]
pub(crate) struct Factored {
    pub state: Mutex<FactoredState>,
}

impl FactoredState {
    /// Assembles and factors A on the rows with `inverse_diagonal > 0`; `conductance(p)` is
    /// V_p k_p of particle `p`, whose rows are its nodes plus `offset(p)`; `couplings` are
    /// the interfaces between groups. `None` when the system is too large or not factorable.
    #[allow(clippy::too_many_arguments)]
    pub fn factor<const D: usize>(
        &mut self,
        it: &Interpolation<D>,
        particles: usize,
        conductance: impl Fn(usize) -> f64,
        offset: &dyn Fn(usize) -> usize,
        couplings: &[Coupling],
        capacity: &[f64],
        convection: &[f64],
        inverse_diagonal: &[f64],
        dt: f64,
    ) -> Option<SparseCholesky> {
        if particles * it.stencil * (it.stencil + 1) / 2 > MAX_ENTRIES {
            return None;
        }
        self.index.clear();
        self.index.resize(inverse_diagonal.len(), u32::MAX);
        self.nodes.clear();
        for (i, &d) in inverse_diagonal.iter().enumerate() {
            if d > 0.0 {
                self.index[i] = self.nodes.len() as u32;
                self.nodes.push(i as u32);
            }
        }
        let n = self.nodes.len();
        if n == 0 {
            return None;
        }
        self.pairs.clear();
        self.values.clear();
        for p in 0..particles {
            let s = dt * conductance(p);
            let o = offset(p);
            for a in it.entries(p) {
                let row = self.index[it.node[a] as usize + o];
                if row == u32::MAX {
                    continue;
                }
                for b in it.entries(p) {
                    let col = self.index[it.node[b] as usize + o];
                    if col == u32::MAX || col > row {
                        continue;
                    }
                    self.pairs.push(Pair::new(row as usize, col as usize));
                    self.values.push(s * it.gradient[a].dot(&it.gradient[b]));
                }
            }
        }
        for c in couplings {
            let (a, b) = (self.index[c.a as usize], self.index[c.b as usize]);
            let h = dt * c.conductance;
            for row in [a, b] {
                if row != u32::MAX {
                    self.pairs.push(Pair::new(row as usize, row as usize));
                    self.values.push(h);
                }
            }
            if a != u32::MAX && b != u32::MAX {
                self.pairs
                    .push(Pair::new(a.max(b) as usize, a.min(b) as usize));
                self.values.push(-h);
            }
        }
        for (k, &node) in self.nodes.iter().enumerate() {
            let i = node as usize;
            self.pairs.push(Pair::new(k, k));
            self.values.push(capacity[i] + dt * convection[i]);
        }
        SparseCholesky::factor_with_pattern(n, &self.pairs, &self.values, &mut self.pattern).ok()
    }

    /// z = A⁻¹ r on the free nodes (zero elsewhere), with the factor of [`Self::factor`].
    pub fn precondition(&mut self, factor: &SparseCholesky, r: &[f64], z: &mut [f64]) {
        self.compact.clear();
        self.compact
            .extend(self.nodes.iter().map(|&i| r[i as usize]));
        factor.solve_in_place(&mut self.compact);
        z.fill(0.0);
        for (&i, &v) in self.nodes.iter().zip(&self.compact) {
            z[i as usize] = v;
        }
    }
}
