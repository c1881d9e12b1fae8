//! Rate inlets in a wall: an `inflow` at a set rate whose face lies on a wall's plane and
//! points into the domain is a hole in the wall through which the liquid is pushed at the
//! entry speed U. The wall there is a velocity condition, v·n = U inward, not v·n = 0.
//!
//! Without it the projection saw only a wall there: the liquid at the face stood still,
//! the entering particles crowded into the cells before it, and only the volume source
//! (volume_source.rs) pushed them apart, one layer's worth at a time. With the face one
//! cell in front of the wall (as `examples/liquid-inflow-tank.json` had it) the pool's
//! liquid between the wall and the face had nowhere to go but up: a jet up the wall at
//! 0.6 m/s, where the inlet brings 0.05 m/s, that left the tank's open top (issue 19,
//! stop 85).
//!
//! The condition acts in three places:
//! - the pressure equation's wall term: Σ_c ∫_c ∇N_i·v = −∫_Γ N_i v·n on the wall, zero
//!   for a fixed wall, is U·a_i on the inlet's face nodes, with a_i = ∫_Γin N_i the node's
//!   share of the inlet's face, so the pressure pushes the liquid away at the rate the
//!   inlet brings it (`add_flux`);
//! - the nodal velocity after the walls act: the face's nodes and the ghosts behind them
//!   move at U·w_i along the inlet's direction, with w_i = a_i over ∫N_i on the part of
//!   the face inside the domain (1 within the inlet, less at its edge), so the particles
//!   entering, and the liquid before them, move on at U (`impose`);
//! - the pumping work: the wall does Σ_i p_i U a_i per unit time on the liquid, booked
//!   with this step's pressure in place of the entering particles' p·V (`work`).
//!
//! Measured on that tank with its inlet moved onto the wall (`mpm run
//! examples/liquid-inflow-tank.json`, stop 86): the energy balance's drift +0.0008 of
//! its largest mechanical energy, against +2.95 with the face a cell in front of the wall
//! and the particles' p·V booked; with 200 frames the run finishes (it had stopped at
//! 0.353 s), its fastest particle 0.20 m/s.
//!
//! The inlet's face is the union of its lattice points' squares (h across, h × h in 3D),
//! whose area times U is the rate. The speed over a step is U times the share of the step
//! within the flow's [start, end]. A moving inlet, a pressure inlet, or a face off every
//! wall plane stays with the volume source alone.

use crate::boundary::{GRID_PADDING, WallPlane};
use crate::grid::Grid;
use crate::math::Vector;
use crate::scene::{Contact, InflowLayout};

/// One inlet on a wall plane.
struct WallInlet {
    /// The inflow plan's index (inflow.rs), whose entering particles' pumping work this
    /// inlet books in their place.
    plan: usize,
    /// The wall's normal axis and the entry direction along it (+1 from a lower wall).
    axis: usize,
    sign: f64,
    /// The entry speed U and the flow's time window.
    speed: f64,
    start: f64,
    end: f64,
    /// The face's nodes on the plane with their share a_i of the face and their velocity
    /// weight w_i.
    face: Vec<(usize, f64, f64)>,
    /// The nodes behind the plane on the face nodes' lines, with their weight w_i.
    ghosts: Vec<(usize, f64)>,
    /// Whether the liquid at the face can take the flow this step (set by `add_flux`).
    flowing: bool,
}

/// The scene's rate inlets that lie on wall planes.
pub(super) struct WallInlets {
    inlets: Vec<WallInlet>,
}

/// ∫ max(0, 1 − |s|) ds from −1 to `u`.
fn hat_integral(u: f64) -> f64 {
    let u = u.clamp(-1.0, 1.0);
    if u <= 0.0 {
        0.5 * (u + 1.0) * (u + 1.0)
    } else {
        1.0 - 0.5 * (1.0 - u) * (1.0 - u)
    }
}

/// ∫ N(x − node) dx over [a, b], N the hat of half-width `dx`.
fn hat_over(node: f64, a: f64, b: f64, dx: f64) -> f64 {
    dx * (hat_integral((b - node) / dx) - hat_integral((a - node) / dx)).max(0.0)
}

