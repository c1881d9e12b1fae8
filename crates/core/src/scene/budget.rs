//! Bounds on the work a scene asks for, checked from its numbers before anything is
//! allocated: particles from the shapes' volumes inside the domain, grid nodes, frames, the
//! size of the result store, time steps, set-up point tests. A scene over a limit is refused
//! with the estimate and the limit, at the JSON path of the number that set it.

use super::Issue;
use super::lattice::{BoxLattice, CentredLattice, MAX_SPACINGS, Region, bounding_box};
use super::{AntiLocking, Scene, Shape};
use crate::grid_activity::{BLOCK_NODES, MAX_BLOCKS_PER_PARTICLE};
use crate::plugin::Registry;
use std::sync::OnceLock;

/// Most nodes a grid may span: a sparse grid reserves address space for the whole box
/// (32 bytes a node in 3D: 0.5 TB here), though it takes memory only where particles are.
pub const MAX_GRID_SPAN_NODES: f64 = 1.6e10;

/// The largest work a scene may ask for. The defaults are generous for one machine; `mpm`
/// raises them with `--limit NAME=N` and the job service sets its own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Most particles of all bodies together (estimated from the shapes, then counted).
    pub max_particles: u64,
    /// Most grid nodes, the padding around the domain included.
    pub max_grid_nodes: u64,
    /// Most output frames.
    pub max_frames: u64,
    /// Largest result store, bytes: (frames + 1) × particles × stored numbers × 8.
    pub max_store_bytes: u64,
    /// Largest particle file (CSV) read into memory, bytes.
    pub max_file_bytes: u64,
    /// Most time steps a fixed `solver.dt` may ask for (end_time / dt).
    pub max_steps: u64,
    /// Most point tests while generating particles: lattice points visited to fill the
    /// shapes, plus particles × holes.
    pub max_setup_tests: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_particles: 20_000_000,
            max_grid_nodes: 30_000_000,
            max_frames: 100_000,
            max_store_bytes: 100_000_000_000,
            max_file_bytes: 4_000_000_000,
            max_steps: 1_000_000_000,
            max_setup_tests: 2_000_000_000,
        }
    }
}

static CURRENT: OnceLock<Limits> = OnceLock::new();

impl Limits {
    /// The limits of this process: those given to [`Limits::set_current`], else the defaults.
    pub fn current() -> Limits {
        CURRENT.get().copied().unwrap_or_default()
    }

    /// Sets this process's limits once (the `mpm` binary does so from `--limit`); returns
    /// false when they were already set.
    pub fn set_current(limits: Limits) -> bool {
        CURRENT.set(limits).is_ok()
    }

    /// The names `--limit NAME=N` accepts.
    pub const NAMES: &'static [&'static str] = &[
        "particles",
        "grid_nodes",
        "frames",
        "store_bytes",
        "file_bytes",
        "steps",
        "setup_tests",
    ];

    /// Sets one limit from `NAME=N` (`particles=5e7`).
    pub fn apply(&mut self, assignment: &str) -> Result<(), String> {
        let (name, raw) = assignment
            .split_once('=')
            .ok_or_else(|| format!("`{assignment}`: expected NAME=N"))?;
        let value: f64 = raw
            .trim()
            .parse()
            .map_err(|_| format!("`{assignment}`: `{raw}` is not a number"))?;
        if !(value >= 1.0 && value <= u64::MAX as f64) {
            return Err(format!("`{assignment}`: a limit must be a number >= 1"));
        }
        let value = value as u64;
        let slot = match name.trim() {
            "particles" => &mut self.max_particles,
            "grid_nodes" => &mut self.max_grid_nodes,
            "frames" => &mut self.max_frames,
            "store_bytes" => &mut self.max_store_bytes,
            "file_bytes" => &mut self.max_file_bytes,
            "steps" => &mut self.max_steps,
            "setup_tests" => &mut self.max_setup_tests,
            other => {
                return Err(format!(
                    "unknown limit `{other}` (known: {})",
                    Self::NAMES.join(", ")
                ));
            }
        };
        *slot = value;
        Ok(())
    }
}

/// What a scene would cost, estimated from its numbers without generating anything.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Particles of each body (shape volume inside the domain / spacing^D; 0 for files).
    pub body_particles: Vec<f64>,
    /// Lattice points visited to fill each body's shape.
    pub body_points: Vec<f64>,
    /// Grid nodes held in memory at most (0 when the domain is malformed): the whole box,
    /// padding included, for the shared grid and every contact field's grid; for a sparse
    /// grid no more than its particles' stencils can reach.
    pub grid_nodes: f64,
    /// Nodes of the box the grid spans (its address space, for a sparse grid).
    pub grid_span_nodes: f64,
}

