//! Bonded interfaces that can delaminate: a cohesive law at the grid nodes shared by the
//! two velocity fields of a `cohesive` contact pair (the node-based imperfect interface of
//! multi-velocity-field MPM, after Nairn 2013).
//!
//! - Where: one state per grid node (`CohesiveNode`: the pair, the interface area, the
//!   opening and the damage), allocated once at setup. The interface is fixed at the first
//!   step: nodes where exactly the pair's two fields have mass and fill at least 40% of the
//!   node's support (the gap test of `contact.rs`, loosened so that the half-empty node on
//!   a free surface at the end of an interface bonds) are bonded, or start debonded
//!   inside the pair's `precrack`. Nodes do not move, so the state suits interfaces whose
//!   faces slide less than a cell (delamination, not long sliding).
//! - Area: from the volume gradients `Σ_p V_p ∇w_ip` of the two fields (their mass
//!   gradients over the nodal densities): the smaller magnitude, or the larger component
//!   along the interface normal where that is smaller (free surfaces near the node add to
//!   the gradients; see `bond`); the interface area the node's shape function sees: the
//!   nodal forces a uniform traction `t` puts on a node are `t A`, and the areas of the
//!   nodes across a flat interface add up to the interface area (partition of unity).
//!   Both bodies must be three cells thick or more there: a free surface within the
//!   kernel's reach of an interface node adds to the volume gradients.
//! - Law: initially rigid, then linear softening. The impulse that brings the two fields to
//!   their common velocity (the force the bond must carry) is split into the normal and the
//!   tangential traction; the normal one is capped at `σc (1 − d)` in tension (compression
//!   is carried in full: an intact interface is contact), the tangential one at
//!   `τc (1 − d) + μ max(0, −t_n)`; once past them each mode's traction is its mean along
//!   the softening line over the opening the fields would make this step (no more than
//!   the energy the node has left). Capped, the fields separate and the opening
//!   `δ += (v_g − v_f) dt` grows (integrated from the velocities the particles then move
//!   with); the damage `d = max over time of min(1, ‖(⟨δn⟩/δnc, δt/δtc)‖_α)` with
//!   `δc = 2 G_c / strength` per mode. A pure mode dissipates its fracture energy. The law
//!   never does more than bring the fields to their common velocity, so no stiffness
//!   limits the time step. Fully damaged (or never bonded) nodes are Coulomb contact with
//!   the law's friction coefficient.
//! - Energy: the work of the capped tractions on the opening, `Σ J·Δδ / dt`, is dissipated
//!   (the softening law unloads rigidly, so none of it is stored); it enters the energy
//!   ledger like friction work (`EnergyLedger::cohesive`) and the run reports it as
//!   `contact.cohesive_dissipation` (under compression it includes the friction part of
//!   the shear cap while the node softens; Coulomb friction of debonded nodes is
//!   `contact.friction_work`).

use super::DimensionDispatch;
use super::parallel::SharedSlice;
use super::simulation::Simulation;
use super::stencil::Stencil;
use crate::grid::{Grid, node_coords, node_position};
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::Vector;
use crate::physics::PhysicsReport;
use crate::scene::{CohesiveLaw, INTERFACE_DAMAGE, Shape};
use rayon::prelude::*;

/// How far below a full support the particle volume at a node may be at the first step for
/// the node to join a bonded interface (fraction of `dx^D`). Bodies whose particles tile
/// space fill it exactly, except at the free ends of the interface: the node on the free
/// surface is half empty (0.5) and the next one misses 2%. Both must bond: left unbonded,
/// the ends of an interface open and close as contact, and two bonded blocks thrown apart
/// lost 0.79 of their energy instead of the 0.45 that one shared field (and bonded fields)
/// lose. 0.6 bonds them (not the corners of a 3D interface, a quarter full) and bonds bodies across
/// gaps narrower than about 0.8 cells (at a node in the gap the volume falls by about
/// 0.75 of the gap's width in cells): closer than that, bodies count as touching.
const BOND_TOLERANCE: f64 = 0.6;