impl WallInlets {
    /// The wall inlets among `plans` (index, layout, is a pressure inlet), on `grid` with
    /// the walls `walls`; `None` when there are none.
    pub(super) fn new<'a, const D: usize>(
        grid: &Grid<D>,
        walls: &[WallPlane],
        plans: impl Iterator<Item = (usize, &'a InflowLayout, bool)>,
    ) -> Option<Self> {
        let dx = grid.dx;
        let inlets: Vec<WallInlet> = plans
            .filter(|(_, layout, pressure)| {
                !pressure && layout.speed > 0.0 && layout.inlet_velocity.iter().all(|v| *v == 0.0)
            })
            .filter_map(|(plan, layout, _)| {
                let wall = walls.iter().find(|w| {
                    let into = if w.upper { -1.0 } else { 1.0 };
                    let plane = grid.origin[w.axis] + w.surface as f64 * dx;
                    (layout.direction[w.axis] * into - 1.0).abs() < 1e-9
                        && (layout.center[w.axis] - plane).abs() <= 1e-6 * dx
                })?;
                Some(Self::resolve(grid, wall, walls, plan, layout))
            })
            .collect();
        (!inlets.is_empty()).then_some(Self { inlets })
    }

    /// The face and ghost nodes of the inlet `layout` on `wall` (one of `walls`).
    fn resolve<const D: usize>(
        grid: &Grid<D>,
        wall: &WallPlane,
        walls: &[WallPlane],
        plan: usize,
        layout: &InflowLayout,
    ) -> WallInlet {
        let (axis, dx, h) = (wall.axis, grid.dx, layout.spacing);
        // The domain's extent along each tangent axis (walls and open faces alike).
        let low = |d: usize| grid.origin[d] + GRID_PADDING as f64 * dx;
        let high = |d: usize| grid.origin[d] + (grid.cells[d] - GRID_PADDING) as f64 * dx;
        let mut face = Vec::new();
        let mut ghosts = Vec::new();
        for i in 0..grid.len() {
            let ijk = grid.coords(i);
            if ijk[axis] != wall.surface {
                continue;
            }
            let x = grid.position(ijk);
            // a_i: the lattice squares' integral of the node's hat.
            let share_at = |x: &Vector<D>| -> f64 {
                layout
                    .offsets
                    .iter()
                    .map(|o| {
                        (0..D)
                            .filter(|&d| d != axis)
                            .map(|d| {
                                let p = layout.center[d] + o[d];
                                hat_over(x[d], p - 0.5 * h, p + 0.5 * h, dx)
                            })
                            .product::<f64>()
                    })
                    .sum()
            };
            // w_i: a_i over the open part of the hat's own integral. A node of the plane
            // behind another wall (below a floor the inlet stands on) takes the weight of
            // its mirror image in front of it: the liquid at the corner moves along that
            // wall as the liquid beside it does (the slip wall's symmetry). Left at the
            // other wall's 0, the particles along the floor at the inlet lagged, and the
            // tank's balance read −0.28 against −0.09.
            // (Not behind a stick wall, which holds the liquid still.)
            let sticks = |d: usize, upper: bool| {
                walls.iter().any(|w| {
                    w.axis == d && w.upper == upper && matches!(w.condition, Contact::Stick)
                })
            };
            let mut image = x;
            for d in (0..D).filter(|&d| d != axis) {
                if image[d] < low(d) && !sticks(d, false) {
                    image[d] = 2.0 * low(d) - image[d];
                } else if image[d] > high(d) && !sticks(d, true) {
                    image[d] = 2.0 * high(d) - image[d];
                }
            }
            let open: f64 = (0..D)
                .filter(|&d| d != axis)
                .map(|d| hat_over(image[d], low(d), high(d), dx))
                .product();
            let share = share_at(&x);
            let weight = (share_at(&image) / open.max(1e-300)).min(1.0);
            // (A hat that only touches the inlet's edge gets a round-off share.)
            let tiny = 1e-9 * dx.powi(D as i32 - 1);
            let (share, weight) = (
                if share > tiny { share } else { 0.0 },
                if weight > 1e-9 { weight } else { 0.0 },
            );
            if share == 0.0 && weight == 0.0 {
                continue;
            }
            face.push((i, share, weight));
            let mut behind = ijk;
            loop {
                let next = if wall.upper {
                    behind[axis] + 1
                } else {
                    match behind[axis].checked_sub(1) {
                        Some(k) => k,
                        None => break,
                    }
                };
                if next >= grid.nodes[axis] {
                    break;
                }
                behind[axis] = next;
                ghosts.push((grid.index(behind), weight));
            }
        }
        WallInlet {
            plan,
            axis,
            sign: if wall.upper { -1.0 } else { 1.0 },
            speed: layout.speed,
            start: layout.start,
            end: layout.end,
            face,
            ghosts,
            flowing: true,
        }
    }

