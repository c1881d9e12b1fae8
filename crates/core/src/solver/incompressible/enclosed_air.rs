//! Air the liquid encloses (`solver.mechanics.incompressible.enclosed_air`): a pocket of
//! air cut off from every open domain face is an isothermal ideal gas that resists being
//! filled, instead of free surface at zero pressure.
//!
//! Each step the empty cells (no particle, not solid) are split into regions; two empty
//! cells that share a grid node belong to one region, so no node touches two of them. A
//! region that reaches the grid's edge through an open face (the padding beyond a walled
//! face is solid) is open air. A closed one holds gas: the amount p·V it had last step
//! (shared out over the regions its cells went to, in proportion to cells, so pockets that
//! split or merge keep their gas, and gas that reaches open air is gone) plus the ambient
//! pressure times the cells that were open air (a pocket closing). A region of liquid cells
//! torn open, with no gas, and a pocket of fewer than `min_cells` cells (it keeps its gas
//! for when it grows) are gaps: they have a pressure unknown like a pocket's, but no gas
//! that resists (C = 0) and a target volume of 0, so the liquid closes them at the volume
//! source's pace and their pressure is the liquid's around them. As free surface at gauge
//! 0 they were sinks inside liquid a compressed pocket pressurises (an inlet filling a
//! sealed box inverted a particle within 45 ms).
//!
//! The nodes around a pocket share one pressure unknown P_k (plus the surface-tension
//! Laplace pressure each node has on its own), the pocket's row being the sum of its nodes'
//! rows: with φ = Σ_{i ∈ pocket} N_i that row says the liquid's volume flux into the pocket
//! within the step, ∫∇φ·v dt, is what the gas gives up at the new pressure (Boyle,
//! linearised: V·(P − P_last)/p_abs) plus a share of the difference between the pocket's
//! measured volume and the gas's own V = n/p_abs (the same share per velocity-CFL step as
//! the inflow's volume source, so that particles drifting into a pocket are pushed out
//! again and the gas's volume follows the cells over many steps, not in one jolt):
//! Σ_i (A p)_i + C P_k = Σ_i b_i + C P_last − (share/dt²)(V_measured − V), C = V/(p_abs·dt²).
//! C > 0 keeps the system symmetric positive definite even in a box with every face walled
//! (a gap's C = 0 leaves it positive semi-definite where a liquid region touches neither
//! free surface nor gas: in a box walled all round and full, gaps keep their volume, so
//! that the system stays consistent).
//! The measured volume is the pocket's cells plus what the liquid cells around it lack of a
//! full cell, so a surface row half full counts half.
//!
//! A checkpoint forgets the pockets' history (the writing run and the resumed one alike):
//! each pocket starts again from the ambient pressure and its measured volume.

use crate::grid::Grid;
use crate::scene::EnclosedAirSettings;

/// No region (a liquid or solid cell), no pocket (a node no pocket ties).
const NONE: u32 = u32::MAX;
/// Last step's label of a cell that was open air.
const OPEN: u32 = u32::MAX - 1;

/// One empty region of this step.
#[derive(Clone, Copy, Debug, Default)]
struct Region {
    cells: usize,
    open: bool,
    /// Gas amount p_abs·V (Pa·m^D) and the gas's own volume V = n/p_abs.
    gas: f64,
    volume: f64,
    /// Index among this step's pocket unknowns, or `NONE`.
    unknown: u32,
    /// Index among the carried pockets (closed with gas), or `NONE`.
    carried: u32,
}

/// A pocket with gas, carried from one step to the next.
#[derive(Clone, Copy, Debug, Default)]
struct Pocket {
    gas: f64,
    volume: f64,
    /// Cells of this step's regions its cells went to (filled in the next step).
    reached: usize,
}

/// One pocket pressure unknown of this step's solve.
#[derive(Clone, Copy, Debug, Default)]
struct Unknown {
    region: u32,
    /// C = V/(p_abs·dt²) and the diagonal of the pocket's row for the preconditioner.
    compliance: f64,
    diagonal: f64,
    /// Measured volume: the region's cells plus the neighbouring liquid cells' shortfall.
    measured: f64,
    /// A gap, not a gas pocket: it holds no gas, or fewer cells than `min_cells`.
    gap: bool,
    /// The volume share's part of its right-hand side (the volume source's, for the
    /// source's own solve with implicit viscosity).
    source: f64,
}

