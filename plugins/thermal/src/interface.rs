//! Contact conductance: an imperfect thermal interface between two contact bodies.
//!
//! Without it, heat crosses every contact as if the bodies were one (conduction runs on the
//! shared grid). With `physics.thermal.contact_conductance`, the bodies of a named pair get
//! temperatures of their own on the grid: the contact fields (`contact.pairs`) joined by
//! perfectly conducting contact form one *thermal group*, and every group carries its own
//! nodal temperature, capacity and conduction. At a node where two groups with a
//! conductance h meet, the flux `h A_i (T_a − T_b)` flows between their nodal temperatures
//! (Nairn's node-based imperfect interface, the heat analogue of the cohesive bond):
//! - the interface area `A_i` the node carries is the one the cohesive bond uses: from the
//!   volume gradients `Σ_p V_p ∇w_ip` of the two groups (the smaller magnitude, or the
//!   larger component along the normal where that is smaller), so the areas of the nodes
//!   across a flat interface add up to the interface area (partition of unity);
//! - the node couples the groups where both have heat capacity (each has particles within
//!   the kernel's reach) and the particle volume both map to it fills at least a fifth of
//!   its support (`TOUCH_FILL`), which drops the nodes outside the bodies along the edges of
//!   the interface but keeps a 3D interface's corner nodes (a quarter full). Bodies apart
//!   by more than the kernel's reach exchange no heat; closer than that, they still do
//!   (the coupling has no gap measure of its own).
//!
//! Only the implicit integrator carries it: a group's capacity at a node on the edge of its
//! kernel's reach is tiny, so the explicit step the coupling would need has no useful bound.

use mpm_core::math::Vector;
use mpm_core::scene::{Issue, Scene};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Share of a node's support the particle volume of two groups must fill for them to
/// couple there. At 0.4 (the cohesive bond's) a 3D interface lost its corner nodes and with
/// them 7.6% of a 4 × 4-cell interface's area (error 1.4% against 0.56% at 0.2).
const TOUCH_FILL: f64 = 0.2;

/// A thermal contact conductance between two contact bodies.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactConductance {
    /// The two bodies (`bodies[].name`, each named in a `contact.pairs` entry).
    pub bodies: [String; 2],
    /// Heat transfer coefficient across the interface, W/(m² K) (> 0).
    pub coefficient: f64,
}

/// One coupling of a step: rows `a` and `b` of the grouped nodal temperature (node plus
/// group × nodes) exchange heat through `conductance` (W/K, or W/(m K) in 2D).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Coupling {
    pub a: u32,
    pub b: u32,
    pub conductance: f64,
}

/// The thermal groups of a scene and the conductance between every two.
#[derive(Clone, Debug)]
pub(crate) struct Interfaces {
    /// Thermal group of every contact field.
    group_of_field: Vec<u8>,
    /// Number of groups (1: one temperature per node, as without contact conductance).
    pub groups: usize,
    /// Coefficient between every two groups, `groups × groups` (0: none).
    coefficient: Vec<f64>,
}

impl Interfaces {
    /// One group: no conductance named.
    pub fn single() -> Self {
        Self {
            group_of_field: Vec::new(),
            groups: 1,
            coefficient: vec![0.0],
        }
    }