    /// Whether the inflow plan `plan` is a wall inlet (its pumping work is booked here).
    pub(super) fn has_plan(&self, plan: usize) -> bool {
        self.inlets.iter().any(|w| w.plan == plan)
    }

    /// The inlet's mean entry speed over the step [t, t + dt].
    fn speed_over(inlet: &WallInlet, t: f64, dt: f64) -> f64 {
        let open = ((t + dt).min(inlet.end) - t.max(inlet.start)).max(0.0);
        if dt > 0.0 {
            inlet.speed * open / dt
        } else {
            0.0
        }
    }

    /// Adds the inlets' wall term U·a_i/dt to the pressure equation's right-hand side for
    /// the step [t, t + dt]. An inlet none of whose face nodes is `open` to the flow (the
    /// liquid before it sealed all round, without a free surface or a gas pocket) does not
    /// flow this step: the pressure equation of a sealed region has no solution with a
    /// net inflow.
    pub(super) fn add_flux(
        &mut self,
        t: f64,
        dt: f64,
        rhs: &mut [f64],
        mut open: impl FnMut(usize) -> bool,
    ) {
        for inlet in &mut self.inlets {
            let u = Self::speed_over(inlet, t, dt);
            inlet.flowing = inlet.face.iter().any(|&(i, _, _)| open(i));
            if u <= 0.0 || !inlet.flowing {
                continue;
            }
            for &(i, share, _) in &inlet.face {
                rhs[i] += u * share / dt;
            }
        }
    }

    /// Sets the normal velocity of the inlets' face and ghost nodes that carry mass to
    /// U·w_i into the domain, for the step [t, t + dt] (after the walls acted). Returns
    /// the kinetic energy that added, Σ ½ m_i (|v_i'|² − |v_i|²), J (J/m in 2D): the work
    /// the face did where the pressure equation did not hold its flux (nodes on the free
    /// surface, above a pool that covers only part of the inlet).
    pub(super) fn impose<const D: usize>(&self, grid: &mut Grid<D>, t: f64, dt: f64) -> f64 {
        let mut energy = 0.0;
        for inlet in self.inlets.iter().filter(|w| w.flowing) {
            let u = Self::speed_over(inlet, t, dt);
            if u <= 0.0 {
                continue;
            }
            let nodes = inlet.face.iter().map(|&(i, _, w)| (i, w));
            for (i, w) in nodes.chain(inlet.ghosts.iter().copied()) {
                let m = grid.mass[i];
                if m > 0.0 {
                    let v: &mut Vector<D> = &mut grid.momentum[i];
                    let before = v.norm_squared();
                    v[inlet.axis] = inlet.sign * u * w;
                    energy += 0.5 * m * (v.norm_squared() - before);
                }
            }
        }
        energy
    }

