//! The volume source (scenes with inlets or enclosed air, or `volume_correction`): a cell
//! whose particles' volume differs from its own gives (or takes) a share of the difference
//! through the pressure equation's right-hand side. The divergence-free projection alone
//! keeps the grid velocity's divergence zero, not the particles' volume per cell, so
//! entering particles pile up at an inlet, the liquid's particles cluster (mod.rs,
//! inflow.rs), and a liquid pulled by a meniscus thins (a capillary fill).
//!
//! The share is per velocity-CFL step (the step the flow alone would take at the scene's
//! `cfl`, or at `SOURCE_CFL` if that is larger): a shorter step (a capillary or viscous
//! bound, a frame time, a `cfl` under `SOURCE_CFL`) gives less, in proportion, so the
//! correction's velocity does not grow as 1/dt. With implicit viscosity the projection is
//! incremental and the source's right-hand side is also kept apart, solved on its own and
//! left out of the pressure that comes back as next step's force (`incremental_pressure`).

use super::Incompressible;
use super::{cell_of, moving_rows};
use crate::boundary::Boundaries;
use crate::grid::{Grid, node_coords, node_position};
use crate::math::Vector;
use crate::particles::Particles;

/// Share of a cell's excess particle volume the pressure equation removes per velocity-CFL
/// step.
pub(super) const VOLUME_CORRECTION: f64 = 0.3;

/// The least CFL number of the velocity-CFL step the share is given per (the default
/// `cfl`): a scene with a smaller `cfl` does not correct faster in time. At `cfl` 0.1 a
/// share per step of its own closed a gap of one cell in a few steps at several times the
/// flow's speed, and those speeds shrank the step until it collapsed.
pub(super) const SOURCE_CFL: f64 = 0.3;

impl<const D: usize> Incompressible<D> {
    /// Adds the source to the right-hand side (and, when `source_solved`, to its own);
    /// `rate` = min(1, dt / velocity-CFL step).
    pub(super) fn add_volume_source(
        &mut self,
        grid: &Grid<D>,
        particles: &Particles<D>,
        dt: f64,
        rate: f64,
    ) {
        let dx = grid.dx;
        let corners = 1 << D;
        if self.source_solved {
            self.source_rhs.resize(self.rhs.len(), 0.0);
            self.source_rhs.fill(0.0);
            self.source_pressure.resize(self.rhs.len(), 0.0);
        }
        let share = rate / (corners as f64 * dt * dt);
        self.source_volume.resize(self.rhs.len(), 0.0);
        self.source_volume.fill(0.0);
        self.count_volume(grid, particles);
        for c in 0..self.cell_volume.len() {
            if let Some(volume) = self.volume_source(c, dx) {
                let base = self.cell_node[c];
                for a in 0..corners {
                    let node = base + self.corner_offset[a];
                    self.rhs[node] += volume * share;
                    self.source_volume[node] += volume * rate / corners as f64;
                    if self.source_solved {
                        self.source_rhs[node] += volume * share;
                    }
                }
            }
        }
        self.balance_sealed_regions(dt);
        if self.source_solved {
            self.leave_out_inherited_source(dt);
        }
    }

    /// Takes the last step's source out of the source's own right-hand side. The velocity
    /// that source gave the liquid comes back through the particles with its divergence,
    /// and this step's projection takes that divergence away again (and the source puts in
    /// its own). The pressure that takes it away belongs to the source too: kept as the
    /// liquid's (implicit viscosity's `incremental_pressure`), it grew as 1/dt, and a step
    /// cut short to land on a frame time kept 12 kPa at an inlet's corner that the next
    /// step applied as a force, inverting a particle (the inflow tank with 20 frames at
    /// 0.06 s, stop 83; it still inverts one at 0.42 s, after the inlet closes).
    fn leave_out_inherited_source(&mut self, dt: f64) {
        let n = self.source_volume.len();
        if self.last_source_rate.len() == n {
            for (rhs, last) in self.source_rhs.iter_mut().zip(&self.last_source_rate) {
                *rhs -= last / dt;
            }
        }
        self.last_source_rate.clear();
        self.last_source_rate
            .extend(self.source_volume.iter().map(|v| v / dt));
    }