/// Most rows the `cohesive` table keeps: rows closer in time than `end_time / MAX_ROWS`
/// replace the previous one.
const MAX_ROWS: f64 = 500.0;

/// What a grid node is to a bonded interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum NodeRole {
    /// Not on a bonded interface.
    #[default]
    None,
    /// On the interface of fields `pair`, bonded at the start.
    Bonded,
    /// On the interface, inside a precrack: debonded from the start.
    Precracked,
}

/// The state of the bonded interface at one grid node.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CohesiveNode<const D: usize> {
    /// The two fields (lower index first).
    pub(crate) pair: [u8; 2],
    /// What the node is.
    pub(crate) role: NodeRole,
    /// Interface area the node carries, m^(D−1).
    pub(crate) area: f64,
    /// Opening `∫ (v_second − v_first) dt`, m.
    pub(crate) opening: Vector<D>,
    /// Damage: 0 intact, 1 debonded; never decreases.
    pub(crate) damage: f64,
}

impl<const D: usize> Default for CohesiveNode<D> {
    fn default() -> Self {
        Self {
            pair: [0, 0],
            role: NodeRole::None,
            area: 0.0,
            opening: Vector::<D>::zeros(),
            damage: 0.0,
        }
    }
}

/// A precrack of a cohesive pair of fields.
pub(crate) struct Precrack {
    /// The two fields (lower index first).
    pub(crate) pair: [u8; 2],
    /// Where the interface starts debonded.
    pub(crate) shape: Shape,
}

/// The bonded interfaces of a run: one node state per grid node and the running totals.
pub(crate) struct Cohesive<const D: usize> {
    /// One state per grid node.
    pub(crate) nodes: Vec<CohesiveNode<D>>,
    /// The precracks of the scene's cohesive pairs.
    precracks: Vec<Precrack>,
    /// Whether the interface nodes have been found (at the first step).
    bonded: bool,
    /// Energy the interfaces dissipated so far, J (≥ 0).
    pub(crate) dissipated: f64,
    /// Interface nodes damaged but not debonded.
    damaged: usize,
    /// Interface nodes debonded (precracked ones included).
    failed: usize,
    /// Debonded interface length (2D, m per m of thickness) or area (3D, m²).
    debonded: f64,
    /// Interface length or area found at the first step (bonded and precracked).
    interface: f64,
}

/// What the cohesive law did at one node in one step.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct NodeChange {
    /// Energy dissipated, J.
    pub dissipated: f64,
    /// Nodes whose damage left 0.
    pub damaged: usize,
    /// Nodes whose damage reached 1.
    pub failed: usize,
    /// Their area.
    pub failed_area: f64,
}

impl NodeChange {
    /// Sum of two changes.
    pub(crate) fn merge(a: Self, b: Self) -> Self {
        Self {
            dissipated: a.dissipated + b.dissipated,
            damaged: a.damaged + b.damaged,
            failed: a.failed + b.failed,
            failed_area: a.failed_area + b.failed_area,
        }
    }
}

impl<const D: usize> Cohesive<D> {
    /// Node states for a grid of `len` nodes.
    pub(crate) fn new(len: usize, precracks: Vec<Precrack>) -> Self {
        Self {
            nodes: vec![CohesiveNode::default(); len],
            precracks,
            bonded: false,
            dissipated: 0.0,
            damaged: 0,
            failed: 0,
            debonded: 0.0,
            interface: 0.0,
        }
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<CohesiveNode<D>>()
    }

