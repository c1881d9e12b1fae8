//! The refined explicit step (`solver.refinement`): USL explicit dynamics with APIC whose
//! grid is the truncated hierarchical B-spline basis of `crate::refinement` instead of
//! the uniform grid's nodes. P2G scatters mass, affine momentum and the stress's force
//! to every active function not zero at a particle; the functions' velocities are
//! updated, held by walls and obstacles at their centres (Greville points) as nodes are;
//! G2P gathers the velocity, APIC's C = B·D_p⁻¹ with the particle's own inertia D_p (so
//! angular momentum is kept across levels) and ∇v for F. One global step, bounded by the
//! finest level's cell. Stick and symmetry walls fold the functions behind them onto
//! their mirror images on the same level, as the uniform grid folds its ghost nodes
//! (`Boundaries::fold_stick_walls`): exact where the levels are symmetric about the wall's
//! plane. Without a refined level the step is the uniform explicit step on the base grid.

use super::DimensionDispatch;
use super::grid_update::GridWork;
use super::mode::StepMode;
use super::parallel::{SharedSlice, chunk_count, chunk_range, ordered_reduce};
use super::simulation::Simulation;
use super::stage_clock::StepStage;
use super::stats::{KinematicStats, ParticleFault};
use super::timestep::stable_time_step;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector, determinant, inverse};
use crate::refinement::{ExtractionCache, LevelGrid, Levels, ThbBasis, Weight};
use rayon::prelude::*;
use std::time::Instant;

/// What one slab of P2G keeps from step to step: each element's extraction, and the
/// weights of the slab's particles this step, one after the other (G2P reads them again:
/// particles do not move between the two).
#[derive(Default)]
struct Scratch<const D: usize> {
    cache: ExtractionCache<D>,
    weights: Vec<Weight<D>>,
}

/// Where one particle's weights of this step lie: `weights[start..start + len]` of slab
/// `slab`'s scratch; `len` 0 where the particle is off the basis.
#[derive(Clone, Copy, Debug, Default)]
struct WeightRange {
    slab: u32,
    start: u32,
    len: u32,
}

/// A stick or symmetry wall's ghost function (its centre behind the wall's plane) and the
/// active function of its level mirrored across the plane, onto which it folds.
#[derive(Clone, Copy, Debug)]
struct Mirror {
    ghost: u32,
    front: u32,
    axis: usize,
    symmetry: bool,
}

impl Mirror {
    /// The mirror image of a momentum or velocity: negated behind a stick wall, its normal
    /// component negated behind a symmetry wall.
    fn image<const D: usize>(&self, mut v: Vector<D>) -> Vector<D> {
        if self.symmetry {
            v[self.axis] = -v[self.axis];
            v
        } else {
            -v
        }
    }
}

/// The refined step's state: the basis, its grid and the passes' scratch.
pub(super) struct Refined<const D: usize> {
    basis: ThbBasis<D>,
    /// Every active function's centre, m.
    centers: Vec<Vector<D>>,
    /// How far outside a stick grip each function's centre may lie and still be held, m:
    /// 0 on the base level, half the level's cell on a refined one (`new`).
    obstacle_reach: Vec<f64>,
    grid: LevelGrid<D>,
    /// Force per function, N (N/m in 2D).
    force: Vec<Vector<D>>,
    /// P2G's particles per x-slab of three base cells, and each slab's scratch.
    slabs: Vec<Vec<u32>>,
    slab_scratch: Vec<Scratch<D>>,
    /// Each particle's weights of this step in `slab_scratch` (written by P2G).
    located: Vec<WeightRange>,
    /// The finest level's cell size, m: the step's bound.
    finest_spacing: f64,
    /// Ghost functions of stick and symmetry walls, wall by wall, nearest the plane first
    /// (found at the first step, from the run's walls).
    mirrors: Option<Vec<Mirror>>,
}

