//! What one implicit step keeps: the active grid nodes and their unknowns, the particles'
//! stencils at the start of the step, the constraints of walls and obstacles, and a
//! snapshot of the particle state so a step that fails can be retried from its start.

use super::super::DimensionDispatch;
use super::super::interpolation::build_interpolation;
use super::super::simulation::Simulation;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector, determinant};
use crate::physics::Interpolation;
use crate::scene::Contact;

/// The P-wave modulus ρc² of material group `g` at the last stress update (its stiffness
/// scale: the Jacobi preconditioner and the force floor use it).
pub(super) fn group_modulus<const D: usize, K: Kernel>(sim: &Simulation<D, K>, g: usize) -> f64
where
    dyn Material: DimensionDispatch<D>,
{
    let c = sim
        .stress_scratch
        .group_wave_speed
        .get(g)
        .copied()
        .unwrap_or(0.0);
    sim.particles.groups[g].material.density() * c * c
}

/// Marks a grid node with no unknown.
pub(super) const INACTIVE: u32 = u32::MAX;

/// A node whose increment is another's image: a ghost behind a stick wall (negated), behind
/// a symmetry wall (normal component negated), or a weakly supported node tied to its
/// neighbours (extrapolated linearly from `front` and `second`, `2 front − second`, or
/// copied from `front` when `second` is [`INACTIVE`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Mirror {
    pub ghost: u32,
    pub front: u32,
    pub second: u32,
    pub axis: u8,
    pub kind: MirrorKind,
}

/// How a [`Mirror`] maps its front node's increment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum MirrorKind {
    Stick,
    Symmetry,
    Tie,
}

impl Mirror {
    /// The factor component `d` of the front's increment takes on the ghost.
    #[inline]
    pub fn sign(&self, d: usize) -> f64 {
        match self.kind {
            MirrorKind::Stick => -1.0,
            MirrorKind::Symmetry if d == self.axis as usize => -1.0,
            MirrorKind::Symmetry | MirrorKind::Tie => 1.0,
        }
    }
}

/// Nodes whose particle support Σ_p w V is below this fraction of a cell's volume are tied
/// to their best-supported neighbour in the static form. Such a node (a corner just past a
/// free surface, reached only by the tail of a few particles' kernels) takes a load ∝ w but
/// a stiffness ∝ |∇w|², so alone it would move many times more than the body in a linear
/// solve and wreck Newton's convergence (the small-cut-cell problem of unfitted methods).
pub(super) const WEAK_SUPPORT: f64 = 0.01;

/// A constraint on the component of a node's increment along a general normal
/// (a slip surface that is not axis-aligned): `du·n = value`.
#[derive(Clone, Copy, Debug)]
pub(super) struct NormalConstraint<const D: usize> {
    pub dof: u32,
    pub normal: Vector<D>,
    pub value: f64,
}