/// The enclosed air's state and workspace (sized on the first step, reused).
pub(super) struct EnclosedAir {
    settings: EnclosedAirSettings,
    /// Per cell: this step's region, or `NONE`.
    region: Vec<u32>,
    /// Per cell: last step's carried pocket, `OPEN` for open air, or `NONE`.
    before: Vec<u32>,
    /// Per node: this step's pocket unknown that ties it, or `NONE`.
    tie: Vec<u32>,
    /// The tied nodes and their unknowns, in node order (the operator's pocket rows read
    /// these every CG iteration, not the whole `tie`).
    tied_nodes: Vec<(usize, u32)>,
    regions: Vec<Region>,
    pockets: Vec<Pocket>,
    next_pockets: Vec<Pocket>,
    unknowns: Vec<Unknown>,
    stack: Vec<usize>,
    /// The pockets' history is unknown (first step, after a checkpoint).
    fresh: bool,
    /// This step has open air or a gas pocket, so the liquid's volume can go somewhere
    /// and gaps may close; in a full box walled all round they keep their volume.
    anchored: bool,
}

impl EnclosedAir {
    pub(super) fn new(settings: EnclosedAirSettings) -> Self {
        Self {
            settings,
            region: Vec::new(),
            before: Vec::new(),
            tie: Vec::new(),
            tied_nodes: Vec::new(),
            regions: Vec::new(),
            pockets: Vec::new(),
            next_pockets: Vec::new(),
            unknowns: Vec::new(),
            stack: Vec::new(),
            fresh: true,
            anchored: false,
        }
    }

    /// Forgets the pockets' history (a checkpoint is written: the resumed run has none).
    pub(super) fn forget(&mut self) {
        self.fresh = true;
    }

    /// Number of pocket unknowns this step (appended after the nodes in the solve).
    pub(super) fn unknowns(&self) -> usize {
        self.unknowns.len()
    }

    /// This step's gas pockets and gaps (closed regions solved as closing).
    pub(super) fn counts(&self) -> (usize, usize) {
        let gaps = self.unknowns.iter().filter(|u| u.gap).count();
        (self.unknowns.len() - gaps, gaps)
    }

