//! Surface tension of liquid particles at the free surface, as the pressure jump across
//! it: the projection's free-surface nodes get the Laplace pressure p = σ·κ instead of 0
//! (the free-surface boundary condition of ghost-fluid and level-set projection solvers,
//! e.g. Enright, Nguyen, Gibou & Fedkiw 2003), so capillarity enters the same Poisson
//! solve that keeps the volume, not as an extra body force.
//!
//! The curvature comes from the particles' colour field (Brackbill, Kothe & Zemach 1992):
//! c_i = m_i / (ρ·dx^D) on the nodes (the P2G mass, smooth with B-spline kernels: 1
//! inside, 0 outside, over about two cells), its inward normal n = ∇c/|∇c| by central
//! differences, κ = −∇·n by central differences of n. Curvature at the nodes of the
//! colour band is 1/r of each node's own level set, not of the surface; a surface node
//! takes the mean of κ over the band nodes within two cells, weighted by |∇c|, which
//! peaks on the c = ½ contour, so the mean stands for the curvature of the surface, and
//! by triangular weights (1, 2, 3, 2, 1) along each axis, so that no surface wave is given a
//! pressure that amplifies it.
//! Across every wall the colour is the liquid's plus its mirror image, so that a wall is
//! not mistaken for a free surface, and the liquid meets the wall at 90°; a wall with a
//! static contact angle θ (`domain.walls[].contact_angle`) instead continues the colour
//! into the wall along lines at θ to it (the level-set contact-angle extension), so the
//! curvature next to the contact line is the meniscus's. Obstacles do the same
//! (`obstacles[].contact_angle`): nodes inside one, near its surface, take the image
//! across the surface's nearest point, or across the far one of a thin obstacle where
//! that is wetter; other bodies are not mirrored and look like voids. Behind a pressure
//! inlet's face the colour is 1 (the reservoir's liquid), so the face is no free surface.
//!
//! Explicit in the surface's shape, so the step is bounded by a capillary wave limit:
//! dt ≤ √(ρ·dx³ / (25π·σ)), 0.4 times Brackbill et al.'s √(ρ̄·dx³/(2πσ)) with ρ̄ = ρ/2
//! (the mean of the liquid's and the void's densities). The textbook bound times the
//! scene's `cfl` 0.5 let a drop of radius 20 cells lose its pressure within 0.05 s; 0.4 of
//! it (the same as `cfl` 0.2) keeps it within 0.4%.
use crate::boundary::{SolidImage, WallPlane, mirror_pairs};
use crate::grid::{Grid, node_coords};
use crate::math::Vector;

/// Smallest |∇c|·dx at which a node's normal is defined (below it the colour is flat:
/// deep inside the liquid or far outside).
const FLAT: f64 = 0.02;
/// Passes of the (1, 2, 1)/4 filter on the colour before it is differentiated.
const SMOOTHING: usize = 2;
/// Reach, in nodes, of the band mean that gives a surface node its curvature.
const REACH: isize = 2;
/// Weights of the band mean along each axis, triangular over the 2·REACH + 1 nodes (the
/// flat 3-node window applied twice, whose response ((1 + 2 cos k)/3)² is never negative).
/// A flat 5-node window has a negative response to surface waves 2.5–5 cells long, which
/// then grow under a capillary pressure of the wrong sign: a 30° meniscus 20 cells wide lost
/// half its depth by 1 s, and a drop of 10 cells radius reached 5.13 mm from 5 mm by 0.3 s
/// (5.002 mm with these weights).
const BAND_WEIGHTS: [f64; 5] = [1.0, 2.0, 3.0, 2.0, 1.0];
/// Least difference of the wall plane's colour on the two sides of a node that tells on
/// which side the liquid lies (a contact line within reach).
const CLEAR_SIDE: f64 = 0.1;
/// Depth, in cells, inside an obstacle down to which the colour takes its image: as far as
/// the smoothing, the two differences and the band mean reach from a surface node.
pub(super) const IMAGE_REACH: f64 = 4.0;
/// Distance, in cells, in front of an obstacle within which the particles' kernels reach
/// into it, so a node there gets the image's share of the colour.
pub(super) const FOLD_REACH: f64 = 2.0;