impl<const D: usize> Refined<D> {
    /// The step on `levels` (`Levels::for_grid` over the run's grid).
    pub(super) fn new(levels: Levels<D>) -> Self {
        let finest = (0..levels.len())
            .rev()
            .find(|&l| levels.region_len(l) > 0)
            .unwrap_or(0);
        let finest_spacing = levels.level_spacing(finest);
        let basis = ThbBasis::new(levels);
        let centers = (0..basis.len() as u32).map(|id| basis.center(id)).collect();
        // A refined level's function centres lie half its cell off the node planes of a
        // uniform grid of its cell, where scenes put obstacle faces (just short of a node
        // plane, so that a uniform grid holds the nodes on it): held only when inside, the
        // free function beside the face reaches past the body's surface and leaves it
        // traction-free under the obstacle. Reaching half a cell out holds it instead
        // (stick obstacles not moving along their normal only: `Boundaries::apply_booked_at`).
        let obstacle_reach = (0..basis.len() as u32)
            .map(|id| match basis.function(id).0 {
                0 => 0.0,
                level => 0.5 * basis.levels().level_spacing(level),
            })
            .collect();
        Self {
            basis,
            centers,
            obstacle_reach,
            grid: LevelGrid::default(),
            force: Vec::new(),
            slabs: Vec::new(),
            slab_scratch: Vec::new(),
            located: Vec::new(),
            finest_spacing,
            mirrors: None,
        }
    }

    /// Every stick or symmetry wall's ghost functions with their mirrors. Level ℓ's
    /// function with first knot j along the wall's axis is centred at node 0 +
    /// (j + 1.5 − 1.5·2^ℓ)·h_ℓ (`Levels::for_grid`), so across the plane of node s its
    /// image has first knot (3 + 2s)·2^ℓ − 3 − j; a ghost whose image is not active on
    /// its level is held by the wall without folding.
    fn find_mirrors(
        &self,
        boundaries: &crate::boundary::Boundaries<D>,
        origin: &Vector<D>,
        dx: f64,
    ) -> Vec<Mirror> {
        use crate::scene::Contact;
        let mut mirrors = Vec::new();
        for wall in boundaries.wall_planes() {
            let symmetry = match wall.condition {
                Contact::Stick => false,
                Contact::Symmetry => true,
                _ => continue,
            };
            let a = wall.axis;
            let plane = origin[a] + wall.surface as f64 * dx;
            let mut ghosts: Vec<(f64, Mirror)> = Vec::new();
            for (id, centre) in self.centers.iter().enumerate() {
                let depth = if wall.upper {
                    centre[a] - plane
                } else {
                    plane - centre[a]
                };
                if depth <= 1e-9 * dx {
                    continue;
                }
                let (level, mut knot) = self.basis.function(id as u32);
                knot[a] = ((3 + 2 * wall.surface as i64) << level) - 3 - knot[a];
                if let Some(front) = self.basis.id(level, &knot) {
                    let mirror = Mirror {
                        ghost: id as u32,
                        front,
                        axis: a,
                        symmetry,
                    };
                    ghosts.push((depth, mirror));
                }
            }
            ghosts.sort_by(|x, y| x.0.total_cmp(&y.0));
            mirrors.extend(ghosts.into_iter().map(|(_, m)| m));
        }
        mirrors
    }