    /// Takes each sealed liquid region's net source out of it: a region whose free nodes
    /// reach no node of fixed pressure (no free surface, no gas pocket), walled all round,
    /// has a pressure equation that only a right-hand side summing to zero over it can
    /// satisfy. The projection's own divergence does (no flux through walls); the source's
    /// need not, and CG then broke down (the capillary rise's pressure solve at 0.53 s with
    /// `volume_correction`). Such a region keeps the source's redistribution within it.
    fn balance_sealed_regions(&mut self, dt: f64) {
        let corners = 1 << D;
        let nodes = self.source_volume.len();
        let b = &mut self.balance;
        b.root.clear();
        b.root.extend(0..nodes);
        b.anchored.clear();
        b.anchored.resize(nodes, false);
        b.sum.clear();
        b.sum.resize(nodes, 0.0);
        b.count.clear();
        b.count.resize(nodes, 0);
        let free = |i: usize| self.inverse_diagonal[i] > 0.0;
        // Free nodes joined through the liquid cells they share.
        for c in 0..self.cell_volume.len() {
            if self.cell_volume[c] <= 0.0 {
                continue;
            }
            let base = self.cell_node[c];
            let mut first = None;
            for a in 0..corners {
                let i = base + self.corner_offset[a];
                if free(i) {
                    match first {
                        None => first = Some(i),
                        Some(f) => b.join(f, i),
                    }
                }
            }
        }
        // A region with a liquid cell on a node of fixed pressure is anchored.
        for c in 0..self.cell_volume.len() {
            if self.cell_volume[c] <= 0.0 {
                continue;
            }
            let base = self.cell_node[c];
            let corner = |a: usize| base + self.corner_offset[a];
            if let Some(f) = (0..corners).map(corner).find(|&i| free(i))
                && (0..corners).map(corner).any(|i| !free(i))
            {
                let r = b.find(f);
                b.anchored[r] = true;
            }
        }
        for i in (0..nodes).filter(|&i| free(i)) {
            let r = b.find(i);
            b.sum[r] += self.source_volume[i];
            b.count[r] += 1;
        }
        for i in (0..nodes).filter(|&i| free(i)) {
            let r = b.find(i);
            if b.anchored[r] || b.sum[r] == 0.0 {
                continue;
            }
            let mean = b.sum[r] / f64::from(b.count[r]);
            self.source_volume[i] -= mean;
            // The right-hand side took the volume over dt² (the share's 1/(2^D·dt²) on
            // the rate's volume / 2^D per corner).
            let rate_to_rhs = 1.0 / (dt * dt);
            self.rhs[i] -= mean * rate_to_rhs;
            if self.source_solved {
                self.source_rhs[i] -= mean * rate_to_rhs;
            }
        }
    }

    /// The work the pressure does through this step's source: Σ_i p_i ΔV_i over the nodes,
    /// ΔV_i their share of the volume the source lets the cells gain (or lose) in the step
    /// and p_i the total pressure just solved for (with implicit viscosity the increment
    /// plus the pressure kept from the last step), J (J/m in 2D). The kinetic energy
    /// equation's ∫ p ∇·v dV, which a divergence-free velocity does not have.
    pub(super) fn volume_source_work(&self) -> f64 {
        let kept = |i: usize| {
            self.viscosity
                .as_ref()
                .map_or(0.0, |v| v.kept_in_velocity(i))
        };
        self.source_volume
            .iter()
            .enumerate()
            .filter(|(_, dv)| **dv != 0.0)
            .map(|(i, dv)| (self.pressure[i] + kept(i)) * dv)
            .sum()
    }

