//! The background grid: a dense box of nodes holding mass and momentum (then velocity).

use crate::math::Vector;

/// Dense nodal storage. Node `(i, j, k)` is at `origin + (i, j, k)·dx` and lives at index
/// `i·stride[0] + j·stride[1] + k`; 2D grids have one node along z.
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
    pub mass: Vec<f64>,
    /// Nodal momentum after P2G; the grid update turns it into velocity in place.
    pub momentum: Vec<Vector<D>>,
    /// Internal plus external force, kept apart from momentum only for FLIP (empty otherwise).
    pub force: Vec<Vector<D>>,
    /// Velocity before the momentum update, only for FLIP (empty otherwise).
    pub velocity_old: Vec<Vector<D>>,
}

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
            mass: vec![0.0; count],
            momentum: vec![Vector::<D>::zeros(); count],
            force: vec![Vector::<D>::zeros(); extra],
            velocity_old: vec![Vector::<D>::zeros(); extra],
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

    /// Zeroes the arrays P2G accumulates into.
    pub fn clear(&mut self) {
        use rayon::prelude::*;
        const CHUNK: usize = 1 << 14;
        self.mass.par_chunks_mut(CHUNK).for_each(|c| c.fill(0.0));
        self.momentum
            .par_chunks_mut(CHUNK)
            .for_each(|c| c.fill(Vector::<D>::zeros()));
        self.force
            .par_chunks_mut(CHUNK)
            .for_each(|c| c.fill(Vector::<D>::zeros()));
    }

    /// Bytes held by the grid arrays.
    pub fn bytes(&self) -> usize {
        self.mass.capacity() * 8
            + (self.momentum.capacity() + self.force.capacity() + self.velocity_old.capacity())
                * std::mem::size_of::<Vector<D>>()
    }
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