/// Step data of the implicit mode, allocated on the first step and reused.
#[derive(Default)]
pub(super) struct Workspace<const D: usize> {
    /// Stencils of the particles at the start of the step.
    pub interp: Interpolation<D>,
    /// Unknown (active node) of each stencil entry.
    pub entry_dof: Vec<u32>,
    /// Unknown of each grid node, or [`INACTIVE`].
    pub dof_of_node: Vec<u32>,
    /// Grid node of each unknown.
    pub node_of_dof: Vec<u32>,
    /// Ghost nodes and their mirrors, in mirroring order.
    pub mirrors: Vec<Mirror>,
    /// Whether each unknown's node is a ghost (its increment is its mirror's image).
    pub ghost: Vec<bool>,
    /// For a ghost unknown, its entry in `mirrors` (the first), else [`INACTIVE`].
    pub ghost_mirror: Vec<u32>,
    /// Particles sorted by the first node of their stencil, and one summed element block
    /// (the preconditioner's assembly).
    pub order: Vec<u32>,
    pub block: Vec<f64>,
    /// Σ_p Vₚ ∇wₚ of one patch, per stencil entry (F-bar's volumetric block).
    pub patch_gradient: Vec<crate::math::Vector<D>>,
    /// The unknowns and factors of each stencil entry's components in one block (reused).
    pub mapped: Vec<[(usize, f64); 2]>,
    /// Matrix entries of the preconditioner's assembly (reused).
    pub pairs: Vec<faer::sparse::Pair<usize, usize>>,
    pub values: Vec<f64>,
    /// The last factored pattern, its value order and symbolic factorisation.
    pub pattern: crate::linear_solvers::sparse_cholesky::PatternCache,
    /// Per component: 1 for a free unknown, 0 for a fixed one (wall, obstacle, ghost, no
    /// material).
    pub mask: Vec<f64>,
    /// The increment fixed components take (moving obstacles).
    pub prescribed: Vec<f64>,
    /// Constraints along normals that are not axis-aligned.
    pub normals: Vec<NormalConstraint<D>>,
    /// Folded nodal mass (ghosts 0).
    pub mass: Vec<f64>,
    /// Nodal velocity at the start of the step.
    pub velocity: Vec<f64>,
    /// External (gravity) force at the end of the step.
    pub external: Vec<f64>,
    /// Out-of-balance force at the start of the step, M a_n (dynamic form).
    pub force0: Vec<f64>,
    /// Inverse of the estimated tangent diagonal (0 for fixed components).
    pub inverse_diagonal: Vec<f64>,
    /// Displacement increment with the ghosts mirrored (scratch of an evaluation).
    pub full: Vec<f64>,
    /// A Krylov direction with the ghosts mirrored (scratch of a tangent product).
    pub full_v: Vec<f64>,
    /// Stress, and σzz in 2D, at the iterate the tangent linearises about.
    pub stress_cur: Vec<Matrix<D>>,
    pub zz_cur: Vec<f64>,
    /// Generalized plane strain's rank-one term of the tangent (inactive without it).
    pub out_of_plane: super::out_of_plane::OutOfPlaneCoupling<D>,
    /// Gradient of the direction, and the difference step, per particle (tangent product).
    pub grad_v: Vec<Matrix<D>>,
    pub step_of: Vec<f64>,
    /// Each particle's measured isotropic tangent (λ, μ), for the preconditioner.
    pub moduli: Vec<[f64; 2]>,
    /// Each particle's measured whole tangent ∂σ/∂ε (Voigt, `tangent_estimate::components`
    /// order, row-major; the first 9 entries in 2D), without F-bar; empty with it.
    pub tangent: Vec<[f64; 36]>,
    /// Per-thread force buffers of the scatter.
    pub buffers: Vec<Vec<f64>>,
    /// Increment gradient ∇Δu of each particle at the last evaluation.
    pub grad_du: Vec<Matrix<D>>,
    /// F, stress and volume at the start of the step.
    pub f_n: Vec<Matrix<D>>,
    pub stress_n: Vec<Matrix<D>>,
    pub volume_n: Vec<f64>,
    /// Material state at the start of the step, per group and field.
    pub state_n: Vec<Vec<Vec<f64>>>,
    /// Free strain the stress update had applied at the start of the step.
    pub applied_n: Vec<f64>,
    /// Particle support Σ_p w V of each unknown's node, in cell volumes (weak-node ties).
    pub support: Vec<f64>,
    /// The weak-node ties of the step being prepared (reused).
    pub ties: Vec<Mirror>,
    /// Free strain before and after the physics advanced (for ramping within cut steps).
    pub free_strain_old: Vec<f64>,
    pub free_strain_new: Vec<f64>,
    /// Whether the tangent uses the laws' analytic stress derivative (every law has one
    /// and the scene does not ask for finite differences).
    pub analytic: bool,
    /// δF = ∇v Fₙ and dσ per particle, and the free-strain scratch (analytic tangent).
    pub direction: Vec<Matrix<D>>,
    pub stress_change: Vec<Matrix<D>>,
    pub derivative_scratch: crate::solver::stress_derivative::DerivativeScratch<D>,
    /// F-bar's patches and averaged volume changes (only with `solver.anti_locking: fbar`).
    pub fbar: Option<super::fbar::PatchAverage>,
    /// The last step's factored preconditioner (`reuse_preconditioner`).
    pub carried: Option<super::newton::CarriedFactor>,
}