    /// Fills `SourceCells::counted`: each cell's particle volume, every particle's spread
    /// over the 2^D cells whose centres surround it with linear (tent) weights, so that a
    /// particle crossing a cell face moves its volume over gradually. Counted whole in the
    /// cell it sits in, a crossing changed two cells by a particle's volume at once (a
    /// quarter of a cell at 2 per axis in 2D), and the source answered that noise with
    /// currents of mm/s that never settled: a capillary column stirred, short of Jurin's
    /// height (stop 83). A share falling behind a wall or outside the grid counts in the
    /// cell in front (the cell's `cell_home`), one in an obstacle's cell in the open cell
    /// in front of its surface (`SourceCells::home`): left out, that cell looked short of
    /// volume, and the source drew the liquid after the particles (a 3D bump, stop 82).
    /// A share falling in a cell without liquid counts in the particle's own cell, as at a
    /// wall: left out, a crowded free surface looked less full than it was and stayed
    /// crowded.
    fn count_volume(&mut self, grid: &Grid<D>, particles: &Particles<D>) {
        let cells = &mut self.source_cells;
        cells.counted.clear();
        cells.counted.resize(self.cell_volume.len(), 0.0);
        for i in moving_rows(particles) {
            let x = &particles.position[i];
            let mut low = [0usize; 3];
            let mut high = [0usize; 3];
            let mut weight = [[0.0; 2]; 3];
            for d in 0..D {
                let s = (x[d] - grid.origin[d]) * grid.inv_dx - 0.5;
                let last = grid.cells[d] as f64 - 1.0;
                let base = s.floor();
                let f = (s - base).clamp(0.0, 1.0);
                low[d] = base.clamp(0.0, last.max(0.0)) as usize;
                high[d] = (base + 1.0).clamp(0.0, last.max(0.0)) as usize;
                weight[d] = [1.0 - f, f];
            }
            let own = cells.home[self.cell_home[cell_of(grid, x).0]];
            for corner in 0..1usize << D {
                let mut c = 0;
                let mut w = particles.volume0[i];
                for d in 0..D {
                    let up = corner >> d & 1;
                    c = c * grid.cells[d] + if up == 1 { high[d] } else { low[d] };
                    w *= weight[d][up];
                }
                let c = cells.home[self.cell_home[c]];
                let c = if self.cell_volume[c] > 0.0 { c } else { own };
                cells.counted[c] += w;
            }
        }
    }

    /// The volume cell `c` is to give (or take, negative) in a velocity-CFL step: the share
    /// `VOLUME_CORRECTION` of the difference between its spread particle volume and its
    /// open volume (`SourceCells::open`: a cell an obstacle cuts is full with less), in
    /// cells inside the liquid (every corner a pressure unknown), and only what it holds
    /// too much in cells on the free surface. None in a solid cell (an obstacle's or a held
    /// body's): the few particles that stray into one would have it take volume until it
    /// was full, drawing the liquid into the solid.
    fn volume_source(&self, c: usize, dx: f64) -> Option<f64> {
        if self.cell_solid[c] || self.cell_volume[c] <= 0.0 {
            return None;
        }
        let corners = 1 << D;
        let base = self.cell_node[c];
        let inside =
            (0..corners).all(|a| self.inverse_diagonal[base + self.corner_offset[a]] > 0.0);
        let cells = &self.source_cells;
        let excess = cells.counted[c] - cells.open[c] * dx.powi(D as i32);
        (inside || excess > 0.0).then_some(VOLUME_CORRECTION * excess)
    }
}

/// The cells beside obstacles as the volume source sees them, set once per grid.
#[derive(Default)]
pub(super) struct SourceCells {
    /// Per cell: the share of its volume outside walls and obstacles, the volume the
    /// source fills it to ([`open_fractions`]).
    open: Vec<f64>,
    /// Per cell: the cell a particle in it counts in ([`obstacle_homes`]).
    home: Vec<usize>,
    /// Per cell: the particle volume the source counts (the cells' volume with the
    /// obstacles' cells' moved to their `home`), m³ (m² in 2D); scratch.
    counted: Vec<f64>,
}

impl SourceCells {
    /// The open shares and homes of the cells with lowest corners `cell_node`, `solid`
    /// the incompressible mode's solid cells.
    pub(super) fn new<const D: usize>(
        grid: &Grid<D>,
        boundaries: &Boundaries<D>,
        cell_node: &[usize],
        solid: &[bool],
    ) -> Self {
        Self {
            open: open_fractions(grid, boundaries, cell_node, solid),
            home: obstacle_homes(grid, boundaries, cell_node, solid),
            counted: Vec::new(),
        }
    }
}

/// Sub-cells per axis at which [`open_fractions`] samples a cell an obstacle's surface
/// cuts.
const OPEN_SAMPLES: usize = 4;