    /// At the first step: marks the nodes of every cohesive pair's interface (`is_cohesive`
    /// of two fields) as bonded or precracked, with their areas. Later calls do nothing.
    pub(crate) fn bond(
        &mut self,
        grids: &[Grid<D>],
        gradient: &[Vec<Vector<D>>],
        volume: &[Vec<f64>],
        is_cohesive: impl Fn(usize, usize) -> bool,
    ) {
        if self.bonded {
            return;
        }
        self.bonded = true;
        let Some(first) = grids.first() else {
            return;
        };
        let (origin, dx, stride) = (first.origin, first.dx, first.stride);
        let full = dx.powi(D as i32) * (1.0 - BOND_TOLERANCE);
        for (i, node) in self.nodes.iter_mut().enumerate() {
            let mut present = (0..grids.len()).filter(|&f| grids[f].mass[i] > 0.0);
            let (Some(a), Some(b), None) = (present.next(), present.next(), present.next()) else {
                continue;
            };
            if !is_cohesive(a, b) || volume[a][i] + volume[b][i] < full {
                continue;
            }
            // Each field's volume gradient Σ V_p ∇w_ip (its mass gradient, grid units, over
            // its nodal density) is the interface's part, the same for both, plus the part
            // of the field's own free surfaces near the node. The smaller magnitude is exact
            // where one field has no free surface near; along the normal (the difference of
            // the two gradients) the larger is exact where the free surfaces are symmetric
            // about the interface, as at its ends. The smaller of the two estimates.
            let volume_gradient = |f: usize| gradient[f][i] / dx * volume[f][i] / grids[f].mass[i];
            let (ga, gb) = (volume_gradient(a), volume_gradient(b));
            let n = (gradient[a][i] - gradient[b][i]).normalize();
            let area = ga
                .norm()
                .min(gb.norm())
                .min(ga.dot(&n).abs().max(gb.dot(&n).abs()));
            if !(area > 0.0 && area.is_finite()) {
                continue;
            }
            let pair = [a as u8, b as u8];
            let x = node_position(&origin, dx, node_coords(&stride, i));
            let cracked = self
                .precracks
                .iter()
                .any(|p| p.pair == pair && p.shape.contains(x.as_slice()));
            *node = CohesiveNode {
                pair,
                role: if cracked {
                    NodeRole::Precracked
                } else {
                    NodeRole::Bonded
                },
                area,
                opening: Vector::<D>::zeros(),
                damage: if cracked { 1.0 } else { 0.0 },
            };
            self.interface += area;
            if cracked {
                self.failed += 1;
                self.debonded += area;
            }
        }
    }

    /// The node states, shared between the node-parallel tasks of the contact pass.
    pub(crate) fn shared(&mut self) -> SharedSlice<CohesiveNode<D>> {
        SharedSlice::new(&mut self.nodes)
    }

    /// Adds one step's changes to the totals and records them: the figures
    /// `contact.cohesive_dissipation` and `contact.cohesive_interface` (the interface
    /// length or area found at the first step) and the table `cohesive` (time, debonded length or
    /// area, damaged and debonded nodes, dissipated energy), a row whenever the number of
    /// debonded nodes changes, at most `MAX_ROWS` rows over the run.
    pub(crate) fn record(
        &mut self,
        change: NodeChange,
        time: f64,
        end_time: f64,
        report: &mut PhysicsReport,
    ) {
        self.dissipated += change.dissipated;
        self.damaged = (self.damaged + change.damaged).saturating_sub(change.failed);
        self.failed += change.failed;
        self.debonded += change.failed_area;
        report.record_max("contact.cohesive_dissipation", self.dissipated);
        report.record_max("contact.cohesive_interface", self.interface);
        let table = report.table_mut(
            "cohesive",
            &[
                "time",
                "debonded",
                "damaged_nodes",
                "debonded_nodes",
                "dissipated",
            ],
        );
        let failed = self.failed as f64;
        // A row (one allocation) only when the count of debonded nodes changes.
        if table.rows.last().is_none_or(|last| last[3] != failed) {
            let close = table.rows.len() > 1
                && table
                    .rows
                    .last()
                    .is_some_and(|last| time - last[0] < end_time / MAX_ROWS);
            if close {
                table.rows.pop();
            }
            table.rows.push(vec![
                time,
                self.debonded,
                self.damaged as f64,
                failed,
                self.dissipated,
            ]);
        }
    }
}

/// What a bonded node does to its two fields in one step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bond<const D: usize> {
    /// The impulse on the first field (the second gets its opposite), N·s.
    pub(crate) impulse: Vector<D>,
    /// Whether the bond holds (the fields take their common velocity, the opening does
    /// not change); otherwise a traction reached its cap and the fields separate.
    pub(crate) holds: bool,
}