impl<const D: usize> Workspace<D> {
    /// Unknowns (components).
    pub fn len(&self) -> usize {
        self.node_of_dof.len() * D
    }

    /// Builds the step's stencils, active nodes, mirrors and nodal mass and velocity (the
    /// grid holds the folded mass and the start velocity after `sim.p2g` and the grid
    /// update the caller ran).
    pub fn prepare<K: Kernel>(&mut self, sim: &Simulation<D, K>, dynamic: bool)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let grid = &sim.grid;
        build_interpolation::<D, K>(grid, &sim.particles, &mut self.interp);
        self.dof_of_node.clear();
        self.dof_of_node.resize(grid.len(), INACTIVE);
        self.node_of_dof.clear();
        self.entry_dof.clear();
        self.entry_dof.resize(self.interp.node.len(), INACTIVE);
        for (e, &node) in self.interp.node.iter().enumerate() {
            let slot = &mut self.dof_of_node[node as usize];
            if *slot == INACTIVE {
                *slot = self.node_of_dof.len() as u32;
                self.node_of_dof.push(node);
            }
            self.entry_dof[e] = *slot;
        }
        self.mirrors.clear();
        let (dof_of_node, node_of_dof, mirrors) = (
            &mut self.dof_of_node,
            &mut self.node_of_dof,
            &mut self.mirrors,
        );
        sim.boundaries
            .for_each_mirror_node(grid.nodes, |ghost, front, axis, symmetry| {
                let kind = if symmetry {
                    MirrorKind::Symmetry
                } else {
                    MirrorKind::Stick
                };
                let g = dof_of_node[grid.index(ghost)];
                if g == INACTIVE {
                    return;
                }
                let f_node = grid.index(front);
                if dof_of_node[f_node] == INACTIVE {
                    dof_of_node[f_node] = node_of_dof.len() as u32;
                    node_of_dof.push(f_node as u32);
                }
                mirrors.push(Mirror {
                    ghost: g,
                    front: dof_of_node[f_node],
                    second: INACTIVE,
                    axis: axis as u8,
                    kind,
                });
            });
        if !dynamic {
            self.tie_weak_nodes(sim);
        }
        let n = self.len();
        let nodes = self.node_of_dof.len();
        self.ghost.clear();
        self.ghost.resize(nodes, false);
        self.ghost_mirror.clear();
        self.ghost_mirror.resize(nodes, INACTIVE);
        for (i, m) in self.mirrors.iter().enumerate() {
            self.ghost[m.ghost as usize] = true;
            if self.ghost_mirror[m.ghost as usize] == INACTIVE {
                self.ghost_mirror[m.ghost as usize] = i as u32;
            }
        }
        for v in [
            &mut self.mask,
            &mut self.prescribed,
            &mut self.velocity,
            &mut self.external,
            &mut self.force0,
            &mut self.inverse_diagonal,
            &mut self.full,
            &mut self.full_v,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.mass.clear();
        self.mass.resize(nodes, 0.0);
        if dynamic {
            for (k, &node) in self.node_of_dof.iter().enumerate() {
                self.mass[k] = grid.mass[node as usize];
                let v = grid.momentum[node as usize];
                for d in 0..D {
                    self.velocity[k * D + d] = v[d];
                }
            }
        }
        let threads = rayon::current_num_threads().max(1);
        self.buffers.resize_with(threads, Vec::new);
        for b in &mut self.buffers {
            b.clear();
            b.resize(n, 0.0);
        }
    }