/// The capillary step limit of a liquid of surface tension `sigma`, density `density` and
/// least viscosity `mu` (0 with explicit viscosity) on cells of `dx`; unbounded without
/// surface tension. The larger of the inertial bound c₁τ_ρ, τ_ρ = √(ρdx³/σ), c₁ = 1/√(25π)
/// (√(ρdx³/(25πσ)), as with no viscosity), and the viscous one c₂τ_μ, τ_μ = μdx/σ,
/// c₂ = [`VISCOUS_CAPILLARY`] (Galusinski & Vigneaux 2008 add the two; the larger alone is
/// below their sum and leaves a liquid with τ_μ < 1.13 τ_ρ at the inertial step). With
/// implicit viscosity the capillary pressure is solved before the viscous step
/// (capillary_first.rs), so the viscous bound holds however large μ is.
pub(super) fn stable_dt(sigma: f64, density: f64, mu: f64, dx: f64) -> f64 {
    if sigma <= 0.0 {
        return f64::INFINITY;
    }
    let viscous = VISCOUS_CAPILLARY * mu.max(0.0) * dx / sigma;
    inertial_dt(sigma, density, dx).max(viscous)
}

/// The inertial capillary step √(ρdx³/(25πσ)), the bound of an explicit capillary wave;
/// unbounded without surface tension.
pub(super) fn inertial_dt(sigma: f64, density: f64, dx: f64) -> f64 {
    if sigma <= 0.0 {
        return f64::INFINITY;
    }
    (density * dx * dx * dx / (25.0 * std::f64::consts::PI * sigma)).sqrt()
}

/// c₂ of the viscous–capillary bound: how far a viscous liquid's capillary step grows with
/// μdx/σ (implicit viscosity only). Measured on the oscillating drop (2D, radius 10 cells)
/// against a run at half its inertial step: at the bound with the default `cfl` 0.5 its
/// quadrupole moment deviates by 0.6% (μ = 1 Pa·s) and 1% (μ = 10); the error is of first
/// order in dt. A 10-cell meniscus at μ = 0.2 Pa·s (τ_μ = 0.76 τ_ρ) gives 3.9% on
/// Young–Laplace at the inertial step and 5–6% from 1.2× it, so weakly viscous liquids
/// keep the inertial step.
const VISCOUS_CAPILLARY: f64 = 0.1;

/// The colour field, its normals and curvature, and the scene's liquid constants.
pub(super) struct SurfaceTension<const D: usize> {
    /// Surface tension σ, N/m (liquid against the void).
    pub(super) sigma: f64,
    /// Density ρ of the liquid, kg/m³ (the colour is the nodal mass over ρ·dx^D).
    density: f64,
    /// Per node: the colour c, smoothed (and a scratch copy for the smoothing passes).
    pub(super) colour: Vec<f64>,
    scratch: Vec<f64>,
    /// Per node: ∇c (zero where undefined).
    pub(super) gradient: Vec<Vector<D>>,
    /// Per node: inward unit normal ∇c/|∇c| (zero where the colour is flat).
    normal: Vec<Vector<D>>,
    /// Per node: −∇·n where every neighbour's normal is defined, else NaN.
    curvature: Vec<f64>,
    /// Per node: whether a liquid cell touches it.
    touches_liquid: Vec<bool>,
    /// The walls, across which the colour is mirrored.
    pub(super) walls: Vec<WallPlane>,
    /// The nodes near obstacles' surfaces, inside (which take the colour's image) and in
    /// front (which take the image's share of what the particles put inside).
    pub(super) solid_images: Vec<SolidImage<D>>,
    /// Nodes behind flowing pressure inlets' faces, full of the reservoir's liquid: the
    /// colour is 1 there (pressure_inlet.rs), so an inlet face is not a free surface.
    pub(super) reservoir: Vec<usize>,
}