    /// Finds this step's regions and pockets and ties the pockets' nodes. `cell_volume`
    /// is the particles' volume per cell (0: empty), `cell_node` the lowest corner node of
    /// each cell, `corners` the node offsets of a cell's corners.
    pub(super) fn find_pockets<const D: usize>(
        &mut self,
        grid: &Grid<D>,
        cell_volume: &[f64],
        cell_solid: &[bool],
        cell_node: &[usize],
        corners: &[usize],
    ) {
        let cells = cell_volume.len();
        if self.region.len() != cells {
            self.region = vec![NONE; cells];
            self.before = vec![NONE; cells];
            self.tie = vec![NONE; grid.len()];
        }
        let cell_size = grid.dx.powi(D as i32);
        let ambient = self.settings.ambient_pressure;
        let mut shape = [1usize; 3];
        shape[..D].copy_from_slice(&grid.cells[..D]);
        self.region.fill(NONE);
        self.regions.clear();
        for pocket in &mut self.pockets {
            pocket.reached = 0;
        }
        // Flood fill over the empty cells, 3^D − 1 neighbours (cells sharing a node).
        for seed in 0..cells {
            if self.region[seed] != NONE || cell_volume[seed] > 0.0 || cell_solid[seed] {
                continue;
            }
            let label = self.regions.len() as u32;
            let mut region = Region {
                unknown: NONE,
                carried: NONE,
                ..Region::default()
            };
            self.region[seed] = label;
            self.stack.clear();
            self.stack.push(seed);
            while let Some(c) = self.stack.pop() {
                region.cells += 1;
                let ijk = coords::<D>(c, &shape);
                if (0..D).any(|d| ijk[d] == 0 || ijk[d] + 1 == shape[d]) {
                    region.open = true;
                }
                for k in 0..3usize.pow(D as u32) {
                    let mut rest = k;
                    let mut neighbour = 0usize;
                    let mut inside = true;
                    for d in 0..D {
                        let at = ijk[d] as isize + (rest % 3) as isize - 1;
                        rest /= 3;
                        if at < 0 || at >= shape[d] as isize {
                            inside = false;
                            break;
                        }
                        neighbour = neighbour * shape[d] + at as usize;
                    }
                    if inside
                        && self.region[neighbour] == NONE
                        && cell_volume[neighbour] <= 0.0
                        && !cell_solid[neighbour]
                    {
                        self.region[neighbour] = label;
                        self.stack.push(neighbour);
                    }
                }
            }
            self.regions.push(region);
        }
        if self.fresh {
            // No history: every region's air is at the ambient pressure.
            for region in &mut self.regions {
                region.gas = ambient * region.cells as f64 * cell_size;
                region.volume = region.cells as f64 * cell_size;
            }
            self.fresh = false;
        } else {
            self.share_out_gas(cell_size);
        }
        // Closed regions with gas are carried; large enough ones get an unknown.
        self.next_pockets.clear();
        self.unknowns.clear();
        for (r, region) in self.regions.iter_mut().enumerate() {
            if region.open {
                continue;
            }
            if region.gas > 0.0 {
                region.carried = self.next_pockets.len() as u32;
                self.next_pockets.push(Pocket {
                    gas: region.gas,
                    volume: region.volume,
                    reached: 0,
                });
            }
            region.unknown = self.unknowns.len() as u32;
            self.unknowns.push(Unknown {
                region: r as u32,
                measured: region.cells as f64 * cell_size,
                gap: region.gas <= 0.0 || (region.cells as f64) < self.settings.min_cells,
                ..Unknown::default()
            });
        }
        self.anchored = self.regions.iter().any(|r| r.open) || self.unknowns.iter().any(|u| !u.gap);
        std::mem::swap(&mut self.pockets, &mut self.next_pockets);
        for c in 0..cells {
            let r = self.region[c];
            self.before[c] = if r == NONE {
                NONE
            } else if self.regions[r as usize].open {
                OPEN
            } else {
                self.regions[r as usize].carried
            };
        }
        // Tie the pockets' nodes; add the shortfall of the liquid cells around them.
        self.tie.fill(NONE);
        for (&r, &base) in self.region.iter().zip(cell_node) {
            if r == NONE {
                continue;
            }
            let unknown = self.regions[r as usize].unknown;
            if unknown != NONE {
                for offset in corners {
                    self.tie[base + offset] = unknown;
                }
            }
        }
        self.tied_nodes.clear();
        self.tied_nodes.extend(
            self.tie
                .iter()
                .enumerate()
                .filter(|(_, k)| **k != NONE)
                .map(|(i, &k)| (i, k)),
        );
        for c in 0..cells {
            if cell_volume[c] <= 0.0 {
                continue;
            }
            if let Some(&k) = corners
                .iter()
                .map(|o| &self.tie[cell_node[c] + o])
                .find(|k| **k != NONE)
            {
                self.unknowns[k as usize].measured += (cell_size - cell_volume[c]).max(0.0);
            }
        }
    }

    /// Gives each region the gas of last step's pockets in proportion to the cells of
    /// theirs it holds, and the ambient air of the cells that were open air.
    fn share_out_gas(&mut self, cell_size: f64) {
        let ambient = self.settings.ambient_pressure;
        for (c, &r) in self.region.iter().enumerate() {
            if r == NONE {
                continue;
            }
            match self.before[c] {
                NONE => {}
                OPEN => {
                    let region = &mut self.regions[r as usize];
                    region.gas += ambient * cell_size;
                    region.volume += cell_size;
                }
                k => self.pockets[k as usize].reached += 1,
            }
        }
        for (c, &r) in self.region.iter().enumerate() {
            let k = self.before[c];
            if r == NONE || k == NONE || k == OPEN {
                continue;
            }
            let pocket = self.pockets[k as usize];
            let share = 1.0 / pocket.reached as f64;
            let region = &mut self.regions[r as usize];
            region.gas += pocket.gas * share;
            region.volume += pocket.volume * share;
        }
    }