impl Estimate {
    /// Particles of all bodies.
    pub fn particles(&self) -> f64 {
        self.body_particles.iter().sum()
    }
}

/// The domain as a region, when it is well formed.
fn domain_region(s: &Scene, dim: usize) -> Option<Region> {
    let d = &s.domain;
    if d.min.len() != dim || d.max.len() != dim || !(d.cell_size.is_finite() && d.cell_size > 0.0) {
        return None;
    }
    let mut r = Region {
        lo: [0.0; 3],
        hi: [0.0; 3],
    };
    for a in 0..dim {
        if !(d.min[a].is_finite() && d.max[a].is_finite() && d.max[a] > d.min[a]) {
            return None;
        }
        r.lo[a] = d.min[a];
        r.hi[a] = d.max[a];
    }
    Some(r)
}

/// Whether a shape's numbers are all there and finite (else validation reports them).
fn well_formed(dim: usize, shape: &Shape) -> bool {
    let vector = |v: &[f64]| v.len() == dim && v.iter().all(|x| x.is_finite());
    match shape {
        Shape::Box { min, max } => vector(min) && vector(max),
        Shape::Sphere { center, radius } => vector(center) && radius.is_finite() && *radius > 0.0,
        Shape::Cylinder {
            center,
            radius,
            axis,
            length,
        } => {
            dim == 3
                && vector(center)
                && vector(axis)
                && axis.iter().any(|x| *x != 0.0)
                && radius.is_finite()
                && *radius > 0.0
                && length.is_finite()
                && *length > 0.0
        }
        Shape::File { .. } | Shape::Inflow(_) => false,
    }
}

/// The region a body's particles may occupy: the domain, or (without `clip_to_domain`)
/// the domain and one cell around it, where the per-particle check still refuses any
/// particle outside; shapes reaching further are refused up front.
pub(crate) fn body_region(domain: &Region, cell: f64, clip: bool) -> Region {
    let mut r = *domain;
    if !clip {
        for a in 0..3 {
            r.lo[a] -= cell;
            r.hi[a] += cell;
        }
    }
    r
}

/// Lattice points visited and particles expected for one shape within `region`.
fn shape_cost(dim: usize, shape: &Shape, h: f64, region: &Region) -> (f64, f64) {
    let Some(bounds) = bounding_box(dim, shape) else {
        return (0.0, 0.0);
    };
    let bounds = bounds.intersect(region);
    match shape {
        Shape::Box { min, max } => {
            let points = BoxLattice::new(dim, min, max, h, region).map_or(0.0, |l| l.points());
            (points, points)
        }
        Shape::Sphere { center, radius } => {
            let points = CentredLattice::new(dim, center, *radius, h, [0.5; 3], &bounds).points();
            let volume = if dim == 2 {
                std::f64::consts::PI * radius * radius
            } else {
                4.0 / 3.0 * std::f64::consts::PI * radius.powi(3)
            };
            (points, points.min(volume / h.powi(dim as i32)))
        }
        Shape::Cylinder {
            center,
            radius,
            length,
            ..
        } => {
            let reach = (radius * radius + length * length / 4.0).sqrt();
            let points = CentredLattice::new(dim, center, reach, h, [0.5; 3], &bounds).points();
            let volume = std::f64::consts::PI * radius * radius * length;
            (points, points.min(volume / h.powi(3)))
        }
        Shape::File { .. } | Shape::Inflow(_) => (0.0, 0.0),
    }
}