    /// The work the inlets' walls did on the liquid over the step [t, t + dt] at the
    /// nodal pressure `pressure`: Σ_i p_i U a_i dt, J (J/m in 2D).
    pub(super) fn work(&self, pressure: &[f64], t: f64, dt: f64) -> f64 {
        self.inlets
            .iter()
            .filter(|w| w.flowing)
            .map(|inlet| {
                let u = Self::speed_over(inlet, t, dt);
                inlet
                    .face
                    .iter()
                    .map(|&(i, share, _)| pressure[i] * u * share * dt)
                    .sum::<f64>()
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tank of examples/liquid-inflow-tank.json: 20 mm square, 0.5 mm cells, padded by
    /// two cells, its left wall's plane at node 2; a 4 mm inlet at the floor, h = 0.25 mm.
    fn tank_inlet() -> WallInlets {
        let dx = 5e-4;
        let grid = Grid::<2>::new(
            Vector::<2>::new(-2.0 * dx, -2.0 * dx),
            [44, 44, 1],
            dx,
            false,
        );
        let wall = WallPlane {
            axis: 0,
            upper: false,
            surface: 2,
            contact_angle: std::f64::consts::FRAC_PI_2,
            condition: Contact::Slip,
        };
        let h = 2.5e-4;
        let layout = InflowLayout {
            offsets: (0..16)
                .map(|k| [0.0, (k as f64 + 0.5 - 8.0) * h, 0.0])
                .collect(),
            direction: [1.0, 0.0, 0.0],
            inlet_velocity: [0.0; 3],
            speed: 0.05,
            pressure: None,
            end: 0.4,
            half_width: 2e-3,
            round: false,
            tangents: [[0.0, 1.0, 0.0], [0.0; 3]],
            layers: 80,
            spacing: h,
            start: 0.0,
            center: [0.0, 2e-3, 0.0],
        };
        WallInlets::new(&grid, &[wall], std::iter::once((0, &layout, false))).unwrap()
    }

    #[test]
    fn the_face_shares_add_up_to_the_inlet_and_its_edges_move_in_part() {
        let inlets = tank_inlet();
        let inlet = &inlets.inlets[0];
        // Nodes at y = −1, −0.5, 0, ..., 4 mm: eleven on the plane, two ghosts behind
        // each; the two below the floor carry no flux and move as their images above it.
        assert_eq!(inlet.face.len(), 11);
        assert_eq!(inlet.ghosts.len(), 22);
        assert!(
            inlet.face[..2]
                .iter()
                .all(|f| f.1 == 0.0 && (f.2 - 1.0).abs() < 1e-12)
        );
        let total: f64 = inlet.face.iter().map(|f| f.1).sum();
        assert!((total - 4e-3).abs() < 1e-15, "{total}");
        // The floor's corner node has half a hat in the domain, all of it on the inlet;
        // the node at the inlet's top edge has half its hat on the inlet.
        let (first, last) = (inlet.face[2], inlet.face[10]);
        assert!((first.1 - 2.5e-4).abs() < 1e-15 && (first.2 - 1.0).abs() < 1e-12);
        assert!((last.1 - 2.5e-4).abs() < 1e-15 && (last.2 - 0.5).abs() < 1e-12);
        assert!(inlet.face[3..10].iter().all(|f| (f.2 - 1.0).abs() < 1e-12));
        // The rate U·width through the face over a step inside the flow, and a share of
        // it over the step that ends the flow.
        let mut rhs = vec![0.0; 45 * 45];
        let mut inlets = inlets;
        inlets.add_flux(0.1, 1e-3, &mut rhs, |_| true);
        let flux: f64 = rhs.iter().sum::<f64>() * 1e-3;
        assert!((flux - 2e-4).abs() < 1e-15, "{flux}");
        assert!((WallInlets::speed_over(&inlets.inlets[0], 0.3995, 1e-3) - 0.025).abs() < 1e-12);
    }

    #[test]
    fn a_hat_integrates_to_its_cell_and_splits_at_its_node() {
        let dx = 0.5;
        assert!((hat_over(1.0, -5.0, 5.0, dx) - dx).abs() < 1e-15);
        assert!((hat_over(1.0, 1.0, 5.0, dx) - 0.5 * dx).abs() < 1e-15);
        // A quarter cell on either side of the node: 7/16 of the hat's integral.
        let part = hat_over(1.0, 0.875, 1.125, dx) / dx;
        assert!((part - 7.0 / 16.0).abs() < 1e-15, "{part}");
        assert_eq!(hat_over(1.0, 2.0, 3.0, dx), 0.0);
    }
}