    /// P2G: mass, APIC momentum, the stress's force and dead loads per function. Particles
    /// are binned into x-slabs three base cells wide and slabs of one colour (even, then
    /// odd) scatter in parallel: every function's support spans at most three base cells
    /// along x, so no function is written from two slabs of one colour.
    fn particles_to_functions<K: Kernel>(&mut self, sim: &Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        self.grid.clear(&self.basis);
        self.force.clear();
        self.force.resize(self.basis.len(), Vector::<D>::zeros());
        let p = &sim.particles;
        let width = 3.0 * sim.grid.dx;
        let count = ((sim.grid.cells[0] as f64 * sim.grid.dx) / width).ceil() as usize + 1;
        self.slabs.resize_with(count, Vec::new);
        self.slab_scratch.resize_with(count, Default::default);
        for slab in &mut self.slabs {
            slab.clear();
        }
        let x0 = sim.grid.origin[0];
        for (k, x) in p.position.iter().enumerate() {
            let s = ((x[0] - x0) / width).floor().clamp(0.0, (count - 1) as f64) as usize;
            self.slabs[s].push(k as u32);
        }
        let loads = (!p.external_force.is_empty()).then_some(&p.external_force);
        self.located.resize(p.len(), WeightRange::default());
        let mass_out = SharedSlice::new(&mut self.grid.mass);
        let momentum_out = SharedSlice::new(&mut self.grid.momentum);
        let force_out = SharedSlice::new(&mut self.force);
        let located = SharedSlice::new(&mut self.located);
        let (basis, centers, slabs) = (&self.basis, &self.centers, &self.slabs);
        for colour in 0..2 {
            self.slab_scratch
                .par_iter_mut()
                .enumerate()
                .filter(|(s, _)| s % 2 == colour)
                .for_each(|(s, scratch)| {
                    let Scratch { cache, weights } = scratch;
                    weights.clear();
                    for &k in &slabs[s] {
                        let k = k as usize;
                        let x = &p.position[k];
                        let start = weights.len();
                        // A particle off the basis stopped the run at the G2P before.
                        let found = basis.append_cached(cache, x, weights).is_ok();
                        let range = WeightRange {
                            slab: s as u32,
                            start: start as u32,
                            len: if found {
                                (weights.len() - start) as u32
                            } else {
                                0
                            },
                        };
                        // SAFETY: every particle lies in exactly one slab.
                        unsafe { *located.get(k) = range };
                        if !found {
                            weights.truncate(start);
                            continue;
                        }
                        let m = p.mass[k];
                        let volume = p.volume0[k] * determinant(&p.deformation_gradient[k]);
                        let stress = p.stress[k] * volume;
                        let load = loads.map_or(Vector::<D>::zeros(), |l| l[k]);
                        for w in &weights[start..] {
                            let i = w.id as usize;
                            let offset = centers[i] - x;
                            // SAFETY: slabs of one colour write disjoint functions (above).
                            unsafe {
                                *mass_out.get(i) += w.value * m;
                                *momentum_out.get(i) +=
                                    (p.velocity[k] + p.affine[k] * offset) * (w.value * m);
                                *force_out.get(i) += load * w.value - stress * w.gradient;
                            }
                        }
                    }
                });
        }
    }

    /// Momentum and forces to velocity, damping, walls and obstacles; the work they did.
    fn update_functions<K: Kernel>(&mut self, sim: &Simulation<D, K>, dt: f64) -> GridWork
    where
        dyn Material: DimensionDispatch<D>,
    {
        let gravity = sim.settings.gravity;
        let damping = (-sim.settings.damping * dt).exp();
        let time = sim.time + dt;
        let grid = (&sim.grid.origin, sim.grid.dx);
        let mirrors = self.mirrors.take().unwrap_or_default();
        let mut work = GridWork::default();
        let LevelGrid { mass, momentum } = &mut self.grid;
        for (i, p) in momentum.iter_mut().enumerate() {
            *p += (self.force[i] + gravity * mass[i]) * dt;
        }
        // The body's image behind stick and symmetry walls, as P2G of body and image.
        for m in &mirrors {
            let (g, f) = (m.ghost as usize, m.front as usize);
            if mass[g] == 0.0 && momentum[g] == Vector::<D>::zeros() {
                continue;
            }
            mass[f] += mass[g];
            mass[g] = 0.0;
            let image = m.image(momentum[g]);
            momentum[f] += image;
        }
        for (i, v) in momentum.iter_mut().enumerate() {
            let m = mass[i];
            if m <= 0.0 {
                *v = Vector::<D>::zeros();
                continue;
            }
            *v /= m;
            if damping < 1.0 {
                *v *= damping;
            }
            let booked = sim.boundaries.apply_booked_at(
                &self.centers[i],
                grid,
                self.obstacle_reach[i],
                time,
                m,
                v,
            );
            work.boundaries += booked.work;
            work.friction += booked.friction;
            if damping < 1.0 && booked.work == 0.0 {
                work.damping += 0.5 * m * v.norm_squared() * (1.0 / (damping * damping) - 1.0);
            }
        }
        for m in &mirrors {
            momentum[m.ghost as usize] = m.image(momentum[m.front as usize]);
        }
        self.mirrors = Some(mirrors);
        work
    }