    /// Fills the pocket unknowns' rows (entries n.. of `rhs`, `inverse_diagonal`, and the
    /// start value in `pressure`, all of length n + unknowns): the sum of the tied nodes'
    /// right-hand sides, the gas's compliance, and the volume share (`share` per velocity-
    /// CFL step, already scaled by the step). `scaled_stiffness(c)` gives a liquid cell's
    /// element stiffness factor (V/m of the cell) and `stiffness` the element matrix.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn fill_rows(
        &mut self,
        n: usize,
        dt: f64,
        share: f64,
        cell_scale: impl Fn(usize) -> Option<f64>,
        cell_node: &[usize],
        corners: &[usize],
        stiffness: &[[f64; 8]; 8],
        rhs: &mut [f64],
        inverse_diagonal: &mut [f64],
        pressure: &mut [f64],
    ) {
        let ambient = self.settings.ambient_pressure;
        for u in self.unknowns.iter_mut() {
            let region = &self.regions[u.region as usize];
            u.compliance = if u.gap {
                0.0
            } else {
                let absolute = region.gas / region.volume;
                region.volume / (absolute * dt * dt)
            };
            u.diagonal = u.compliance;
        }
        // The diagonal of the pocket's row: Σ over liquid cells of the element stiffness
        // between corners tied to the same pocket.
        for (c, &base) in cell_node.iter().enumerate() {
            let Some(scale) = cell_scale(c) else { continue };
            for (a, oa) in corners.iter().enumerate() {
                let k = self.tie[base + oa];
                if k == NONE {
                    continue;
                }
                for (b, ob) in corners.iter().enumerate() {
                    if self.tie[base + ob] == k {
                        self.unknowns[k as usize].diagonal += scale * stiffness[a][b];
                    }
                }
            }
        }
        self.gather_tied(rhs, n);
        for (k, u) in self.unknowns.iter_mut().enumerate() {
            u.source = 0.0;
            if u.diagonal <= 0.0 {
                // A gap no liquid cell touches: nothing to solve for.
                rhs[n + k] = 0.0;
                inverse_diagonal[n + k] = 0.0;
                pressure[n + k] = 0.0;
                continue;
            }
            let region = &self.regions[u.region as usize];
            let (last, target) = if u.gap {
                // A gap closes (its target volume is 0) at the volume source's pace; its
                // pressure is whatever the liquid around it needs for that. With nowhere
                // for the volume to go the system would have no solution: it stays.
                (0.0, if self.anchored { 0.0 } else { u.measured })
            } else {
                (region.gas / region.volume - ambient, region.volume)
            };
            u.source = -share / (dt * dt) * (u.measured - target);
            rhs[n + k] += u.compliance * last + u.source;
            inverse_diagonal[n + k] = 1.0 / u.diagonal;
            pressure[n + k] = last;
        }
    }

    /// The pocket rows of the volume source's own right-hand side (`rhs`, its nodes' rows
    /// filled): the sum of the tied nodes' and the volume share, with none of the gas's
    /// last pressure, so that the source's pressure is its part of the whole solve's.
    pub(super) fn source_rows(&self, n: usize, rhs: &mut [f64]) {
        self.gather_tied(rhs, n);
        for (k, u) in self.unknowns.iter().enumerate() {
            rhs[n + k] = if u.diagonal > 0.0 {
                rhs[n + k] + u.source
            } else {
                0.0
            };
        }
    }

    /// Sets each pocket's (gap's) entry after the `n` nodes to the sum of its tied nodes'.
    fn gather_tied(&self, values: &mut [f64], n: usize) {
        values[n..n + self.unknowns.len()].fill(0.0);
        for &(i, k) in &self.tied_nodes {
            values[n + k as usize] += values[i];
        }
    }

    /// Adds each pocket's (gap's) value after the `n` nodes to its tied nodes.
    pub(super) fn add_tied(&self, values: &mut [f64], n: usize) {
        for &(i, k) in &self.tied_nodes {
            values[i] += values[n + k as usize];
        }
    }

    /// The pocket pressure a tied node adds to its own value in the operator (0 untied).
    #[inline]
    pub(super) fn tied(&self, node: usize, x: &[f64], n: usize) -> f64 {
        match self.tie.get(node) {
            Some(&k) if k != NONE => x[n + k as usize],
            _ => 0.0,
        }
    }

    /// Whether node `i` is tied to a pocket this step.
    pub(super) fn is_tied(&self, i: usize) -> bool {
        self.tie.get(i).is_some_and(|&k| k != NONE)
    }

    /// The pocket rows of the operator: y[n+k] = Σ_{tied i} y_i + C_k x[n+k].
    pub(super) fn gather(&self, x: &[f64], y: &mut [f64], n: usize) {
        for (k, u) in self.unknowns.iter().enumerate() {
            y[n + k] = u.compliance * x[n + k];
        }
        for &(i, k) in &self.tied_nodes {
            y[n + k as usize] += y[i];
        }
    }

    /// After the solve: adds each pocket's pressure to its tied nodes, keeps the gas's new
    /// volume, and returns the largest pocket gauge pressure (0 without pockets).
    pub(super) fn finish(&mut self, pressure: &mut [f64], n: usize) -> f64 {
        let ambient = self.settings.ambient_pressure;
        self.add_tied(pressure, n);
        let mut largest: f64 = 0.0;
        for (k, u) in self.unknowns.iter().enumerate().filter(|(_, u)| !u.gap) {
            let region = &self.regions[u.region as usize];
            let gauge = pressure[n + k];
            // The solve never takes a pocket below vacuum; guard against it all the same.
            let absolute = (ambient + gauge).max(1e-6 * ambient);
            let pocket = &mut self.pockets[region.carried as usize];
            pocket.volume = pocket.gas / absolute;
            largest = largest.max(gauge);
        }
        largest
    }
}