    /// The groups of `scene` for the conductances `list` (at `path`), or the problems.
    pub fn new(list: &[ContactConductance], path: &str, scene: &Scene) -> Result<Self, Vec<Issue>> {
        if list.is_empty() {
            return Ok(Self::single());
        }
        let mut issues = Vec::new();
        let Some(contact) = &scene.contact else {
            return Err(vec![Issue::new(
                path,
                "a contact conductance acts between contact bodies, and the scene has no `contact` section (name the bodies in `contact.pairs`)",
            )]);
        };
        let (keys, _) = contact.fields(scene);
        let field_of = |name: &str| keys.iter().position(|k| *k == Some(name));
        // Fields of each named pair; pairs with a bad body are skipped after the issue.
        let mut pairs: Vec<(usize, usize, f64, usize)> = Vec::new();
        for (k, c) in list.iter().enumerate() {
            let at = format!("{path}[{k}]");
            if !(c.coefficient.is_finite() && c.coefficient > 0.0) {
                issues.push(Issue::new(
                    format!("{at}.coefficient"),
                    format!(
                        "must be a finite number > 0 W/(m² K) (got {})",
                        c.coefficient
                    ),
                ));
            }
            let mut fields = [0; 2];
            let mut ok = true;
            for (j, name) in c.bodies.iter().enumerate() {
                match field_of(name) {
                    Some(f) => fields[j] = f,
                    None => {
                        ok = false;
                        issues.push(Issue::new(
                            format!("{at}.bodies[{j}]"),
                            format!(
                                "\"{name}\" is not a contact body (name it in `contact.pairs`)"
                            ),
                        ));
                    }
                }
            }
            if ok && fields[0] == fields[1] {
                ok = false;
                issues.push(Issue::new(
                    format!("{at}.bodies"),
                    "name two different contact bodies",
                ));
            }
            if ok {
                let (a, b) = (fields[0].min(fields[1]), fields[0].max(fields[1]));
                if let Some(first) = pairs.iter().find(|p| (p.0, p.1) == (a, b)).map(|p| p.3) {
                    issues.push(Issue::new(
                        format!("{at}.bodies"),
                        format!("these bodies already have a conductance in {path}[{first}]"),
                    ));
                } else {
                    pairs.push((a, b, c.coefficient, k));
                }
            }
        }
        // Fields join a group wherever no conductance separates them (perfect contact).
        let count = keys.len();
        let mut root: Vec<usize> = (0..count).collect();
        fn find(root: &mut [usize], mut f: usize) -> usize {
            while root[f] != f {
                root[f] = root[root[f]];
                f = root[f];
            }
            f
        }
        for a in 0..count {
            for b in a + 1..count {
                if !pairs.iter().any(|p| (p.0, p.1) == (a, b)) {
                    let (ra, rb) = (find(&mut root, a), find(&mut root, b));
                    root[ra.max(rb)] = ra.min(rb);
                }
            }
        }
        let mut group_of_field = vec![0u8; count];
        let mut roots: Vec<usize> = Vec::new();
        for (f, group) in group_of_field.iter_mut().enumerate() {
            let r = find(&mut root, f);
            let g = roots.iter().position(|&x| x == r).unwrap_or_else(|| {
                roots.push(r);
                roots.len() - 1
            });
            *group = g as u8;
        }
        let groups = roots.len();
        let mut coefficient = vec![0.0; groups * groups];
        for &(a, b, h, k) in &pairs {
            let (ga, gb) = (group_of_field[a] as usize, group_of_field[b] as usize);
            let name = |f: usize| keys[f].unwrap_or("(the bodies no pair names)");
            if ga == gb {
                issues.push(Issue::new(
                    format!("{path}[{k}].bodies"),
                    format!(
                        "\"{}\" and \"{}\" are also joined through perfectly conducting contact (every two contact bodies without a conductance between them, and the bodies no contact pair names, conduct as one): give those pairs a conductance too",
                        name(a),
                        name(b)
                    ),
                ));
                continue;
            }
            let old = coefficient[ga * groups + gb];
            if old != 0.0 && old != h {
                issues.push(Issue::new(
                    format!("{path}[{k}].coefficient"),
                    "differs from another conductance between the same two groups of perfectly conducting bodies",
                ));
            }
            coefficient[ga * groups + gb] = h;
            coefficient[gb * groups + ga] = h;
        }
        if issues.is_empty() {
            Ok(Self {
                group_of_field,
                groups,
                coefficient,
            })
        } else {
            Err(issues)
        }
    }

    /// The thermal group of a particle in contact field `field`.
    #[inline]
    pub fn group(&self, field: u8) -> usize {
        self.group_of_field
            .get(field as usize)
            .map_or(0, |&g| g as usize)
    }

    /// Appends to `out` the couplings of the step at the `nodes` grid nodes: `capacity` and
    /// `volume` (Σ_p V_p w_ip) per row, `gradient[axis]` (Σ_p V_p ∂w_ip/∂x_axis) per row,
    /// rows being node + group × nodes; `cell_volume` is dx^D.
    pub fn couplings<const D: usize>(
        &self,
        nodes: usize,
        capacity: &[f64],
        volume: &[f64],
        gradient: &[Vec<f64>],
        cell_volume: f64,
        out: &mut Vec<Coupling>,
    ) {
        out.clear();
        let g = self.groups;
        let volume_gradient = |row: usize| Vector::<D>::from_fn(|axis, _| gradient[axis][row]);
        for i in 0..nodes {
            for ga in 0..g {
                let a = i + ga * nodes;
                if capacity[a] <= 0.0 {
                    continue;
                }
                for gb in ga + 1..g {
                    let b = i + gb * nodes;
                    let h = self.coefficient[ga * g + gb];
                    if h == 0.0
                        || capacity[b] <= 0.0
                        || volume[a] + volume[b] < TOUCH_FILL * cell_volume
                    {
                        continue;
                    }
                    let (va, vb) = (volume_gradient(a), volume_gradient(b));
                    let normal = (va - vb).normalize();
                    let area = va
                        .norm()
                        .min(vb.norm())
                        .min(va.dot(&normal).abs().max(vb.dot(&normal).abs()));
                    if area > 0.0 && area.is_finite() {
                        out.push(Coupling {
                            a: a as u32,
                            b: b as u32,
                            conductance: h * area,
                        });
                    }
                }
            }
        }
    }
}

/// `y += H x`: the interface fluxes `H (x_a − x_b)` out of row `a` and into row `b`.
pub(crate) fn apply_couplings(couplings: &[Coupling], x: &[f64], y: &mut [f64]) {
    for c in couplings {
        let (a, b) = (c.a as usize, c.b as usize);
        let q = c.conductance * (x[a] - x[b]);
        y[a] += q;
        y[b] -= q;
    }
}
