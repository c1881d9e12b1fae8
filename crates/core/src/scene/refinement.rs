//! The `solver.refinement` section: finer grid levels over boxes the scene names
//! (truncated hierarchical B-splines, `crate::refinement`), what a refined scene may hold,
//! and the particles it splits so that every level's cells start with the body's
//! particles per cell.

use super::Transfer;
use super::validator::Validator;
use super::{AntiLocking, BodyParticles, Domain, KernelName, Mechanics, Scene, Scheme, Shape};
use crate::math::{Vector, vector_from_slice};
use crate::refinement::{Kinematics, Levels, RefinementError, split};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Finer grid levels over named regions (`solver.refinement`): each level halves the cell
/// size of the one before it over the union of its boxes, within that level's region.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Refinement {
    /// The refined levels, coarsest first (at most 8). No level runs the refined step on
    /// the base grid alone (the uniform run it is compared with).
    pub levels: Vec<RefinedLevel>,
}

/// One refined level: the boxes whose union it covers. A box grows outward to the cells
/// of the level before it that it touches (their faces lie half a cell off the grid
/// nodes) and is cut to that level's region.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RefinedLevel {
    /// Boxes (min and max corners, m) whose union is the level's region.
    pub boxes: Vec<RegionBox>,
}

/// An axis-aligned box of a refined level.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RegionBox {
    /// Lower corner, m.
    pub min: Vec<f64>,
    /// Upper corner, m.
    pub max: Vec<f64>,
}

/// Why every refusal below is given.
const REFINED_STEP: &str = "the refined step (solver.refinement) is explicit dynamics with \
                            quadratic B-splines, APIC and USL so far";

impl Refinement {
    /// The levels over the run's grid (the domain padded by `GRID_PADDING` cells, as the
    /// solver builds it): level-0 function j is grid node j's quadratic B-spline.
    pub fn grid_levels<const D: usize>(
        &self,
        domain: &Domain,
    ) -> Result<Levels<D>, RefinementError> {
        let pad = crate::boundary::GRID_PADDING;
        let dx = domain.cell_size;
        let min = vector_from_slice::<D>(&domain.min) - Vector::<D>::repeat(pad as f64 * dx);
        let cells: [usize; D] = std::array::from_fn(|d| {
            ((domain.max[d] - domain.min[d]) / dx - 1e-9).ceil() as usize + 2 * pad
        });
        let planes = mirror_planes::<D>(domain);
        let boxes: Vec<Vec<(Vector<D>, Vector<D>)>> = self
            .levels
            .iter()
            .map(|level| {
                let mut boxes: Vec<(Vector<D>, Vector<D>)> = level
                    .boxes
                    .iter()
                    .map(|b| (vector_from_slice(&b.min), vector_from_slice(&b.max)))
                    .collect();
                for &(axis, plane) in &planes {
                    for k in 0..boxes.len() {
                        let (mut lo, mut hi) = boxes[k];
                        (lo[axis], hi[axis]) = (2.0 * plane - hi[axis], 2.0 * plane - lo[axis]);
                        boxes.push((lo, hi));
                    }
                }
                boxes
            })
            .collect();
        Levels::for_grid(min, dx, cells, &boxes)
    }
}

/// The planes (axis, position) of the domain's stick and symmetry walls. Each level's
/// boxes are mirrored across them (the images lie in the grid's padding, or are cut off
/// it), so the levels are symmetric about every such wall and the refined step's fold of
/// the functions behind a wall onto their mirror images is exact, as on the uniform grid.
fn mirror_planes<const D: usize>(domain: &Domain) -> Vec<(usize, f64)> {
    use super::Contact;
    let dx = domain.cell_size;
    let mut planes = Vec::new();
    for wall in &domain.walls {
        if !matches!(wall.condition, Contact::Stick | Contact::Symmetry) {
            continue;
        }
        let inset = wall.thickness.max(1) as f64 - 1.0;
        for side in &wall.sides {
            let (axis, upper) = side.axis_and_upper();
            if axis >= D {
                continue;
            }
            let plane = if upper {
                let cells = ((domain.max[axis] - domain.min[axis]) / dx - 1e-9).ceil();
                domain.min[axis] + (cells - inset) * dx
            } else {
                domain.min[axis] + inset * dx
            };
            planes.push((axis, plane));
        }
    }
    planes
}