impl<const D: usize> SurfaceTension<D> {
    /// For a liquid of surface tension `sigma` (> 0) and density `density` between
    /// `walls` and obstacles (`solid_images`).
    pub(super) fn new(
        sigma: f64,
        density: f64,
        walls: Vec<WallPlane>,
        solid_images: Vec<SolidImage<D>>,
    ) -> Self {
        Self {
            sigma,
            density,
            colour: Vec::new(),
            scratch: Vec::new(),
            gradient: Vec::new(),
            normal: Vec::new(),
            curvature: Vec::new(),
            touches_liquid: Vec::new(),
            walls,
            solid_images,
            reservoir: Vec::new(),
        }
    }

    /// Sets the Laplace pressure σ·κ at the free-surface nodes: nodes that are not pressure
    /// unknowns (`inverse_diagonal` 0) and touch a liquid cell (`liquid_cell_nodes` lists
    /// the lowest corner of each liquid cell, `corner_offset` the 2^D corners).
    pub(super) fn surface_pressure(
        &mut self,
        grid: &Grid<D>,
        liquid_cell_nodes: impl Iterator<Item = usize>,
        corner_offset: &[usize],
        inverse_diagonal: &[f64],
        pressure: &mut [f64],
    ) {
        let n = grid.len();
        self.size_for(grid);
        self.touches_liquid.fill(false);
        for base in liquid_cell_nodes {
            for offset in corner_offset {
                self.touches_liquid[base + offset] = true;
            }
        }
        self.colour_normals(grid);
        self.curvatures(grid);
        for i in 0..n {
            if self.touches_liquid[i] && inverse_diagonal[i] <= 0.0 {
                pressure[i] = self.sigma * self.band_curvature(grid, i);
            }
        }
    }

    /// Whether node `i` touched a liquid cell at the last [`Self::surface_pressure`]: with
    /// the free-surface nodes' `inverse_diagonal` 0, the nodes it gave σ·κ.
    pub(super) fn touches_liquid(&self, i: usize) -> bool {
        self.touches_liquid.get(i).copied().unwrap_or(false)
    }

    /// Sizes the per-node arrays for `grid` (once).
    pub(super) fn size_for(&mut self, grid: &Grid<D>) {
        let n = grid.len();
        if self.gradient.len() != n {
            self.colour = vec![0.0; n];
            self.scratch = vec![0.0; n];
            self.gradient = vec![Vector::<D>::zeros(); n];
            self.normal = vec![Vector::<D>::zeros(); n];
            self.curvature = vec![f64::NAN; n];
            self.touches_liquid = vec![false; n];
        }
    }

    /// The colour c = m/(ρ·dx^D), smoothed by `SMOOTHING` passes of the (1, 2, 1)/4
    /// filter along each axis.
    fn colour(&mut self, grid: &Grid<D>) {
        let scale = 1.0 / (self.density * grid.dx.powi(D as i32));
        for (c, m) in self.colour.iter_mut().zip(&grid.mass) {
            *c = m * scale;
        }
        for &i in &self.reservoir {
            self.colour[i] = 1.0;
        }
        self.mirror_walls(grid, true);
        for _ in 0..SMOOTHING {
            for d in 0..D {
                let s = grid.stride[d];
                for i in 0..grid.len() {
                    let at = node_coords(&grid.stride, i)[d];
                    self.scratch[i] = if at == 0 || at + 1 >= grid.nodes[d] {
                        self.colour[i]
                    } else {
                        0.25 * (self.colour[i - s] + 2.0 * self.colour[i] + self.colour[i + s])
                    };
                }
                std::mem::swap(&mut self.colour, &mut self.scratch);
            }
            self.mirror_walls(grid, false);
            for &i in &self.reservoir {
                self.colour[i] = 1.0;
            }
        }
    }