/// Cell coordinates of cell index `c` (last axis fastest, as `cell_of` numbers them).
#[inline]
fn coords<const D: usize>(c: usize, shape: &[usize; 3]) -> [usize; 3] {
    let mut ijk = [0; 3];
    let mut rest = c;
    for d in (0..D).rev() {
        ijk[d] = rest % shape[d];
        rest /= shape[d];
    }
    ijk
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vector;

    /// An 8 × 8-cell 2D grid with every cell liquid except `empty` (cell coordinates).
    fn cells_with(empty: &[(usize, usize)]) -> (Grid<2>, Vec<f64>, Vec<bool>, Vec<usize>) {
        let grid = Grid::<2>::new(Vector::<2>::zeros(), [8, 8, 1], 1.0, false);
        let mut volume = vec![1.0; 64];
        for &(i, j) in empty {
            volume[i * 8 + j] = 0.0;
        }
        let node = (0..64)
            .map(|c| (c / 8) * grid.stride[0] + (c % 8) * grid.stride[1])
            .collect();
        (grid, volume, vec![false; 64], node)
    }

    fn air() -> EnclosedAir {
        EnclosedAir::new(EnclosedAirSettings {
            ambient_pressure: 1000.0,
            min_cells: 2.0,
        })
    }

    fn gas(air: &EnclosedAir) -> f64 {
        air.pockets.iter().map(|p| p.gas).sum()
    }

    #[test]
    fn a_closed_hole_is_a_pocket_and_open_air_is_not() {
        let (grid, volume, solid, node) = cells_with(&[(3, 3), (3, 4), (0, 5), (1, 5)]);
        let mut air = air();
        let corners = [
            0,
            grid.stride[1],
            grid.stride[0],
            grid.stride[0] + grid.stride[1],
        ];
        air.find_pockets(&grid, &volume, &solid, &node, &corners);
        // The hole in the middle, not the notch from the grid's edge.
        assert_eq!(air.unknowns(), 1);
        assert_eq!(gas(&air), 1000.0 * 2.0);
        let tied = air.tie.iter().filter(|k| **k == 0).count();
        assert_eq!(tied, 2 * 3, "the hole's 2 × 1 cells have 3 × 2 corners");
    }

    #[test]
    fn a_pocket_that_splits_keeps_its_gas_and_a_compressed_one_shrinks() {
        let strip: Vec<(usize, usize)> = (1..6).map(|j| (3, j)).collect();
        let (grid, volume, solid, node) = cells_with(&strip);
        let corners = [
            0,
            grid.stride[1],
            grid.stride[0],
            grid.stride[0] + grid.stride[1],
        ];
        let mut air = air();
        air.find_pockets(&grid, &volume, &solid, &node, &corners);
        assert_eq!(air.unknowns(), 1);
        let before = gas(&air);
        // Liquid fills the strip's middle cell: two pockets of two cells, half the gas each.
        let (_, mut volume, _, _) = cells_with(&strip);
        volume[3 * 8 + 3] = 1.0;
        air.find_pockets(&grid, &volume, &solid, &node, &corners);
        assert_eq!(air.unknowns(), 2);
        assert!((gas(&air) - before).abs() < 1e-9, "{} {before}", gas(&air));
        assert!((air.pockets[0].gas - 0.5 * before).abs() < 1e-9);
        // Each half compressed to 1500 Pa absolute takes two thirds of its volume.
        let n = grid.len();
        let mut pressure = vec![0.0; n + 2];
        pressure[n] = 500.0;
        pressure[n + 1] = 500.0;
        let largest = air.finish(&mut pressure, n);
        assert_eq!(largest, 500.0);
        for p in &air.pockets {
            assert!((p.volume - 2.5 * 2.0 / 3.0).abs() < 1e-12, "{}", p.volume);
        }
    }

    #[test]
    fn a_hole_torn_in_the_liquid_is_a_gap_that_closes_where_the_volume_can_go() {
        // With a notch open to the grid's edge a hole that opens inside the liquid (it was
        // liquid, so it holds no gas) is a gap: no compliance, and its row asks the share of
        // its volume back. In a box that is full and sealed there is nowhere for it to go.
        let corners = |grid: &Grid<2>| {
            [
                0,
                grid.stride[1],
                grid.stride[0],
                grid.stride[0] + grid.stride[1],
            ]
        };
        let mut stiffness = [[0.0; 8]; 8];
        for (a, row) in stiffness.iter_mut().enumerate().take(4) {
            row[a] = 1.0;
        }
        for (notch, asked) in [(&[(0, 5), (1, 5)][..], -0.5), (&[][..], 0.0)] {
            let (grid, volume, solid, node) = cells_with(notch);
            let corners = corners(&grid);
            let mut air = air();
            air.find_pockets(&grid, &volume, &solid, &node, &corners);
            assert_eq!(air.counts(), (0, 0));
            let mut torn = notch.to_vec();
            torn.push((4, 4));
            let (_, volume, _, _) = cells_with(&torn);
            air.find_pockets(&grid, &volume, &solid, &node, &corners);
            assert_eq!(air.counts(), (0, 1), "one gap, no gas pocket");
            let n = grid.len();
            let (mut rhs, mut inverse, mut pressure) =
                (vec![0.0; n + 1], vec![0.0; n + 1], vec![0.0; n + 1]);
            air.fill_rows(
                n,
                1.0,
                0.5,
                |c| (volume[c] > 0.0).then_some(1.0),
                &node,
                &corners,
                &stiffness,
                &mut rhs,
                &mut inverse,
                &mut pressure,
            );
            assert_eq!(air.unknowns[0].compliance, 0.0);
            assert!(inverse[n] > 0.0);
            // The hole's one cell, with its full neighbours: share × 1 cell.
            assert_eq!(rhs[n], asked, "notch {notch:?}");
            // A gap's pressure is no pocket's: the largest gauge stays 0.
            pressure[n] = 50.0;
            assert_eq!(air.finish(&mut pressure, n), 0.0);
        }
    }
}
