//! The background grid: a box of nodes holding mass and momentum (then velocity).

use crate::grid_activity::{BLOCK_NODES, GridActivity};
use crate::math::Vector;
use crate::paged::PagedArray;
use crate::solver::parallel::SharedSlice;
use std::ops::Range;

/// Nodal storage. Node `(i, j, k)` is at `origin + (i, j, k)·dx` and lives at index
/// `i·stride[0] + j·stride[1] + k`; 2D grids have one node along z.
///
/// The arrays span the whole box but take memory page by page as they are written
/// ([`PagedArray`]). A sparse grid ([`Grid::set_sparse`]) also tracks which blocks of
/// nodes the particles' stencils reach ([`GridActivity`]): only those are cleared,
/// updated and kept, so its work and memory follow the particles. A dense grid clears and
/// updates every node, for the solver modes whose operators write anywhere on the grid.
pub struct Grid<const D: usize> {
    /// Position of node (0, 0, 0).
    pub origin: Vector<D>,
    /// Cell size.
    pub dx: f64,
    /// 1 / dx.
    pub inv_dx: f64,
    /// Cells along each axis (1 for unused axes).
    pub cells: [usize; 3],
    /// Nodes along each axis (`cells + 1`, 1 for unused axes).
    pub nodes: [usize; 3],
    /// Index strides of the axes.
    pub stride: [usize; 3],
    /// Nodal mass.
    pub mass: PagedArray<f64>,
    /// Nodal momentum after P2G; the grid update turns it into velocity in place.
    pub momentum: PagedArray<Vector<D>>,
    /// Internal plus external force, kept apart from momentum only for FLIP (empty otherwise).
    pub force: PagedArray<Vector<D>>,
    /// Velocity before the momentum update, only for FLIP (empty otherwise).
    pub velocity_old: PagedArray<Vector<D>>,
    /// XPIC's extrapolated velocity, then its correction to the PIC velocity (empty unless
    /// `transfer: xpic`; [`Grid::enable_xpic`]).
    pub xpic_velocity: PagedArray<Vector<D>>,
    /// XPIC's scratch: one particle round trip S⁺S of `xpic_velocity` (empty unless XPIC).
    pub xpic_round_trip: PagedArray<Vector<D>>,
    /// The blocks in use, for a sparse grid (`None`: dense).
    activity: Option<GridActivity>,
    /// Node ranges released at once, reused.
    clear_ranges: Vec<Range<usize>>,
    /// Whether the grid was cleared since the marks were last taken.
    cleared: bool,
}

/// Nodes per unit of a dense grid's parallel loops.
const DENSE_CHUNK: usize = 4096;

impl<const D: usize> Grid<D> {
    /// A zeroed grid covering `[min, min + cells·dx]`; `flip` allocates the FLIP arrays.
    pub fn new(min: Vector<D>, cells: [usize; 3], dx: f64, flip: bool) -> Self {
        let mut nodes = [1usize; 3];
        for d in 0..D {
            nodes[d] = cells[d] + 1;
        }
        let stride = [nodes[1] * nodes[2], nodes[2], 1];
        let count = nodes[0] * nodes[1] * nodes[2];
        let extra = if flip { count } else { 0 };
        Self {
            origin: min,
            dx,
            inv_dx: 1.0 / dx,
            cells,
            nodes,
            stride,
            mass: PagedArray::zeroed(count),
            momentum: PagedArray::zeroed(count),
            force: PagedArray::zeroed(extra),
            velocity_old: PagedArray::zeroed(extra),
            xpic_velocity: PagedArray::zeroed(0),
            xpic_round_trip: PagedArray::zeroed(0),
            activity: None,
            clear_ranges: Vec::new(),
            cleared: true,
        }
    }

    /// Makes the grid sparse (only the blocks particles reach are cleared, updated and kept)
    /// or dense. Either way every node reads zero until the next P2G.
    pub fn set_sparse(&mut self, sparse: bool) {
        let len = self.len();
        for array in [
            &mut self.momentum,
            &mut self.force,
            &mut self.velocity_old,
            &mut self.xpic_velocity,
            &mut self.xpic_round_trip,
        ] {
            let n = array.len();
            array.release(0..n);
        }
        self.mass.release(0..len);
        self.activity = sparse.then(|| GridActivity::new(len));
        self.cleared = true;
    }