    /// Makes the colour the liquid's plus its image across each wall, so that a wall looks
    /// like more liquid and not like a free surface. With `fold`,
    /// what the particles put behind a wall is added to the mirror nodes in front and the
    /// wall plane's own value is doubled (the image's share; stick walls have folded their
    /// mass already, so their ghosts add nothing). Then every node behind a wall takes its
    /// mirror's value, or on a wall with a contact angle other than 90° the value
    /// [`Self::image`] gives it.
    fn mirror_walls(&mut self, grid: &Grid<D>, fold: bool) {
        for w in 0..self.walls.len() {
            let wall = self.walls[w];
            let (a, s) = (wall.axis, wall.surface);
            let slant = 1.0 / wall.contact_angle.tan();
            let slanted = slant.abs() > 1e-12;
            let mut normal = Vector::<D>::zeros();
            normal[a] = if wall.upper { -1.0 } else { 1.0 };
            for i in 0..grid.len() {
                let ijk = node_coords(&grid.stride, i);
                if ijk[a] != s {
                    continue;
                }
                let line = i - s * grid.stride[a];
                let node = |k: usize| line + k * grid.stride[a];
                if fold {
                    self.colour[i] *= 2.0;
                }
                for (ghost, front) in mirror_pairs(wall.upper, s, grid.nodes[a]) {
                    if fold {
                        self.colour[node(front)] += self.colour[node(ghost)];
                    }
                    self.colour[node(ghost)] = self.colour[node(front)];
                }
            }
            if !slanted {
                continue;
            }
            // A second pass, once every line of the wall is folded: an image reads the
            // wall plane and the nodes in front of it along other lines.
            for i in 0..grid.len() {
                if node_coords(&grid.stride, i)[a] != s {
                    continue;
                }
                let line = i - s * grid.stride[a];
                for (ghost, _) in mirror_pairs(wall.upper, s, grid.nodes[a]) {
                    let mut at = node_position(grid, i);
                    at[a] = ghost as f64;
                    let depth = ghost.abs_diff(s) as f64;
                    self.colour[line + ghost * grid.stride[a]] =
                        self.image(grid, &at, &normal, depth, slant);
                }
            }
        }
        self.mirror_obstacles(grid, fold);
    }

    /// The obstacles' share of [`Self::mirror_walls`]: with `fold`, a node in front of an
    /// obstacle gains what the particles put at its mirror point inside; then every node
    /// inside near the surface takes [`Self::image`] across the surface's nearest point,
    /// or across the far surface where that is within reach (a thin obstacle) and its
    /// image is wetter. A node past the middle of a plate thinner than twice the reach
    /// would otherwise image the far side, and a plate wetted on one side only would look,
    /// two cells in from its wetted face, like a free surface (a meniscus between 4-cell
    /// plates read its pressure 118% off; 1.1% with the wetter image).
    fn mirror_obstacles(&mut self, grid: &Grid<D>, fold: bool) {
        if self.solid_images.is_empty() {
            return;
        }
        if fold {
            self.scratch.copy_from_slice(&self.colour);
            for image in self.solid_images.iter().filter(|image| image.depth < 0.0) {
                let mirror = node_position(grid, image.node) + image.normal * (2.0 * image.depth);
                self.colour[image.node] += sample(&self.scratch, grid, &mirror);
            }
            for image in self.solid_images.iter().filter(|image| image.depth == 0.0) {
                self.colour[image.node] *= 2.0;
            }
        }
        for k in 0..self.solid_images.len() {
            let image = self.solid_images[k];
            if image.depth > 0.0 {
                let slant = 1.0 / image.contact_angle.tan();
                let at = node_position(grid, image.node);
                let mut c = self.image(grid, &at, &image.normal, image.depth, slant);
                if image.far_depth.is_finite() {
                    let far = self.image(grid, &at, &image.far_normal, image.far_depth, slant);
                    c = c.max(far);
                }
                self.colour[image.node] = c;
            }
        }
    }

