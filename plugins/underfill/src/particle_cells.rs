//! The grid's cells as liquid particles see them (`physics.liquid_voids`): closed (outside
//! the domain, behind a wall, inside an obstacle or a held body: the die, substrate and
//! bumps of a fill are held obstacles, `scene::held_bodies`), liquid (holding a liquid
//! particle) or air. Air regions are what the void tracker labels; the fill region is timed on them.

use crate::voids::AirCells;

/// The grid's cells as air, liquid or closed. `closed` and `vented` are fixed for the run;
/// `liquid` is set from the particles at each labelling.
pub(crate) struct GridCells {
    /// Cells per axis (1 past the scene's dimension).
    pub n: [usize; 3],
    /// Cell size, m.
    pub dx: f64,
    /// Corner of cell 0, m.
    pub origin: [f64; 3],
    /// The scene's dimension.
    pub dimension: usize,
    /// Outside the domain, behind a wall or inside an obstacle.
    pub closed: Vec<bool>,
    /// On a vent face.
    pub vented: Vec<bool>,
    /// Holds a liquid particle.
    pub liquid: Vec<bool>,
}

impl GridCells {
    /// `n` cells of size `dx` from `origin`, none closed, vented or liquid.
    pub fn new(n: [usize; 3], dx: f64, origin: [f64; 3], dimension: usize) -> Self {
        let count = n.iter().product();
        Self {
            n,
            dx,
            origin,
            dimension,
            closed: vec![false; count],
            vented: vec![false; count],
            liquid: vec![false; count],
        }
    }

    /// The cell indices of cell `c` along each axis.
    pub fn coords(&self, c: usize) -> [usize; 3] {
        [
            c % self.n[0],
            (c / self.n[0]) % self.n[1],
            c / (self.n[0] * self.n[1]),
        ]
    }

    fn index(&self, ijk: [usize; 3]) -> usize {
        ijk[0] + self.n[0] * (ijk[1] + self.n[1] * ijk[2])
    }

    /// The centre of cell `c`, m (0 past the scene's dimension).
    pub fn centre(&self, c: usize) -> [f64; 3] {
        let ijk = self.coords(c);
        [0, 1, 2].map(|a| {
            if a < self.dimension {
                self.origin[a] + (ijk[a] as f64 + 0.5) * self.dx
            } else {
                0.0
            }
        })
    }

    /// The cell holding position `x`, if on the grid.
    pub fn cell_of(&self, x: &[f64]) -> Option<usize> {
        let mut ijk = [0usize; 3];
        for (a, &xa) in x.iter().enumerate() {
            let s = ((xa - self.origin[a]) / self.dx).floor();
            if !(s >= 0.0 && (s as usize) < self.n[a]) {
                return None;
            }
            ijk[a] = s as usize;
        }
        Some(self.index(ijk))
    }

    /// Whether liquid may stand in cell `c`: not closed.
    pub fn is_open(&self, c: usize) -> bool {
        !self.closed[c]
    }

    /// The measure of one cell: its area in a plane scene, its volume in 3D.
    pub fn measure(&self) -> f64 {
        self.dx.powi(self.dimension as i32)
    }
}

impl AirCells for GridCells {
    fn len(&self) -> usize {
        self.closed.len()
    }

    fn is_air(&self, c: usize) -> bool {
        self.is_open(c) && !self.liquid[c]
    }

    fn vented(&self, c: usize) -> bool {
        self.vented[c]
    }

    fn air(&self, c: usize) -> (f64, f64, [f64; 3]) {
        (self.measure(), self.measure(), self.centre(c))
    }

    fn for_each_neighbour(&self, c: usize, mut f: impl FnMut(usize)) {
        let ijk = self.coords(c);
        for a in 0..self.dimension {
            let stride = [1, self.n[0], self.n[0] * self.n[1]][a];
            if ijk[a] > 0 {
                f(c - stride);
            }
            if ijk[a] + 1 < self.n[a] {
                f(c + stride);
            }
        }
    }
}