    /// Allocates XPIC's two node arrays (pages are taken as they are written).
    pub fn enable_xpic(&mut self) {
        let len = self.len();
        self.xpic_velocity = PagedArray::zeroed(len);
        self.xpic_round_trip = PagedArray::zeroed(len);
    }

    /// Whether the grid is sparse.
    pub fn is_sparse(&self) -> bool {
        self.activity.is_some()
    }

    /// Marks the blocks of nodes `range` as written (a sparse grid's P2G does this for every
    /// particle's stencil; [`Grid::take_marks`] then makes them the active ones); nothing for
    /// a dense grid. Thread-safe.
    #[inline(always)]
    pub fn mark(&self, range: Range<usize>) {
        if let Some(activity) = &self.activity {
            activity.mark(range);
        }
    }

    /// Whether node `index` is in use this step (always, on a dense grid).
    #[inline(always)]
    pub fn is_active(&self, index: usize) -> bool {
        self.activity.as_ref().is_none_or(|a| a.is_active(index))
    }

    /// Puts node `index`'s block in use this step, for a writer no stencil announced (a
    /// wall folding mass in front of it); its nodes hold zeros until written.
    pub fn activate(&mut self, index: usize) {
        if let Some(activity) = &mut self.activity {
            activity.activate(index);
        }
    }

    /// The units of the grid's node loops: every node of a dense grid falls in one, every
    /// node in use of a sparse one (elsewhere mass and momentum are zero and stay so).
    pub fn blocks(&self) -> NodeBlocks<'_> {
        NodeBlocks {
            activity: self.activity.as_ref(),
            len: self.len(),
        }
    }

    /// The blocks to loop over and the arrays, borrowed apart: the grid update writes
    /// velocities block by block.
    pub fn split_for_update(&mut self) -> GridArrays<'_, D> {
        GridArrays {
            blocks: NodeBlocks {
                activity: self.activity.as_ref(),
                len: self.mass.len(),
            },
            mass: &self.mass,
            momentum: &mut self.momentum,
            force: &self.force,
            velocity_old: &mut self.velocity_old,
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// Whether the grid has no nodes (never true for a built grid).
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Node index of integer coordinates.
    #[inline(always)]
    pub fn index(&self, ijk: [usize; 3]) -> usize {
        ijk[0] * self.stride[0] + ijk[1] * self.stride[1] + ijk[2]
    }

    /// Integer coordinates of a node index.
    #[inline(always)]
    pub fn coords(&self, index: usize) -> [usize; 3] {
        node_coords(&self.stride, index)
    }

    /// Position of a node.
    #[inline(always)]
    pub fn position(&self, ijk: [usize; 3]) -> Vector<D> {
        node_position(&self.origin, self.dx, ijk)
    }

    /// Zeroes the arrays P2G accumulates into. A sparse grid zeroes its active blocks (those
    /// the last transfers wrote): every other node is zero already.
    pub fn clear(&mut self) {
        use rayon::prelude::*;
        const CHUNK: usize = 1 << 14;
        self.take_marks();
        let Some(activity) = &self.activity else {
            self.mass.par_chunks_mut(CHUNK).for_each(|c| c.fill(0.0));
            self.momentum
                .par_chunks_mut(CHUNK)
                .for_each(|c| c.fill(Vector::<D>::zeros()));
            self.force
                .par_chunks_mut(CHUNK)
                .for_each(|c| c.fill(Vector::<D>::zeros()));
            return;
        };
        self.cleared = true;
        // The blocks written since the last clear are this step's active ones: zero them in
        // parallel.
        let blocks = NodeBlocks {
            activity: Some(activity),
            len: self.mass.len(),
        };
        let flip = !self.force.is_empty();
        let zero = Vector::<D>::zeros();
        let mass = SharedSlice::new(&mut self.mass);
        let momentum = SharedSlice::new(&mut self.momentum);
        let force = SharedSlice::new(&mut self.force);
        (0..blocks.count()).into_par_iter().for_each(|k| {
            let range = blocks.range(k);
            // SAFETY: the blocks are distinct, so no two tasks touch one node.
            unsafe {
                mass.range(range.clone()).fill(0.0);
                momentum.range(range.clone()).fill(zero);
                if flip {
                    force.range(range).fill(zero);
                }
            }
        });
    }

    /// On a sparse grid, after a transfer: the blocks it marked become the active ones, and
    /// the blocks active before but not written now (zero since the clear) give their pages
    /// back; after a transfer that followed no clear, its blocks join those in use. Nothing
    /// on a dense grid, or when nothing was marked since the last call.
    pub fn take_marks(&mut self) {
        let Some(activity) = &mut self.activity else {
            return;
        };
        if !activity.has_marks() {
            return;
        }
        // After a clear the marks are the step's blocks; without one (MUSL's second
        // transfer) they join the blocks already in use, whose mass is still there.
        let replace = std::mem::take(&mut self.cleared);
        let ranges = &mut self.clear_ranges;
        ranges.clear();
        activity.begin_step(replace, |range, kept| {
            if kept {
                return;
            }
            match ranges.last_mut() {
                Some(last) if last.end == range.start => last.end = range.end,
                _ => ranges.push(range),
            }
        });
        let flip = !self.force.is_empty();
        for range in &self.clear_ranges {
            self.mass.release(range.clone());
            self.momentum.release(range.clone());
            if flip {
                self.force.release(range.clone());
                self.velocity_old.release(range.clone());
            }
            if !self.xpic_velocity.is_empty() {
                self.xpic_velocity.release(range.clone());
                self.xpic_round_trip.release(range.clone());
            }
        }
    }

    /// Zeroes the momentum of every node in use (MUSL's second transfer keeps the mass).
    pub fn clear_momentum(&mut self) {
        let zero = Vector::<D>::zeros();
        let view = self.split_for_update();
        for k in 0..view.blocks.count() {
            view.momentum[view.blocks.range(k)].fill(zero);
        }
    }

    /// Bytes the grid arrays take: all of them for a dense grid; for a sparse one, the
    /// largest number of blocks in use at once so far, and the tracking.
    pub fn bytes(&self) -> usize {
        let per_node = 8
            + (usize::from(!self.momentum.is_empty())
                + usize::from(!self.force.is_empty())
                + usize::from(!self.velocity_old.is_empty())
                + 2 * usize::from(!self.xpic_velocity.is_empty()))
                * std::mem::size_of::<Vector<D>>();
        match &self.activity {
            None => self.len() * per_node,
            Some(a) => a.peak_blocks() * BLOCK_NODES * per_node + a.bytes(),
        }
    }
}