    /// Ties each weakly supported node (see [`WEAK_SUPPORT`]) to its neighbours: along the
    /// direction whose next two nodes are well supported (the first with the most support),
    /// it takes their linear extrapolation, so a uniform strain (and nearly a bending one)
    /// is kept; with only one such neighbour it copies it; ghosts stay as they are.
    fn tie_weak_nodes<K: Kernel>(&mut self, sim: &Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let grid = &sim.grid;
        let nodes = self.node_of_dof.len();
        let support = &mut self.support;
        support.clear();
        support.resize(nodes, 0.0);
        let cell = grid.dx.powi(D as i32);
        for p in 0..sim.particles.len() {
            let v = sim.particles.volume0[p] * determinant(&sim.particles.deformation_gradient[p]);
            for e in self.interp.entries(p) {
                support[self.entry_dof[e] as usize] += self.interp.weight[e] * v / cell;
            }
        }
        // The wall ghosts so far (`prepare` marks the ties too afterwards).
        let is_ghost = &mut self.ghost;
        is_ghost.clear();
        is_ghost.resize(nodes, false);
        for m in &self.mirrors {
            is_ghost[m.ghost as usize] = true;
        }
        let (is_ghost, support, dof_of_node) = (&*is_ghost, &*support, &self.dof_of_node);
        // The well-supported unknown `steps` nodes from `ijk` along `offset`, if any.
        let strong = |ijk: [usize; 3], offset: [i64; 3], steps: i64| -> Option<u32> {
            let mut n = ijk;
            for d in 0..D {
                let c = ijk[d] as i64 + steps * offset[d];
                if c < 0 || c as usize >= grid.nodes[d] {
                    return None;
                }
                n[d] = c as usize;
            }
            let j = dof_of_node[grid.index(n)];
            (j != INACTIVE && !is_ghost[j as usize] && support[j as usize] >= WEAK_SUPPORT)
                .then_some(j)
        };
        let ties = &mut self.ties;
        ties.clear();
        for k in 0..nodes {
            if is_ghost[k] || support[k] >= WEAK_SUPPORT {
                continue;
            }
            let ijk = grid.coords(self.node_of_dof[k] as usize);
            // (front, second, support of front), linear extrapolation preferred.
            let mut best: Option<(u32, u32, f64)> = None;
            for code in 0..3usize.pow(D as u32) {
                let mut offset = [0i64; 3];
                let mut c = code;
                for o in offset.iter_mut().take(D) {
                    *o = (c % 3) as i64 - 1;
                    c /= 3;
                }
                if offset == [0; 3] {
                    continue;
                }
                let Some(j) = strong(ijk, offset, 1) else {
                    continue;
                };
                let second = strong(ijk, offset, 2).unwrap_or(INACTIVE);
                let s = support[j as usize];
                let better = match best {
                    None => true,
                    Some((_, b2, bs)) => (second != INACTIVE, s) > (b2 != INACTIVE, bs),
                };
                if better {
                    best = Some((j, second, s));
                }
            }
            if let Some((front, second, _)) = best {
                ties.push(Mirror {
                    ghost: k as u32,
                    front,
                    second,
                    axis: 0,
                    kind: MirrorKind::Tie,
                });
            }
        }
        // Ties go first: a tied node may itself be the image of a wall's ghost, so it must
        // take its value before the ghost copies it (and its ghost's force folds onto it
        // before it folds onward).
        self.mirrors.splice(0..0, ties.drain(..));
    }

    /// Gravity on the nodes, `g·scale` (the load ramp), before folding.
    pub fn gravity<K: Kernel>(&mut self, sim: &Simulation<D, K>, scale: f64)
    where
        dyn Material: DimensionDispatch<D>,
    {
        self.external.fill(0.0);
        let g = sim.settings.gravity * scale;
        if g.norm() == 0.0 {
            return;
        }
        for p in 0..sim.particles.len() {
            let mg = g * sim.particles.mass[p];
            for e in self.interp.entries(p) {
                let w = self.interp.weight[e];
                let k = self.entry_dof[e] as usize;
                for d in 0..D {
                    self.external[k * D + d] += w * mg[d];
                }
            }
        }
    }