/// The impulse of a bonded node, from the fields' masses `m`, velocities `v` and the unit
/// normal `n` pointing from the first field to the second, over a step `dt`; `None` when
/// the node is debonded (contact acts).
#[inline]
pub(crate) fn bond_impulse<const D: usize>(
    node: &CohesiveNode<D>,
    law: &CohesiveLaw,
    m: [f64; 2],
    v: [Vector<D>; 2],
    n: &Vector<D>,
    dt: f64,
) -> Option<Bond<D>> {
    if node.role != NodeRole::Bonded || node.damage >= 1.0 {
        return None;
    }
    // The impulse that brings both fields to their common velocity, as a traction.
    let reduced = m[0] * m[1] / (m[0] + m[1]);
    let stick = (v[1] - v[0]) * reduced;
    let scale = dt * node.area;
    let normal = stick.dot(n) / scale;
    let tangential = (stick - n * stick.dot(n)) / scale;
    // The bond holds while the tractions stay below the softened strengths.
    let intact = 1.0 - node.damage;
    let friction = law.friction * (-normal).max(0.0);
    let slip = tangential.norm();
    if normal <= law.normal_strength * intact && slip <= law.shear_strength * intact + friction {
        return Some(Bond {
            impulse: stick,
            holds: true,
        });
    }
    // Otherwise each mode's traction is capped at its mean along the softening line over
    // the opening the fields would make unbonded this step (`free`, an upper bound of the
    // opening they make): the softened strength `σc (1 − d)` for small steps, and no more
    // than the fracture energy the node has left when it would break within the step, so
    // the explicit step never dissipates more than the law.
    let relative = (v[1] - v[0]) * dt;
    let (free_n, free_t) = (
        relative.dot(n).max(0.0),
        (relative - n * relative.dot(n)).norm(),
    );
    let secant = |strength: f64, energy: f64, free: f64| {
        let final_opening = 2.0 * energy / strength;
        let x = (free / final_opening).min(intact);
        if x > 0.0 {
            energy * x * (2.0 * intact - x) / free
        } else {
            strength * intact
        }
    };
    let normal_cap = secant(law.normal_strength, law.mode_i_energy, free_n);
    let shear_cap = secant(law.shear_strength, law.mode_ii_energy, free_t) + friction;
    let normal = normal.min(normal_cap);
    let tangential = if slip > shear_cap {
        tangential * (shear_cap / slip)
    } else {
        tangential
    };
    Some(Bond {
        impulse: (n * normal + tangential) * scale,
        holds: false,
    })
}

/// Advances a bonded node by one step after its fields took the velocities `v` (walls and
/// obstacles applied) under `bond`: the opening, the damage and the energy dissipated.
/// A bond that holds changes nothing (its fields share one velocity, up to rounding).
#[inline]
pub(crate) fn advance<const D: usize>(
    node: &mut CohesiveNode<D>,
    law: &CohesiveLaw,
    v: [Vector<D>; 2],
    bond: &Bond<D>,
    n: &Vector<D>,
    dt: f64,
) -> NodeChange {
    if bond.holds {
        return NodeChange::default();
    }
    let impulse = &bond.impulse;
    let step = (v[1] - v[0]) * dt;
    node.opening += step;
    let mut change = NodeChange {
        dissipated: (impulse.dot(&step) / dt).max(0.0),
        ..NodeChange::default()
    };
    let opening_n = node.opening.dot(n);
    let opening_t = (node.opening - n * opening_n).norm();
    let final_n = 2.0 * law.mode_i_energy / law.normal_strength;
    let final_t = 2.0 * law.mode_ii_energy / law.shear_strength;
    let alpha = law.mixed_mode_exponent;
    let ratio = ((opening_n.max(0.0) / final_n).powf(alpha) + (opening_t / final_t).powf(alpha))
        .powf(1.0 / alpha);
    let damage = node.damage.max(ratio.min(1.0));
    if damage > node.damage {
        if node.damage == 0.0 {
            change.damaged = 1;
        }
        if damage >= 1.0 {
            change.failed = 1;
            change.failed_area = node.area;
        }
        node.damage = damage;
    }
    change
}

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Fills the particle field `interface_damage` (when the run has one): the largest
    /// damage of the interface nodes in each particle's stencil, 0 away from interfaces.
    pub(super) fn gather_interface_damage(&mut self) {
        let Some(cohesive) = self.contact.as_ref().and_then(|c| c.cohesive.as_ref()) else {
            return;
        };
        let Some(out) = self.particles.shared.get_mut(INTERFACE_DAMAGE) else {
            return;
        };
        let (grid, nodes) = (&self.grid, &cohesive.nodes);
        let (position, half_size) = (&self.particles.position, &self.particles.half_size);
        out.par_iter_mut().enumerate().for_each(|(p, d)| {
            let half = if K::USES_PARTICLE_SIZE {
                half_size[p]
            } else {
                0.0
            };
            let stencil = Stencil::<D>::new::<K>(grid, &position[p], half);
            let mut worst = 0.0f64;
            stencil.for_each::<K>(&grid.stride, |i, w, _, _| {
                if w > 0.0 && nodes[i].role != NodeRole::None {
                    worst = worst.max(nodes[i].damage);
                }
            });
            *d = worst;
        });
    }
}