    /// The colour at a node inside a solid (`at`, in node units), `depth` nodes behind the
    /// surface whose unit normal into the liquid is `normal`, for a contact angle θ with
    /// cot θ = `slant`: the colour at the node's mirror image across the surface, moved
    /// 2·depth·cot θ nodes along the surface towards the liquid. The surface's level lines
    /// then cross the solid's surface at θ and go on into the solid as they run in front of
    /// it (a straight line exactly, a curve to second order): the level-set contact-angle
    /// extension, so the normals and curvature at the contact line see the angle. Towards
    /// the liquid is where the colour along the surface is higher that far away; where it
    /// is the same on both sides (no contact line within reach), the plain mirror.
    fn image(
        &self,
        grid: &Grid<D>,
        at: &Vector<D>,
        normal: &Vector<D>,
        depth: f64,
        slant: f64,
    ) -> f64 {
        let mut mirror = at + normal * (2.0 * depth);
        let shift = 2.0 * depth * slant;
        if shift.abs() > 1e-12 {
            let surface = at + normal * depth;
            let mut towards = Vector::<D>::zeros();
            for d in 0..D {
                let mut step = Vector::<D>::zeros();
                step[d] = shift.abs();
                towards[d] = sample(&self.colour, grid, &(surface + step))
                    - sample(&self.colour, grid, &(surface - step));
            }
            towards -= normal * towards.dot(normal);
            let length = towards.norm();
            if length >= CLEAR_SIDE {
                mirror += towards * (shift / length);
            }
        }
        sample(&self.colour, grid, &mirror)
    }

    /// ∇c and n = ∇c/|∇c| at every interior node.
    pub(super) fn colour_normals(&mut self, grid: &Grid<D>) {
        self.colour(grid);
        let scale = 0.5 * grid.inv_dx;
        for i in 0..grid.len() {
            let ijk = node_coords(&grid.stride, i);
            let mut g = Vector::<D>::zeros();
            let mut inside = true;
            for d in 0..D {
                if ijk[d] == 0 || ijk[d] + 1 >= grid.nodes[d] {
                    inside = false;
                    break;
                }
                let s = grid.stride[d];
                g[d] = (self.colour[i + s] - self.colour[i - s]) * scale;
            }
            if !inside {
                g = Vector::<D>::zeros();
            }
            self.gradient[i] = g;
            let length = g.norm();
            self.normal[i] = if length * grid.dx > FLAT {
                g / length
            } else {
                Vector::<D>::zeros()
            };
        }
    }

    /// κ = −∇·n by central differences where the node and its 2·D neighbours have a
    /// normal; NaN elsewhere.
    fn curvatures(&mut self, grid: &Grid<D>) {
        let half = 0.5 * grid.inv_dx;
        for i in 0..grid.len() {
            self.curvature[i] = f64::NAN;
            if self.normal[i] == Vector::<D>::zeros() {
                continue;
            }
            let ijk = node_coords(&grid.stride, i);
            let mut divergence = 0.0;
            let mut defined = true;
            for d in 0..D {
                if ijk[d] == 0 || ijk[d] + 1 >= grid.nodes[d] {
                    defined = false;
                    break;
                }
                let s = grid.stride[d];
                let (up, down) = (&self.normal[i + s], &self.normal[i - s]);
                if *up == Vector::<D>::zeros() || *down == Vector::<D>::zeros() {
                    defined = false;
                    break;
                }
                divergence += (up[d] - down[d]) * half;
            }
            if defined {
                self.curvature[i] = -divergence;
            }
        }
    }