/// Estimates a scene's particles and grid without generating anything. Malformed parts
/// (which validation reports) count as zero. The registry says which physics sections keep
/// their node arrays to the particles' stencils
/// ([`crate::physics::PhysicsFactory::node_arrays_follow_particles`]); an unknown section
/// counts as one over the whole grid.
pub fn estimate(s: &Scene, registry: &Registry) -> Estimate {
    let dim = s.dimension as usize;
    let mut e = Estimate::default();
    if dim != 2 && dim != 3 {
        return e;
    }
    let Some(domain) = domain_region(s, dim) else {
        return e;
    };
    let dx = s.domain.cell_size;
    let pad = crate::boundary::GRID_PADDING as f64;
    e.grid_nodes = (0..dim)
        .map(|a| ((domain.hi[a] - domain.lo[a]) / dx - 1e-9).ceil() + 2.0 * pad + 1.0)
        .product();
    if let Some(contact) = &s.contact {
        // Contact gives every named body (and the unnamed ones together) a grid of its own.
        let mut names: Vec<&str> = contact
            .pairs
            .iter()
            .flat_map(|p| p.bodies.iter().map(String::as_str))
            .collect();
        names.sort_unstable();
        names.dedup();
        e.grid_nodes *= (names.len() + 2) as f64;
    }
    for b in &s.bodies {
        let h = dx / f64::from(b.particles_per_cell.clamp(1, 8));
        let region = body_region(&domain, dx, b.clip_to_domain);
        let (points, particles) = if let Shape::Inflow(inflow) = &b.shape {
            let n = inflow.particle_estimate(dim, h, s.solver.end_time);
            (n, n)
        } else if well_formed(dim, &b.shape) && spacings_ok(dim, &b.shape, h) {
            shape_cost(dim, &b.shape, h, &region)
        } else {
            (0.0, 0.0)
        };
        e.body_points.push(points);
        e.body_particles.push(particles);
    }
    e.grid_span_nodes = e.grid_nodes;
    // A sparse grid holds only the blocks particles reach. The estimate leaves it out where
    // the scene keeps other arrays over the whole box (F-bar's, and those of physics
    // operators whose node arrays do not follow the particles' stencils).
    let dense_arrays = s.solver.anti_locking == AntiLocking::Fbar
        || s.physics.keys().any(|k| {
            !registry
                .physics(k)
                .is_some_and(|(_, f)| f.node_arrays_follow_particles())
        });
    if s.solver.sparse_grid(s.contact.is_some()) && !dense_arrays {
        let reach = e.particles() * (MAX_BLOCKS_PER_PARTICLE * BLOCK_NODES) as f64;
        e.grid_nodes = e.grid_nodes.min(reach);
    }
    e
}

/// Whether a shape spans at most [`MAX_SPACINGS`] particle spacings on every axis.
fn spacings_ok(dim: usize, shape: &Shape, h: f64) -> bool {
    bounding_box(dim, shape)
        .is_some_and(|b| (0..dim).all(|a| (b.hi[a] - b.lo[a]) / h <= MAX_SPACINGS))
}