/// Per cell (lowest corner `cell_node`), the share of its volume outside the obstacles
/// (solid bodies held in place among them): 0 in `solid` cells behind a wall, 1 where no
/// obstacle's surface comes within the cell's half diagonal of its centre, otherwise the
/// share of its `OPEN_SAMPLES`^D sub-cells whose centres lie outside every obstacle.
pub(super) fn open_fractions<const D: usize>(
    grid: &Grid<D>,
    boundaries: &Boundaries<D>,
    cell_node: &[usize],
    solid: &[bool],
) -> Vec<f64> {
    let reach = 0.5 * (D as f64).sqrt() * grid.dx;
    let samples = OPEN_SAMPLES.pow(D as u32);
    cell_node
        .iter()
        .zip(solid)
        .map(|(&node, &solid)| {
            let ijk = node_coords(&grid.stride, node);
            if boundaries.cell_is_behind_wall(ijk) {
                return 0.0;
            }
            let corner = node_position(&grid.origin, grid.dx, ijk);
            let centre = corner.add_scalar(0.5 * grid.dx);
            let distance = boundaries.obstacle_distance(&centre);
            if distance.abs() >= reach {
                return if solid { 0.0 } else { 1.0 };
            }
            let open = (0..samples)
                .filter(|&k| {
                    let mut rest = k;
                    let x = Vector::<D>::from_fn(|a, _| {
                        let i = rest % OPEN_SAMPLES;
                        rest /= OPEN_SAMPLES;
                        corner[a] + (i as f64 + 0.5) / OPEN_SAMPLES as f64 * grid.dx
                    });
                    boundaries.obstacle_distance(&x) >= 0.0
                })
                .count();
            open as f64 / samples as f64
        })
        .collect()
}

/// Per cell (lowest corner `cell_node`), the cell the volume source counts its particles
/// in: for a `solid` cell whose centre lies inside an obstacle, the first open cell
/// (inside the grid) half a cell, one or one and a half cells in front of the obstacle's
/// surface along its normal from the centre; for every other cell, and when none of those
/// is open, itself.
pub(super) fn obstacle_homes<const D: usize>(
    grid: &Grid<D>,
    boundaries: &Boundaries<D>,
    cell_node: &[usize],
    solid: &[bool],
) -> Vec<usize> {
    let index = |ijk: [usize; 3]| (0..D).fold(0, |c, d| c * grid.cells[d] + ijk[d]);
    cell_node
        .iter()
        .zip(solid)
        .enumerate()
        .map(|(c, (&node, &inside))| {
            let ijk = node_coords(&grid.stride, node);
            if !inside || boundaries.cell_is_behind_wall(ijk) {
                return c;
            }
            let centre = node_position(&grid.origin, grid.dx, ijk).add_scalar(0.5 * grid.dx);
            let Some((distance, normal)) = boundaries.nearest_obstacle(&centre) else {
                return c;
            };
            // Half a cell past the surface first; a cell whose centre is still inside
            // (the surface cuts it) sends the particles a half cell further, twice at most.
            (1..=3)
                .find_map(|k| {
                    let front = centre + normal * (0.5 * k as f64 * grid.dx - distance);
                    let mut home = [0usize; 3];
                    for d in 0..D {
                        let i = ((front[d] - grid.origin[d]) * grid.inv_dx).floor();
                        if !(i >= 0.0 && i < grid.cells[d] as f64) {
                            return None;
                        }
                        home[d] = i as usize;
                    }
                    let h = index(home);
                    (!solid[h]).then_some(h)
                })
                .unwrap_or(c)
        })
        .collect()
}

/// Scratch of [`Incompressible::balance_sealed_regions`], kept between steps: a union-find
/// over the nodes, and per region whether it is anchored, its source and its node count.
#[derive(Default)]
pub(super) struct SourceBalance {
    root: Vec<usize>,
    anchored: Vec<bool>,
    sum: Vec<f64>,
    count: Vec<u32>,
}

impl SourceBalance {
    /// The region of node `i` (path halving).
    fn find(&mut self, mut i: usize) -> usize {
        while self.root[i] != i {
            self.root[i] = self.root[self.root[i]];
            i = self.root[i];
        }
        i
    }

    /// Whether free node `i` lies in a region the last balance found sealed (no node of
    /// fixed pressure, no gas pocket): no flux can enter it.
    pub(super) fn is_sealed(&mut self, i: usize) -> bool {
        if self.root.len() <= i {
            return false;
        }
        let r = self.find(i);
        !self.anchored[r]
    }