/// The units of a grid's node loops ([`Grid::blocks`]).
#[derive(Clone, Copy)]
pub struct NodeBlocks<'a> {
    activity: Option<&'a GridActivity>,
    len: usize,
}

impl NodeBlocks<'_> {
    /// Number of units.
    pub fn count(&self) -> usize {
        match self.activity {
            Some(a) => a.active_blocks(),
            None => self.len.div_ceil(DENSE_CHUNK),
        }
    }

    /// Node range of unit `k`.
    #[inline(always)]
    pub fn range(&self, k: usize) -> Range<usize> {
        match self.activity {
            Some(a) => a.active_range(k),
            None => k * DENSE_CHUNK..((k + 1) * DENSE_CHUNK).min(self.len),
        }
    }
}

/// A grid's arrays and loop units borrowed apart ([`Grid::split_for_update`]).
pub struct GridArrays<'a, const D: usize> {
    /// The units of the node loops.
    pub blocks: NodeBlocks<'a>,
    /// Nodal mass.
    pub mass: &'a [f64],
    /// Nodal momentum, turned into velocity.
    pub momentum: &'a mut [Vector<D>],
    /// FLIP forces (empty otherwise).
    pub force: &'a [Vector<D>],
    /// FLIP's velocity before the update (empty otherwise).
    pub velocity_old: &'a mut [Vector<D>],
}

/// Integer coordinates of node `index` for index strides `stride`.
#[inline(always)]
pub fn node_coords(stride: &[usize; 3], index: usize) -> [usize; 3] {
    let i = index / stride[0];
    let rem = index % stride[0];
    [i, rem / stride[1], rem % stride[1]]
}

/// Position of node `ijk` of a grid with node (0, 0, 0) at `origin` and cell size `dx`.
#[inline(always)]
pub fn node_position<const D: usize>(origin: &Vector<D>, dx: f64, ijk: [usize; 3]) -> Vector<D> {
    let mut x = *origin;
    for d in 0..D {
        x[d] += ijk[d] as f64 * dx;
    }
    x
}