impl Validator {
    /// Checks `solver.refinement` and refuses what the refined step does not do yet, each
    /// at its JSON path.
    pub(super) fn check_refinement(&mut self, s: &Scene) {
        let Some(refinement) = &s.solver.refinement else {
            return;
        };
        let p = "solver.refinement";
        let max = crate::refinement::MAX_LEVELS;
        if refinement.levels.len() > max {
            self.err(
                format!("{p}.levels"),
                format!(
                    "at most {max} refined levels (got {})",
                    refinement.levels.len()
                ),
            );
            return;
        }
        let before = self.issues.len();
        for (k, level) in refinement.levels.iter().enumerate() {
            if level.boxes.is_empty() {
                self.err(format!("{p}.levels[{k}].boxes"), "needs at least one box");
            }
            for (b, region) in level.boxes.iter().enumerate() {
                self.box_corners(
                    &format!("{p}.levels[{k}].boxes[{b}]"),
                    &region.min,
                    &region.max,
                );
            }
        }
        if self.issues.len() == before && s.domain.cell_size > 0.0 {
            let built = match self.dim {
                2 => refinement
                    .grid_levels::<2>(&s.domain)
                    .map(|l| region_sizes(&l)),
                _ => refinement
                    .grid_levels::<3>(&s.domain)
                    .map(|l| region_sizes(&l)),
            };
            match built {
                Ok(sizes) => {
                    for (k, &n) in sizes.iter().enumerate().skip(1) {
                        if n == 0 {
                            self.err(
                                format!("{p}.levels[{}].boxes", k - 1),
                                "no box reaches a cell of the level before it (inside the \
                                 grid): the level would be empty",
                            );
                        }
                    }
                }
                Err(RefinementError::Elements {
                    level,
                    elements,
                    max,
                }) => self.err(
                    format!("{p}.levels[{}]", level.saturating_sub(1)),
                    format!(
                        "this level's grid would span {elements} cells (at most {max}: each \
                         level keeps a dense mask over the whole domain); refine fewer levels \
                         or use a coarser domain.cell_size"
                    ),
                ),
                Err(e) => self.err(p, e.to_string()),
            }
        }
        self.refuse_unrefined(s);
    }

    /// What a refined scene may not hold yet.
    fn refuse_unrefined(&mut self, s: &Scene) {
        if s.solver.mechanics != Mechanics::Dynamic {
            self.err(
                "solver.mechanics",
                format!("{REFINED_STEP}: use `dynamic` mechanics"),
            );
        }
        if s.solver.kernel != KernelName::Bspline2 {
            self.err("solver.kernel", format!("{REFINED_STEP}: use `bspline2`"));
        }
        if s.solver.transfer != Transfer::Apic {
            self.err("solver.transfer", format!("{REFINED_STEP}: use `apic`"));
        }
        if s.solver.scheme != Scheme::Usl {
            self.err("solver.scheme", format!("{REFINED_STEP}: use `usl`"));
        }
        if s.solver.mls {
            self.err("solver.mls", format!("{REFINED_STEP}: remove it"));
        }
        if s.solver.anti_locking == AntiLocking::Fbar {
            self.err(
                "solver.anti_locking",
                format!("{REFINED_STEP}, without F-bar: remove it"),
            );
        }
        if s.contact.is_some() {
            self.err("contact", format!("{REFINED_STEP}, without contact fields"));
        }
        if let Some(name) = s.physics.keys().next() {
            self.err(
                format!("physics.{name}"),
                format!("{REFINED_STEP}; physics operators work on the uniform grid"),
            );
        }
        if !s.stages.is_empty() {
            self.err("stages", format!("{REFINED_STEP}, in one stage"));
        }
        for (k, body) in s.bodies.iter().enumerate() {
            if matches!(body.shape, Shape::Inflow(_)) {
                self.err(
                    format!("bodies[{k}].shape"),
                    format!("{REFINED_STEP}; particles cannot enter it during the run"),
                );
            }
        }
    }
}