    /// Turns walls and obstacles into constraints on the increment over a step of `dt`
    /// ending at `time`: stick fixes the node (moving with an obstacle), slip, symmetry and
    /// friction fix the normal component (bilateral: the implicit mode does not let a body
    /// leave a slip surface within a step, and friction acts as stick). Ghost nodes are no
    /// unknowns. Returns whether anything holds the body.
    pub fn constrain<K: Kernel>(&mut self, sim: &Simulation<D, K>, time: f64, dt: f64) -> bool
    where
        dyn Material: DimensionDispatch<D>,
    {
        self.mask.fill(1.0);
        self.prescribed.fill(0.0);
        self.normals.clear();
        for m in &self.mirrors {
            let g = m.ghost as usize * D;
            self.mask[g..g + D].fill(0.0);
        }
        let mut held = false;
        let grid = &sim.grid;
        for k in 0..self.node_of_dof.len() {
            if self.ghost[k] {
                continue;
            }
            let node = self.node_of_dof[k] as usize;
            let ijk = grid.coords(node);
            let x = grid.position(ijk);
            let (mask, prescribed, normals) =
                (&mut self.mask, &mut self.prescribed, &mut self.normals);
            sim.boundaries
                .node_conditions(ijk, &x, time, |n, contact, surface_velocity| {
                    held = true;
                    let du = surface_velocity * dt;
                    match contact {
                        Contact::Stick | Contact::Friction { .. } => {
                            for d in 0..D {
                                mask[k * D + d] = 0.0;
                                prescribed[k * D + d] = du[d];
                            }
                        }
                        // Navier walls are refused outside incompressible mechanics.
                        Contact::Slip | Contact::Symmetry | Contact::Navier { .. } => {
                            if let Some(axis) = (0..D).find(|&d| n[d].abs() > 1.0 - 1e-12) {
                                mask[k * D + axis] = 0.0;
                                prescribed[k * D + axis] = du[axis];
                            } else {
                                normals.push(NormalConstraint {
                                    dof: k as u32,
                                    normal: n,
                                    value: du.dot(&n),
                                });
                            }
                        }
                    }
                });
        }
        held
    }

    /// Saves F, stress, material state and the applied free strain of every particle, and
    /// the volume at the start of the step.
    pub fn snapshot<K: Kernel>(&mut self, sim: &Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let p = &sim.particles;
        self.f_n.clear();
        self.f_n.extend_from_slice(&p.deformation_gradient);
        self.stress_n.clear();
        self.stress_n.extend_from_slice(&p.stress);
        self.volume_n.clear();
        self.volume_n.extend(
            p.deformation_gradient
                .iter()
                .zip(&p.volume0)
                .map(|(f, v0)| determinant(f) * v0),
        );
        self.grad_du.clear();
        self.grad_du.resize(p.len(), Matrix::<D>::zeros());
        self.state_n.resize_with(p.groups.len(), Vec::new);
        for (saved, group) in self.state_n.iter_mut().zip(&p.groups) {
            saved.resize_with(group.state.len(), Vec::new);
            for (s, field) in saved.iter_mut().zip(&group.state) {
                s.clear();
                s.extend_from_slice(field);
            }
        }
        self.applied_n.clear();
        self.applied_n
            .extend_from_slice(sim.stress_scratch.applied());
    }

    /// Puts back F, stress, material state and the applied free strain of the snapshot.
    pub fn restore<K: Kernel>(&self, sim: &mut Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let p = &mut sim.particles;
        p.deformation_gradient.copy_from_slice(&self.f_n);
        self.restore_state(sim);
    }

    /// Puts back the stress, material state and applied free strain (not F).
    pub fn restore_state<K: Kernel>(&self, sim: &mut Simulation<D, K>)
    where
        dyn Material: DimensionDispatch<D>,
    {
        let p = &mut sim.particles;
        p.stress.copy_from_slice(&self.stress_n);
        for (saved, group) in self.state_n.iter().zip(&mut p.groups) {
            for (s, field) in saved.iter().zip(&mut group.state) {
                field.copy_from_slice(s);
            }
        }
        sim.stress_scratch.applied_mut().clone_from(&self.applied_n);
    }
}