    /// G2P: velocity, C, F and position of every particle, in parallel chunks, with the
    /// step's statistics.
    fn functions_to_particles<K: Kernel>(
        &mut self,
        sim: &mut Simulation<D, K>,
        dt: f64,
    ) -> KinematicStats<D>
    where
        dyn Material: DimensionDispatch<D>,
    {
        let n = sim.particles.len();
        let chunks = chunk_count(n);
        let gravity = sim.settings.gravity;
        let p = &mut sim.particles;
        let store_gradient = !p.velocity_gradient.is_empty();
        let loads = (!p.external_force.is_empty()).then_some(&p.external_force);
        let mass = &p.mass;
        let position = SharedSlice::new(&mut p.position);
        let velocity = SharedSlice::new(&mut p.velocity);
        let deformation = SharedSlice::new(&mut p.deformation_gradient);
        let affine = SharedSlice::new(&mut p.affine);
        let gradient_out = SharedSlice::new(&mut p.velocity_gradient);
        let (basis, centers, grid_velocity) = (&self.basis, &self.centers, &self.grid.momentum);
        let (slab_scratch, located) = (&self.slab_scratch, &self.located);
        ordered_reduce(
            chunks,
            KinematicStats::default,
            |chunk| {
                let mut stats = KinematicStats::<D>::default();
                for k in chunk_range(chunk, n) {
                    // SAFETY: chunks are disjoint particle ranges; each particle is touched
                    // by exactly one task.
                    let (x, v, f) =
                        unsafe { (position.get(k), velocity.get(k), deformation.get(k)) };
                    let WeightRange { slab, start, len } = located[k];
                    if len > 0 {
                        let (start, len) = (start as usize, len as usize);
                        let weights = &slab_scratch[slab as usize].weights[start..start + len];
                        let mut v_new = Vector::<D>::zeros();
                        let mut b = Matrix::<D>::zeros();
                        let mut inertia = Matrix::<D>::zeros();
                        let mut grad = Matrix::<D>::zeros();
                        for w in weights.iter() {
                            let vi = grid_velocity[w.id as usize];
                            let offset = centers[w.id as usize] - *x;
                            v_new += vi * w.value;
                            b += (vi * w.value) * offset.transpose();
                            inertia += (offset * w.value) * offset.transpose();
                            grad += vi * w.gradient.transpose();
                        }
                        *v = v_new;
                        // SAFETY: as above.
                        unsafe {
                            *affine.get(k) =
                                inverse(&inertia).map_or(Matrix::<D>::zeros(), |d| b * d);
                        }
                        *x += v_new * dt;
                        *f = (Matrix::<D>::identity() + grad * dt) * *f;
                        if store_gradient {
                            // SAFETY: as above.
                            unsafe { *gradient_out.get(k) = grad };
                        }
                    }
                    stats.record(k, mass[k], v, x, f, (&gravity, loads.map(|l| &l[k])));
                    if stats.escaped.is_none() && !basis.covers(x) {
                        stats.escaped = Some(ParticleFault {
                            particle: k,
                            field: "x",
                            value: x.norm(),
                        });
                    }
                }
                stats.max_speed = stats.max_speed.sqrt();
                stats
            },
            KinematicStats::merge,
        )
    }
}

impl<const D: usize, K: Kernel> StepMode<D, K> for Refined<D>
where
    dyn Material: DimensionDispatch<D>,
{
    fn advance(&mut self, sim: &mut Simulation<D, K>, dt: f64) {
        if self.mirrors.is_none() {
            self.mirrors = Some(self.find_mirrors(&sim.boundaries, &sim.grid.origin, sim.grid.dx));
        }
        let start = Instant::now();
        self.particles_to_functions(sim);
        sim.clock.add(StepStage::P2g, start);
        let start = Instant::now();
        let work = self.update_functions(sim, dt);
        sim.ledger.boundaries += work.boundaries;
        sim.ledger.damping += work.damping;
        sim.ledger.friction += work.friction;
        sim.clock.add(StepStage::GridUpdate, start);
        let start = Instant::now();
        let stats = self.functions_to_particles(sim, dt);
        sim.clock.add(StepStage::G2p, start);
        sim.take_kinematics(stats, true);
        sim.update_stresses(dt);
    }

    fn stable_dt(&self, sim: &Simulation<D, K>) -> f64 {
        stable_time_step(
            self.finest_spacing,
            sim.kinematics.max_speed,
            sim.stresses.batch.max_wave_speed,
        )
        .min(sim.physics_dt)
    }
}