/// Elements in each level's region.
fn region_sizes<const D: usize>(levels: &Levels<D>) -> Vec<usize> {
    (0..levels.len()).map(|l| levels.region_len(l)).collect()
}

/// Splits every particle of `body` that lies in a refined region into 2^D children per
/// level it lies below (`crate::refinement::split`: at its sub-cells' centres, each with
/// 1/2^D of the volume), so that a level's cells start with as many particles as the base
/// level's. The caller then drops the children outside the shape and cuts the holes, so
/// both follow each level's spacing. Called before the initial velocities are set, so
/// they are evaluated at the children's places. Stops, saying so, once the body would hold
/// more than `max_particles`.
pub(super) fn split_for_refinement(
    dim: usize,
    refinement: &Refinement,
    domain: &Domain,
    body: &mut BodyParticles,
    max_particles: u64,
) -> Result<(), String> {
    let within = match dim {
        2 => refinement
            .grid_levels::<2>(domain)
            .map(|levels| split_body(&levels, body, max_particles)),
        _ => refinement
            .grid_levels::<3>(domain)
            .map(|levels| split_body(&levels, body, max_particles)),
    };
    match within {
        Ok(true) => Ok(()),
        Ok(false) => Err(format!(
            "splitting the particles in the refined levels would make more than \
             {max_particles} particles (limit `particles`): refine fewer levels or smaller boxes"
        )),
        Err(e) => Err(e.to_string()),
    }
}

/// The split of `body`'s particles; false (the body left as it was) once it would hold
/// more than `max_particles`.
fn split_body<const D: usize>(
    levels: &Levels<D>,
    body: &mut BodyParticles,
    max_particles: u64,
) -> bool {
    if levels.len() == 1 {
        return true;
    }
    // At least 2^(D·ℓ) children per particle at level ℓ: refuse a split far over the
    // limit before making any.
    let least = body.positions.chunks_exact(D).fold(0u64, |n, x| {
        let level = levels.finest_level(&vector_from_slice::<D>(x)).unwrap_or(0);
        n.saturating_add(1u64 << (D * level).min(63))
    });
    if least > max_particles {
        return false;
    }
    let mut positions = Vec::with_capacity(body.positions.len());
    let mut volumes = Vec::with_capacity(body.volumes.len());
    // (particle, its level, its spacing), depth first.
    let mut pending = Vec::new();
    let mut children = Vec::new();
    for (x, &volume) in body.positions.chunks_exact(D).zip(&body.volumes) {
        pending.push((
            Kinematics {
                position: vector_from_slice::<D>(x),
                mass: volume,
                volume,
                velocity: Vector::<D>::zeros(),
                affine: crate::math::Matrix::<D>::zeros(),
            },
            0usize,
            body.spacing,
        ));
        while let Some((particle, depth, spacing)) = pending.pop() {
            let target = levels.finest_level(&particle.position).unwrap_or(0);
            if depth >= target {
                if volumes.len() as u64 >= max_particles {
                    return false;
                }
                positions.extend(particle.position.iter());
                volumes.push(particle.volume);
                continue;
            }
            split(&particle, spacing, &mut children);
            pending.extend(
                children
                    .drain(..)
                    .rev()
                    .map(|c| (c, depth + 1, 0.5 * spacing)),
            );
        }
    }
    body.positions = positions;
    body.volumes = volumes;
    true
}