    /// The curvature of the surface near node `i`: the |∇c|-weighted mean of κ over the
    /// band nodes within `REACH` nodes of it (0 where none has a curvature).
    fn band_curvature(&self, grid: &Grid<D>, i: usize) -> f64 {
        let ijk = node_coords(&grid.stride, i);
        let width = (2 * REACH + 1) as usize;
        let count = width.pow(D as u32);
        let (mut sum, mut weights) = (0.0, 0.0);
        for k in 0..count {
            let mut rest = k;
            let mut j = 0usize;
            let mut inside = true;
            for (d, &here) in ijk.iter().enumerate().take(D) {
                let step = (rest % width) as isize - REACH;
                rest /= width;
                let at = here as isize + step;
                if at < 0 || at >= grid.nodes[d] as isize {
                    inside = false;
                    break;
                }
                j += at as usize * grid.stride[d];
            }
            if !inside || self.curvature[j].is_nan() {
                continue;
            }
            let mut w = self.gradient[j].norm();
            let mut rest = k;
            for _ in 0..D {
                w *= BAND_WEIGHTS[rest % width];
                rest /= width;
            }
            sum += w * self.curvature[j];
            weights += w;
        }
        if weights > 0.0 { sum / weights } else { 0.0 }
    }
}

/// Node `node`'s position in node units (its index along each axis).
fn node_position<const D: usize>(grid: &Grid<D>, node: usize) -> Vector<D> {
    let at = node_coords(&grid.stride, node);
    let mut x = Vector::<D>::zeros();
    for d in 0..D {
        x[d] = at[d] as f64;
    }
    x
}

/// The field `colour` at `x` (node units), interpolated linearly between the nodes and clamped
/// to the grid.
fn sample<const D: usize>(colour: &[f64], grid: &Grid<D>, x: &Vector<D>) -> f64 {
    let mut low = [0usize; D];
    let mut fraction = [0.0; D];
    for d in 0..D {
        let last = grid.nodes[d] - 1;
        let y = x[d].clamp(0.0, last as f64);
        low[d] = (y.floor() as usize).min(last.saturating_sub(1));
        fraction[d] = y - low[d] as f64;
    }
    let mut value = 0.0;
    for corner in 0..1usize << D {
        let mut weight = 1.0;
        let mut j = 0;
        for d in 0..D {
            let (n, w) = if corner & (1 << d) != 0 {
                (low[d] + 1, fraction[d])
            } else {
                (low[d], 1.0 - fraction[d])
            };
            weight *= w;
            j += n.min(grid.nodes[d] - 1) * grid.stride[d];
        }
        if weight > 0.0 {
            value += weight * colour[j];
        }
    }
    value
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Water on 0.5 mm cells: √(ρdx³/σ) = 1.336 ms.
    const WATER: (f64, f64, f64) = (0.07, 1000.0, 5e-4);

    #[test]
    fn an_inviscid_or_weakly_viscous_liquid_keeps_the_inertial_step() {
        let (sigma, rho, dx) = WATER;
        let inertial = (rho * dx.powi(3) / (25.0 * std::f64::consts::PI * sigma)).sqrt();
        assert_eq!(stable_dt(sigma, rho, 0.0, dx), inertial);
        // τ_μ = μdx/σ = 0.71 τ_ρ at μ = 0.1 Pa·s: below 1.13 τ_ρ, so no gain.
        assert_eq!(stable_dt(sigma, rho, 0.1, dx), inertial);
        assert_eq!(stable_dt(0.0, rho, 0.1, dx), f64::INFINITY);
    }

    #[test]
    fn a_viscous_liquid_steps_by_its_viscous_capillary_time() {
        let (sigma, rho, dx) = WATER;
        let tau_rho = (rho * dx.powi(3) / sigma).sqrt();
        // μ = 0.4 Pa·s: τ_μ = 2.86 ms = 2.14 τ_ρ, so 0.1 τ_μ = 0.214 τ_ρ.
        let mid = stable_dt(sigma, rho, 0.4, dx);
        assert!((mid - 0.1 * 0.4 * dx / sigma).abs() < 1e-15, "{mid}");
        // No cap: at μ = 1000 Pa·s the step is 0.1 τ_μ = 535 τ_ρ.
        let thick = stable_dt(sigma, rho, 1e3, dx);
        assert!((thick - 0.1 * 1e3 * dx / sigma).abs() < 1e-12 * thick);
        assert!(thick > 500.0 * tau_rho);
    }
}