/// Checks a scene against `limits` before anything is generated. Shapes reaching more than
/// a cell beyond the domain are refused (unless the body clips to the domain) at the path of
/// the offending number.
pub(crate) fn check(s: &Scene, limits: &Limits, registry: &Registry) -> Vec<Issue> {
    let mut issues = Vec::new();
    let dim = s.dimension as usize;
    if dim != 2 && dim != 3 {
        return issues;
    }
    let big = |x: f64, limit: u64| x > limit as f64;
    if big(f64::from(s.output.frames), limits.max_frames) {
        issues.push(Issue::new(
            "output.frames",
            format!(
                "{} frames; at most {} are allowed (limit `frames`)",
                s.output.frames, limits.max_frames
            ),
        ));
    }
    if let Some(dt) = s.solver.dt
        && dt > 0.0
        && big(s.solver.end_time / dt, limits.max_steps)
    {
        issues.push(Issue::new(
            "solver.dt",
            format!(
                "end_time / dt asks for {:.3e} steps; at most {} are allowed (limit `steps`)",
                s.solver.end_time / dt,
                limits.max_steps
            ),
        ));
    }
    let Some(domain) = domain_region(s, dim) else {
        return issues;
    };
    let dx = s.domain.cell_size;
    for (i, b) in s.bodies.iter().enumerate() {
        let h = dx / f64::from(b.particles_per_cell.clamp(1, 8));
        if !well_formed(dim, &b.shape) {
            continue;
        }
        let path = format!("bodies[{i}].shape");
        if !b.clip_to_domain {
            let region = body_region(&domain, dx, false);
            if let Some(issue) = reach_issue(dim, &path, &b.shape, &domain, &region) {
                issues.push(issue);
                continue;
            }
        }
        if !spacings_ok(dim, &b.shape, h) {
            issues.push(Issue::new(
                &path,
                format!(
                    "the shape spans more than {MAX_SPACINGS:e} particle spacings on an axis; \
                     no grid could hold it"
                ),
            ));
        }
    }
    if !issues.is_empty() {
        return issues;
    }
    let e = estimate(s, registry);
    if big(e.grid_nodes, limits.max_grid_nodes) {
        issues.push(Issue::new(
            "domain.cell_size",
            format!(
                "the grid would hold {:.3e} nodes (domain / cell_size, with padding, or for a \
                 sparse grid what its particles can reach); at most {} are allowed (limit \
                 `grid_nodes`)",
                e.grid_nodes, limits.max_grid_nodes
            ),
        ));
    } else if e.grid_span_nodes > MAX_GRID_SPAN_NODES {
        issues.push(Issue::new(
            "domain.cell_size",
            format!(
                "the grid would span {:.3e} nodes (domain / cell_size, with padding); a grid \
                 spans at most {MAX_GRID_SPAN_NODES:.1e}, even a sparse one",
                e.grid_span_nodes
            ),
        ));
    }
    let total = e.particles();
    for (i, b) in s.bodies.iter().enumerate() {
        let (points, particles) = (e.body_points[i], e.body_particles[i]);
        if big(particles, limits.max_particles) {
            issues.push(Issue::new(
                format!("bodies[{i}].shape"),
                format!(
                    "holds about {particles:.3e} particles (its volume inside the domain / \
                     particle spacing^{dim}); at most {} are allowed (limit `particles`)",
                    limits.max_particles
                ),
            ));
        } else if big(points, limits.max_setup_tests) {
            issues.push(Issue::new(
                format!("bodies[{i}].shape"),
                format!(
                    "filling it tests {points:.3e} lattice points; at most {} are allowed \
                     (limit `setup_tests`)",
                    limits.max_setup_tests
                ),
            ));
        }
        let hole_tests = particles * b.holes.len() as f64;
        if big(hole_tests, limits.max_setup_tests) {
            issues.push(Issue::new(
                format!("bodies[{i}].holes"),
                format!(
                    "{} holes × about {particles:.3e} particles = {hole_tests:.3e} tests; at \
                     most {} are allowed (limit `setup_tests`)",
                    b.holes.len(),
                    limits.max_setup_tests
                ),
            ));
        }
    }
    if issues.is_empty() && big(total, limits.max_particles) {
        issues.push(Issue::new(
            "bodies",
            format!(
                "the bodies hold about {total:.3e} particles together; at most {} are allowed \
                 (limit `particles`)",
                limits.max_particles
            ),
        ));
    }
    let numbers: f64 = s
        .output
        .fields
        .iter()
        .map(|f| match f.as_str() {
            "x" | "v" => dim as f64,
            "stress" | "F" => (dim * dim) as f64,
            _ => 1.0,
        })
        .sum();
    let store = (f64::from(s.output.frames) + 1.0) * total * numbers * 8.0;
    if big(store, limits.max_store_bytes) {
        issues.push(Issue::new(
            "output.frames",
            format!(
                "the results would take about {store:.3e} bytes ({} frames × {total:.3e} \
                 particles × {numbers} numbers × 8); at most {} are allowed (limit `store_bytes`)",
                f64::from(s.output.frames) + 1.0,
                limits.max_store_bytes
            ),
        ));
    }
    issues
}

/// The issue of a shape whose bounding box leaves `region` (the domain and one cell),
/// naming the number that takes it out.
fn reach_issue(
    dim: usize,
    path: &str,
    shape: &Shape,
    domain: &Region,
    region: &Region,
) -> Option<Issue> {
    let bounds = bounding_box(dim, shape)?;
    let axis = (0..dim).find(|&a| bounds.lo[a] < region.lo[a] || bounds.hi[a] > region.hi[a])?;
    let (low, value) = if bounds.lo[axis] < region.lo[axis] {
        (true, bounds.lo[axis])
    } else {
        (false, bounds.hi[axis])
    };
    let inside = |x: f64| x >= region.lo[axis] && x <= region.hi[axis];
    let at = match shape {
        Shape::Box { .. } => format!("{path}.box.{}[{axis}]", if low { "min" } else { "max" }),
        Shape::Sphere { center, .. } if !inside(center[axis]) => {
            format!("{path}.sphere.center[{axis}]")
        }
        Shape::Sphere { .. } => format!("{path}.sphere.radius"),
        Shape::Cylinder { center, .. } if !inside(center[axis]) => {
            format!("{path}.cylinder.center[{axis}]")
        }
        Shape::Cylinder { .. } => format!("{path}.cylinder"),
        Shape::File { .. } | Shape::Inflow(_) => return None,
    };
    Some(Issue::new(
        at,
        format!(
            "the shape reaches {value:e} on axis {axis}, more than a cell outside the domain \
             [{:e}, {:e}]: particles outside the grid are an error (shrink the shape, enlarge \
             the domain, or set `clip_to_domain` to keep only the part inside)",
            domain.lo[axis], domain.hi[axis]
        ),
    ))
}