    /// Puts nodes `i` and `j` in one region.
    fn join(&mut self, i: usize, j: usize) {
        let (a, b) = (self.find(i), self.find(j));
        if a != b {
            self.root[a] = b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::IncompressibleSettings;

    #[test]
    fn a_cell_a_disc_cuts_is_open_by_its_share_outside_it_and_one_inside_counts_in_front() {
        // A disc of radius 0.23 m centred in a 1 m square of 10 × 10 cells: the open area
        // is 1 − π·0.23² = 0.83381 m²; sampled at 4 × 4 points in each cut cell it comes
        // within half a cell's area (0.005 m²).
        let grid = Grid::<2>::new(Vector::<2>::zeros(), [10, 10, 0], 0.1, false);
        let disc: crate::scene::Obstacle = serde_json::from_value(serde_json::json!({
            "shape": {"sphere": {"center": [0.5, 0.5], "radius": 0.23}},
            "condition": "slip"
        }))
        .unwrap();
        let boundaries = Boundaries::<2>::new(&[], &[disc], [10, 10, 0]);
        let cell_node: Vec<usize> = (0..10)
            .flat_map(|i| (0..10).map(move |j| i * grid.stride[0] + j * grid.stride[1]))
            .collect();
        let solid: Vec<bool> = cell_node
            .iter()
            .map(|&n| {
                let ijk = node_coords(&grid.stride, n);
                let centre = node_position(&grid.origin, grid.dx, ijk).add_scalar(0.05);
                boundaries.cell_is_solid(ijk, &centre)
            })
            .collect();
        let open = open_fractions(&grid, &boundaries, &cell_node, &solid);
        let area: f64 = open.iter().sum::<f64>() * 0.01;
        let exact = 1.0 - std::f64::consts::PI * 0.23 * 0.23;
        assert!((area - exact).abs() < 0.005, "{area} against {exact}");
        // Cell (0, 0) is clear of the disc, cells (4..6, 4..6) lie inside it, and cell
        // (2, 5) (x from 0.2 to 0.3 m, the disc's edge at 0.27 m) is cut.
        assert_eq!(open[0], 1.0);
        assert_eq!(open[4 * 10 + 4], 0.0);
        assert!(
            open[2 * 10 + 5] > 0.5 && open[2 * 10 + 5] < 1.0,
            "{}",
            open[25]
        );
        // A cell inside the disc counts its strays in an open cell in front of it: cell
        // (4, 4), whose neighbour (3, 3) towards the surface is cut but solid, in (2, 2);
        // an open cell in itself.
        let home = obstacle_homes(&grid, &boundaries, &cell_node, &solid);
        assert!(solid[3 * 10 + 3]);
        assert_eq!(home[4 * 10 + 4], 2 * 10 + 2);
        assert_eq!(home[3 * 10 + 3], 2 * 10 + 2);
        assert_eq!(home[0], 0);
        assert_eq!(home[2 * 10 + 5], 2 * 10 + 5);
    }

    #[test]
    fn a_sealed_region_keeps_no_net_source_and_an_open_one_keeps_its_own() {
        // A row of four 2D cells, nodes two high (node = 2·x + y). Cell 0 is liquid with
        // every corner free: sealed. Cell 3 is liquid with its two right corners of fixed
        // pressure (a free surface): anchored. Cells 1 and 2 hold no liquid.
        let mut p = Incompressible::<2>::new(IncompressibleSettings::default());
        p.corner_offset[..4].copy_from_slice(&[0, 1, 2, 3]);
        p.cell_node = vec![0, 2, 4, 6];
        p.cell_volume = vec![1.0, 0.0, 0.0, 1.0];
        p.inverse_diagonal = vec![1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0];
        p.source_volume = vec![1.0, 2.0, 3.0, 4.0, 0.0, 0.0, 5.0, 6.0, 0.0, 0.0];
        let dt = 0.5;
        p.rhs = p.source_volume.iter().map(|v| v / (dt * dt)).collect();
        p.balance_sealed_regions(dt);
        // The sealed cell's source, 10 over four nodes, loses its mean of 2.5.
        assert_eq!(&p.source_volume[..4], &[-1.5, -0.5, 0.5, 1.5]);
        assert_eq!(&p.rhs[..4], &[-6.0, -2.0, 2.0, 6.0]);
        // The anchored cell keeps its source.
        assert_eq!(&p.source_volume[6..8], &[5.0, 6.0]);
        assert_eq!(&p.rhs[6..8], &[20.0, 24.0]);
    }
}