impl<const D: usize> Cohesive<D> {
    /// Writes the interface nodes' state and the running totals into a checkpoint.
    pub(crate) fn save(&self, c: &mut crate::checkpoint::Checkpoint) {
        let nodes = &self.nodes;
        c.put(
            "cohesive.pair",
            nodes
                .iter()
                .flat_map(|n| [n.pair[0] as f64, n.pair[1] as f64])
                .collect(),
        );
        c.put(
            "cohesive.role",
            nodes
                .iter()
                .map(|n| match n.role {
                    NodeRole::None => 0.0,
                    NodeRole::Bonded => 1.0,
                    NodeRole::Precracked => 2.0,
                })
                .collect(),
        );
        c.put("cohesive.area", nodes.iter().map(|n| n.area).collect());
        c.put(
            "cohesive.opening",
            nodes
                .iter()
                .flat_map(|n| n.opening.iter().copied())
                .collect(),
        );
        c.put("cohesive.damage", nodes.iter().map(|n| n.damage).collect());
        c.put(
            "cohesive.totals",
            vec![
                if self.bonded { 1.0 } else { 0.0 },
                self.dissipated,
                self.damaged as f64,
                self.failed as f64,
                self.debonded,
                self.interface,
            ],
        );
    }

    /// Takes back what [`Cohesive::save`] wrote.
    pub(crate) fn restore(
        &mut self,
        c: &crate::checkpoint::Checkpoint,
    ) -> Result<(), crate::checkpoint::CheckpointError> {
        let n = self.nodes.len();
        let pair = c.get("cohesive.pair", 2 * n)?;
        let role = c.get("cohesive.role", n)?;
        let area = c.get("cohesive.area", n)?;
        let opening = c.get("cohesive.opening", D * n)?;
        let damage = c.get("cohesive.damage", n)?;
        for (i, node) in self.nodes.iter_mut().enumerate() {
            node.pair = [pair[2 * i] as u8, pair[2 * i + 1] as u8];
            node.role = match role[i] as u8 {
                1 => NodeRole::Bonded,
                2 => NodeRole::Precracked,
                _ => NodeRole::None,
            };
            node.area = area[i];
            node.opening = Vector::<D>::from_column_slice(&opening[D * i..D * (i + 1)]);
            node.damage = damage[i];
        }
        let t = c.get("cohesive.totals", 6)?;
        self.bonded = t[0] != 0.0;
        self.dissipated = t[1];
        self.damaged = t[2] as usize;
        self.failed = t[3] as usize;
        self.debonded = t[4];
        self.interface = t[5];
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law() -> CohesiveLaw {
        CohesiveLaw {
            normal_strength: 1e6,
            shear_strength: 2e6,
            mode_i_energy: 100.0,
            mode_ii_energy: 400.0,
            friction: 0.5,
            mixed_mode_exponent: 2.0,
        }
    }

    fn bonded() -> CohesiveNode<2> {
        CohesiveNode {
            pair: [0, 1],
            role: NodeRole::Bonded,
            area: 0.01,
            ..CohesiveNode::default()
        }
    }

    #[test]
    fn an_intact_bond_below_its_strength_moves_the_fields_together() {
        let n = Vector::<2>::new(0.0, 1.0);
        let v = [Vector::<2>::zeros(), Vector::<2>::new(0.1, 0.2)];
        // Stick impulse 0.5·(0.1, 0.2) = (0.05, 0.1): tractions 5e5 and 1e6 Pa over
        // 0.01 m² · 1e-5 s, below the strengths.
        let bond = bond_impulse(&bonded(), &law(), [1.0, 1.0], v, &n, 1e-5).unwrap();
        assert!(bond.holds);
        assert!((bond.impulse - Vector::<2>::new(0.05, 0.1)).norm() < 1e-15);
    }

    #[test]
    fn compression_is_carried_in_full_and_adds_friction_to_the_shear_cap() {
        let n = Vector::<2>::new(0.0, 1.0);
        // Stick impulse 0.5·(10, −20): 1e8 Pa of compression, 5e7 Pa of shear needed
        // against a cap of 2e6 + 0.5 · 1e8 = 5.2e7 Pa: both carried.
        let v = [Vector::<2>::zeros(), Vector::<2>::new(10.0, -20.0)];
        let bond = bond_impulse(&bonded(), &law(), [1.0, 1.0], v, &n, 1e-5).unwrap();
        let stick = Vector::<2>::new(10.0, -20.0) * 0.5;
        assert!(bond.holds);
        assert!((bond.impulse - stick).norm() < 1e-15 * stick.norm());
    }

    #[test]
    fn mode_i_softening_dissipates_the_fracture_energy() {
        // Pull the two fields apart at a constant rate: the traction is capped at
        // σc (1 − d), the node fails at δ = 2 G_Ic / σc having dissipated G_Ic · A.
        let law = law();
        let n = Vector::<2>::new(0.0, 1.0);
        let mut node = bonded();
        let (dt, rate) = (1e-7, 1.0);
        let mut dissipated = 0.0;
        let mut steps = 0;
        while node.damage < 1.0 && steps < 10_000 {
            let v = [Vector::<2>::zeros(), Vector::<2>::new(0.0, rate)];
            let bond = bond_impulse(&node, &law, [1.0, 1.0], v, &n, dt).unwrap();
            assert!(!bond.holds);
            // The bond slows the separation by j / m on each field; keep it simple by
            // letting the fields open at `rate` whatever the force (a stiff loading).
            dissipated += advance(&mut node, &law, v, &bond, &n, dt).dissipated;
            steps += 1;
        }
        let final_opening = 2.0 * law.mode_i_energy / law.normal_strength;
        assert!((node.opening[1] - final_opening).abs() <= rate * dt * 1.0001);
        let expected = law.mode_i_energy * node.area;
        assert!(
            (dissipated - expected).abs() < 1e-3 * expected,
            "{dissipated} against {expected}"
        );
        assert!(bond_impulse(&node, &law, [1.0, 1.0], [Vector::<2>::zeros(); 2], &n, dt).is_none());
    }

    #[test]
    fn mixed_mode_damage_is_the_power_law_norm_of_the_openings() {
        let law = law();
        let n = Vector::<2>::new(0.0, 1.0);
        let mut node = bonded();
        // Openings of 0.3 of mode I's final opening (2e-4 m) and 0.4 of mode II's (4e-4).
        node.opening = Vector::<2>::new(0.4 * 4e-4, 0.3 * 2e-4);
        let opening = Bond {
            impulse: Vector::<2>::zeros(),
            holds: false,
        };
        advance(
            &mut node,
            &law,
            [Vector::<2>::zeros(); 2],
            &opening,
            &n,
            1e-6,
        );
        assert!((node.damage - 0.5).abs() < 1e-12, "{}", node.damage);
        // Closing does not heal.
        node.opening = Vector::<2>::zeros();
        advance(
            &mut node,
            &law,
            [Vector::<2>::zeros(); 2],
            &opening,
            &n,
            1e-6,
        );
        assert_eq!(node.damage, 0.5);
    }
}
